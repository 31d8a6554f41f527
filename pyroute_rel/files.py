"""Files written all or none: the one writer every command that writes files goes through.

:func:`atomic_write` writes one file by a rename; :func:`write_together` writes a set of files into a folder,
all or none; :func:`check_out_dir` refuses an unusable folder before any work is done.
"""

from __future__ import annotations

import contextlib
import os
import signal
import stat
import tempfile
import threading
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path

from pyroute_rel.errors import OutputError, brief, show
from pyroute_rel.store import kept_call

__all__ = [
    "atomic_write",
    "atomic_write_text",
    "brief_path",
    "check_out_dir",
    "check_targets",
    "clean_stale_staging",
    "write_together",
    "file_mode",
    "read_regular_bytes",
    "STAGING_PREFIX",
    "STAGING_MARKER",
]

#: Prefix of the hidden staging folders :func:`write_together` makes inside the output folder.
STAGING_PREFIX = ".pyroute-rel-"
#: File inside each staging folder that marks it as ours: "pyroute-rel staging" and the writer's process id.
STAGING_MARKER = ".pyroute-rel-staging"


@kept_call("files.mode", limit=1)
def file_mode() -> int:
    """The mode a new file gets from ``open`` under this process's umask (0o644 for the usual 022).

    The umask is read without changing it, so that no other thread ever runs with a umask of 0: from the
    ``Umask:`` line of ``/proc/self/status`` (Linux), else by creating a private probe file with mode 0o666 and
    reading the mode it got.
    """
    try:
        for row in Path("/proc/self/status").read_text(encoding="ascii").splitlines():
            if row.startswith("Umask:"):
                return 0o666 & ~int(row.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    folder = tempfile.mkdtemp(prefix=".pyroute-rel-umask-")  # 0o700: no one else can swap the probe
    probe = os.path.join(folder, "probe")
    try:
        os.close(os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
        return os.stat(probe).st_mode & 0o777
    finally:
        Path(probe).unlink(missing_ok=True)
        os.rmdir(folder)


def read_regular_bytes(
    path: str | os.PathLike[str], *, limit_bytes: int, error: type[Exception], label: str, what: str = "file"
) -> bytes:
    """The bytes of a user's input file, refusing what is not a regular file or larger than ``limit_bytes``.

    A FIFO, a device (``/dev/zero``), a socket or a folder is refused without reading (the file is opened
    non-blocking, so a FIFO without a writer cannot hang the call, and checked with ``fstat`` on the open
    descriptor, so it cannot be swapped after the check); a file larger than ``limit_bytes`` [bytes] is refused
    before it is read. Errors are ``error`` with a one-line message that starts with ``label`` (e.g. the file
    name) and calls the file ``what``: "zone file not found", "zone file is not a regular file (a FIFO)", "zone
    file is larger than the 10 MB limit", "cannot read zone file (...)".
    """
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_NOCTTY", 0))
    except FileNotFoundError:
        raise error(f"{label}: {what} not found") from None
    except (OSError, ValueError) as exc:  # ValueError: a NUL in the name
        raise error(f"{label}: cannot read {what} ({getattr(exc, 'strerror', None) or exc})") from None
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            kind = _KINDS.get(stat.S_IFMT(info.st_mode), "a special file")
            raise error(f"{label}: {what} is not a regular file ({kind}); give the path of a file")
        if info.st_size > limit_bytes:
            raise error(
                f"{label}: {what} of {info.st_size / 1e6:.1f} MB is larger than the {limit_bytes / 1e6:g} MB limit "
                "for this kind of file"
            )
        with os.fdopen(os.dup(fd), "rb") as fh:
            data = fh.read(limit_bytes + 1)
    except OSError as exc:
        if isinstance(exc, error):
            raise
        raise error(f"{label}: cannot read {what} ({exc.strerror or exc})") from None
    finally:
        os.close(fd)
    if len(data) > limit_bytes:  # grew while being read
        raise error(f"{label}: {what} is larger than the {limit_bytes / 1e6:g} MB limit for this kind of file")
    return data


def check_regular_file(
    path: str | os.PathLike[str], *, error: type[Exception], label: str, folder_hint: str = ""
) -> Path:
    """``path`` if it names a regular file, checked without opening it (a FIFO would block an open for ever, a device
    never end a read); else ``error`` in one line starting with ``label``: ": not found", ": is a folder" (then
    ``folder_hint``), ": not a regular file (a FIFO)" (:func:`read_regular_bytes` refuses the same for the files it
    reads whole; this is for files a library opens itself, e.g. weather files)."""
    p = Path(path)
    try:
        mode = p.stat().st_mode
    except FileNotFoundError:
        raise error(f"{label}: not found") from None
    except (OSError, ValueError) as exc:  # ValueError: a NUL in the name
        raise error(f"{label}: cannot read it ({getattr(exc, 'strerror', None) or exc})") from None
    if stat.S_ISDIR(mode):
        raise error(f"{label}: is a folder{folder_hint}")
    if not stat.S_ISREG(mode):
        raise error(f"{label}: not a regular file ({_KINDS.get(stat.S_IFMT(mode), 'a special file')})")
    return p


_KINDS = {
    stat.S_IFDIR: "a folder",
    stat.S_IFIFO: "a FIFO",
    stat.S_IFCHR: "a character device",
    stat.S_IFBLK: "a block device",
    stat.S_IFSOCK: "a socket",
}


def check_out_dir(path: str | os.PathLike[str], *, option: str = "--out", files: Iterable[str] = ()) -> Path:
    """Refuse, before any work, an output folder that cannot be written: a file, a folder under a file, a name too
    long for the file system, or a place without write permission (:class:`~pyroute_rel.errors.OutputError`,
    naming ``option``); in an existing folder, also any of ``files`` that is not a regular file
    (:func:`check_targets`). Creates nothing."""
    if not isinstance(path, (str, os.PathLike)):
        raise OutputError(f"{option} must be a folder name (str or pathlib.Path) (got {brief(path)})")
    if str(path).strip() == "":
        raise OutputError(f"{option} needs a folder name (got an empty string)")
    out = Path(path)
    try:
        if out.exists() and not out.is_dir():
            raise OutputError(f"{option} {brief_path(out)} is a file, not a folder")
        here = out
        while not here.exists() and here != here.parent:
            here = here.parent
    except OutputError:
        raise
    except OSError as exc:  # e.g. a name longer than the file system allows (ENAMETOOLONG)
        raise OutputError(f"{option} {brief_path(out)}: {exc.strerror or exc.__class__.__name__}") from None
    if not here.is_dir():
        raise OutputError(f"{option} {brief_path(out)}: {brief_path(here)} is a file, not a folder")
    if not os.access(here, os.W_OK | os.X_OK):
        raise OutputError(f"{option} {brief_path(out)}: no permission to write in {brief_path(here)}")
    if out.is_dir():
        check_targets(out, files, option=option)
    return out


def brief_path(path: str | os.PathLike[str], limit: int = 120) -> str:
    """A path for a one-line message: control characters escaped, cut in the middle beyond ``limit`` characters."""
    text = show(path)
    return text if len(text) <= limit else f"{text[: limit // 2 - 2]}...{text[-(limit // 2 - 2) :]}"


def check_targets(out: Path, names: Iterable[str], *, option: str = "--out") -> None:
    """Refuse, before anything is written, a target in ``out`` that is not a regular file (a folder, a FIFO, a
    device, a symbolic link to a folder): one :class:`~pyroute_rel.errors.OutputError` naming the first one."""
    for name in names:
        target = out / name
        try:
            if not os.path.lexists(target):
                continue
            if target.is_symlink() and not target.is_dir():
                continue  # a link to a file (or a dangling one) is replaced by the rename, not written through
            if target.is_file():
                continue
        except OSError as exc:
            raise OutputError(f"{option} {brief_path(out)}: {name}: {exc.strerror or exc}") from None
        kind = "a folder" if target.is_dir() else "not a regular file"
        raise OutputError(
            f"{option} {brief_path(out)}: {name} is {kind}; move it away or choose another folder (nothing was written)"
        )


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
    """Write a set of files into a folder, all or none.

    Every target is checked first (:func:`check_targets`: a folder or other non-file where a file goes is refused
    and nothing is written). ``writers[name](path)`` then renders each file into a hidden staging folder inside
    ``out_dir`` (marked by :data:`STAGING_MARKER`), and the set is published by renames only when every one
    succeeded (with the usual mode of a new file); should a rename fail, the files already published are put back
    as they were (from hard links kept in the staging folder). A failure leaves no partial or stale file, nor the
    folder when this call created it; an error writing is an :class:`~pyroute_rel.errors.OutputError` naming
    ``option``. SIGTERM while writing removes the staging folder before the process ends; the staging folder of a
    run killed outright (SIGKILL) is removed by the next call on the same folder (:func:`clean_stale_staging`).
    Returns the paths written."""
    out = check_out_dir(out_dir, option=option)
    for name in writers:
        if not name or Path(name).name != name or name in (".", "..") or name.startswith(STAGING_PREFIX):
            raise OutputError(f"{option}: file names must be plain names inside the folder (got {name!r})")
    if out.is_dir():
        check_targets(out, writers, option=option)
        clean_stale_staging(out)
    created = not out.exists()
    try:
        out.mkdir(parents=True, exist_ok=True)
        staging = Path(tempfile.mkdtemp(prefix=STAGING_PREFIX, dir=out))
        (staging / STAGING_MARKER).write_text(f"pyroute-rel staging\npid {os.getpid()}\n", encoding="ascii")
    except OSError as exc:
        raise OutputError(f"{option} {brief_path(out)}: {exc.strerror or exc}") from None
    try:
        with _terminate_cleanly():
            for name, writer in writers.items():
                writer(staging / name)
                os.chmod(staging / name, file_mode())
            return _publish(staging, out, list(writers))
    except OSError as exc:
        raise OutputError(f"{option} {brief_path(out)}: cannot write ({exc.strerror or exc})") from None
    finally:
        _remove_staging(staging)
        if created and not any(out.iterdir()):
            out.rmdir()


def _publish(staging: Path, out: Path, names: list[str]) -> list[Path]:
    """Move the staged files into ``out`` by renames; on a failure, restore what was there before."""
    backups = {}
    for name in names:  # hard links to the files being replaced, so that a failed publish can restore them
        target = out / name
        if target.is_file() and not target.is_symlink():
            try:
                os.link(target, staging / f".old-{name}")
                backups[name] = staging / f".old-{name}"
            except OSError:
                pass  # a file system without hard links: the publish is still by renames, without a way back
    done: list[str] = []
    try:
        for name in names:
            os.replace(staging / name, out / name)
            done.append(name)
    except BaseException:
        for name in done:
            if name in backups:
                os.replace(backups[name], out / name)
            else:
                (out / name).unlink(missing_ok=True)
        raise
    return [out / name for name in names]


def _remove_staging(staging: Path) -> None:
    """Remove a staging folder and the plain files in it (nothing else: never follows links or recurses)."""
    try:
        with os.scandir(staging) as entries:
            for entry in entries:
                if not entry.is_dir(follow_symlinks=False):
                    os.unlink(entry.path)
        staging.rmdir()
    except OSError:
        pass


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OSError):
        return True
    return True


def clean_stale_staging(out: str | os.PathLike[str]) -> list[Path]:
    """Remove from ``out`` the staging folders that :func:`write_together` left when its process was killed.

    Only folders named ``.pyroute-rel-*``, owned by this user, holding a :data:`STAGING_MARKER` whose process id is
    no longer running (or is this process, which has no write in progress here) are removed, with the plain files
    in them; anything else, a folder of a run still writing included, is left alone. Returns the folders removed.
    """
    removed: list[Path] = []
    try:
        candidates = [p for p in Path(out).iterdir() if p.name.startswith(STAGING_PREFIX)]
    except OSError:
        return removed
    for folder in candidates:
        try:
            if folder.is_symlink() or not folder.is_dir() or folder.stat().st_uid != os.getuid():
                continue
            head, pid_line = (folder / STAGING_MARKER).read_text(encoding="ascii").splitlines()[:2]
            pid = int(pid_line.removeprefix("pid "))
        except (OSError, ValueError, UnicodeDecodeError):
            continue
        if head != "pyroute-rel staging" or (pid != os.getpid() and _alive(pid)):
            continue
        _remove_staging(folder)
        if not folder.exists():
            removed.append(folder)
    return removed


@contextlib.contextmanager
def _terminate_cleanly() -> Iterator[None]:
    """SIGTERM raises SystemExit(143) inside the block (main thread only), so that ``finally`` clauses run."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def on_term(signum: int, frame: object) -> None:
        raise SystemExit(128 + signum)

    previous = signal.signal(signal.SIGTERM, on_term)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, signal.SIG_DFL if previous is None else previous)
