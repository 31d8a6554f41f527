"""The on-disk cache: results that are costly to make and never change for the same inputs.

Compiled failure tables (:mod:`pyroute_rel.failure`) and coastlines grown by a margin
(:mod:`pyroute_rel.obstacles.land`) are kept here between runs, each under a name that hashes everything it
depends on, so an entry is never stale: a changed input is another name.

The folder is ``$PYROUTE_REL_CACHE_DIR``, else ``$XDG_CACHE_HOME/pyroute_rel``, else ``~/.cache/pyroute_rel``.
Writes are atomic (a temporary file renamed into place), so a reader never sees half an entry. A folder that
cannot be written is skipped silently: the cache only saves time. Entries of a kind beyond the newest
``keep`` are removed when a new one is written.
"""

from __future__ import annotations

import hashlib
import os
import tempfile
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import BinaryIO, TypeVar

__all__ = ["cache_dir", "key", "stamp", "read", "load", "write"]

T = TypeVar("T")

ENV = "PYROUTE_REL_CACHE_DIR"


def cache_dir() -> Path:
    """The cache folder (see the module notes); it may not exist yet."""
    env = os.environ.get(ENV)
    if env:
        return Path(env).expanduser()
    xdg = os.environ.get("XDG_CACHE_HOME")
    base = Path(xdg).expanduser() if xdg else Path.home() / ".cache"
    return base / "pyroute_rel"


def key(parts: Iterable[bytes]) -> str:
    """A 32-hex-digit name for the byte strings ``parts`` (length-prefixed, so no two lists collide)."""
    h = hashlib.sha256()
    for part in parts:
        h.update(len(part).to_bytes(8, "little"))
        h.update(part)
    return h.hexdigest()[:32]


def stamp(path: Path) -> bytes:
    """What identifies a source file's version for a key: its path, size and modification time."""
    st = path.stat()
    return f"{path}:{st.st_size}:{st.st_mtime_ns}".encode()


def read(name: str) -> bytes | None:
    """The bytes of entry ``name``, or None when it is absent or unreadable."""
    try:
        return (cache_dir() / name).read_bytes()
    except OSError:
        return None


def load(name: str, decode: Callable[[bytes], T | None]) -> T | None:
    """Entry ``name`` decoded, or None when it is absent, unreadable, or ``decode`` fails on it (a corrupt entry
    is then simply made again by the caller)."""
    data = read(name)
    if data is None:
        return None
    try:
        return decode(data)
    except Exception:
        return None


def write(name: str, save: Callable[[BinaryIO], None] | bytes, *, keep: int | None = None) -> None:
    """Store entry ``name`` atomically: ``save`` is the bytes, or a function writing to a binary file object.

    With ``keep``, entries sharing the name's prefix (up to its first ``-``) beyond the ``keep`` newest are
    deleted.
    """
    folder = cache_dir()
    tmp = None
    try:
        folder.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=".tmp-", dir=folder)
        with os.fdopen(fd, "wb") as fh:
            if isinstance(save, bytes):
                fh.write(save)
            else:
                save(fh)
        os.replace(tmp, folder / name)
        tmp = None
        if keep is not None:
            kind = name.split("-", 1)[0] + "-"
            entries = sorted(
                (p for p in folder.iterdir() if p.name.startswith(kind)), key=lambda p: p.stat().st_mtime, reverse=True
            )
            for old in entries[keep:]:
                old.unlink(missing_ok=True)
    except OSError:
        pass  # not writable: run without a disk cache
    finally:
        if tmp is not None:
            try:
                os.unlink(tmp)
            except OSError:
                pass
