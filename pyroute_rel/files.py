"""Files written all or none: the one writer every command that writes files goes through.

:func:`atomic_write` writes one file by a rename; :func:`write_together` writes a set of files into a folder,
all or none; :func:`check_out_dir` refuses an unusable folder before any work is done.
"""

from __future__ import annotations

import functools
import os
import tempfile
from collections.abc import Callable
from pathlib import Path

from .errors import OutputError, show

__all__ = ["atomic_write", "atomic_write_text", "check_out_dir", "write_together", "file_mode"]


@functools.lru_cache(maxsize=1)
def file_mode() -> int:
    """The mode a new file gets from ``open`` under this process's umask (0o644 for the usual 022)."""
    mask = os.umask(0)
    os.umask(mask)
    return 0o666 & ~mask


def check_out_dir(path: str | os.PathLike[str], *, option: str = "--out") -> Path:
    """Refuse, before any work, an output folder that cannot be written: a file, a folder under a file, or a place
    without write permission (:class:`~pyroute_rel.errors.OutputError`, naming ``option``). Creates nothing."""
    out = Path(path)
    if str(path).strip() == "":
        raise OutputError(f"{option} needs a folder name (got an empty string)")
    if out.exists() and not out.is_dir():
        raise OutputError(f"{option} {show(out)} is a file, not a folder")
    here = out
    while not here.exists() and here != here.parent:
        here = here.parent
    if not here.is_dir():
        raise OutputError(f"{option} {show(out)}: {show(here)} is a file, not a folder")
    if not os.access(here, os.W_OK | os.X_OK):
        raise OutputError(f"{option} {show(out)}: no permission to write in {show(here)}")
    return out


def atomic_write(path: str | os.PathLike[str], writer: Callable[[Path], object]) -> None:
    """Write a file atomically: ``writer`` writes a temporary file in the same folder, then it is renamed.

    A failure inside ``writer`` leaves neither a partial file nor the temporary file behind. The file gets the
    usual mode of a new file (0o644 under umask 022), not the temporary file's private 0o600.
    """
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    try:
        writer(Path(tmp))
        os.chmod(tmp, file_mode())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def atomic_write_text(path: str | os.PathLike[str], text: str) -> None:
    """Write a UTF-8 text file atomically (:func:`atomic_write`)."""
    atomic_write(path, lambda p: p.write_text(text, encoding="utf-8"))


def write_together(
    out_dir: str | os.PathLike[str], writers: dict[str, Callable[[Path], object]], *, option: str = "output folder"
) -> list[Path]:
    """Write a set of files into a folder, all or none: ``writers[name](path)`` renders each into a temporary folder
    inside ``out_dir``, and the files are moved into place only when every one succeeded (with the usual mode of a
    new file). A failure leaves no partial or stale file, nor the folder when this call created it; an error writing
    is an :class:`~pyroute_rel.errors.OutputError` naming ``option``. Returns the paths written."""
    out = check_out_dir(out_dir, option=option)
    for name in writers:
        if not name or Path(name).name != name or name in (".", ".."):
            raise OutputError(f"{option}: file names must be plain names inside the folder (got {name!r})")
    created = not out.exists()
    try:
        out.mkdir(parents=True, exist_ok=True)
        staging = Path(tempfile.mkdtemp(prefix=".pyroute-rel-", dir=out))
    except OSError as exc:
        raise OutputError(f"{option} {show(out)}: {exc.strerror or exc}") from None
    try:
        for name, writer in writers.items():
            writer(staging / name)
            os.chmod(staging / name, file_mode())
        written = []
        for name in writers:
            os.replace(staging / name, out / name)
            written.append(out / name)
        return written
    except OSError as exc:
        raise OutputError(f"{option} {show(out)}: cannot write ({exc.strerror or exc})") from None
    finally:
        for p in staging.glob("*"):
            p.unlink(missing_ok=True)
        staging.rmdir()
        if created and not any(out.iterdir()):
            out.rmdir()
