"""The on-disk cache: results that are costly to make and never change for the same inputs.

Compiled failure tables (:mod:`pyroute_rel.reliability.failure`) and coastlines grown by a margin
(:mod:`pyroute_rel.obstacles.land`) are kept here between runs, each under a name that hashes everything it
depends on (the sources' content and this package's version), so an entry is never stale: a changed input is
another name.

Where
-----
The folder is ``$PYROUTE_REL_CACHE_DIR``, else ``$XDG_CACHE_HOME/pyroute_rel``, else ``~/.cache/pyroute_rel``.
Entries live in a subfolder the cache owns (:data:`ENTRIES`, made private to the user), so pruning never meets a
file the cache did not write, whatever else the chosen folder holds.

Trust
-----
A cache that another user can write could change routes (a compiled failure table of zeros turns every failure
criterion off). So:

- a folder that is not the user's own, or that group or others may write (a shared folder such as ``/tmp`` is
  accepted only with its sticky bit, and then only through the private subfolder), is not used: the run goes on
  without a disk cache and says so once (:class:`CacheWarning`);
- every entry carries a keyed digest (HMAC-SHA256, RFC 2104) of its name and bytes, made with a random key kept
  in the private subfolder (mode 0600); an entry whose digest does not verify, however well formed, is ignored
  and made again. A copied, planted, truncated or edited entry is never used.

Writes are atomic (a temporary file renamed into place), so a reader never sees half an entry. A folder that
cannot be written is skipped: the cache only saves time. Entries of a kind beyond the newest ``keep`` are removed
when a new one is written, among the entries this cache wrote only.
"""

from __future__ import annotations

import hashlib
import hmac
import os
import re
import secrets
import stat
import tempfile
import warnings
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import BinaryIO, TypeVar

from pyroute_rel.errors import CacheWarning
from pyroute_rel.store import kept_call

__all__ = ["cache_dir", "entries_dir", "key", "stamp", "read", "load", "write", "CacheWarning", "ENV", "ENTRIES"]

T = TypeVar("T")

ENV = "PYROUTE_REL_CACHE_DIR"
#: The subfolder of the cache folder that holds the entries (bump the number when the entry format changes).
ENTRIES = "entries-v2"
_MAGIC = b"PRRCACHE2\n"  # first bytes of every entry
_DIGEST = 32  # bytes of HMAC-SHA256
_KEY_FILE = ".key"
_NAME = re.compile(r"^[a-z][a-z0-9_]*-[0-9a-f]{32}\.[a-z0-9]+$")  # kind-<key>.<ext>: the names the cache writes


def cache_dir() -> Path:
    """The cache folder (see the module notes); it may not exist yet."""
    env = os.environ.get(ENV)
    if env:
        return Path(env).expanduser()
    xdg = os.environ.get("XDG_CACHE_HOME")
    base = Path(xdg).expanduser() if xdg else Path.home() / ".cache"
    return base / "pyroute_rel"


def entries_dir() -> Path:
    """The private subfolder holding the entries."""
    return cache_dir() / ENTRIES


def key(parts: Iterable[bytes]) -> str:
    """A 32-hex-digit name for the byte strings ``parts`` (length-prefixed, so no two lists collide) and this
    package's version (a new version never reads an older one's entries).

    >>> key([b"ab", b"c"]) != key([b"a", b"bc"])
    True
    """
    from pyroute_rel import __version__

    h = hashlib.sha256()
    for part in (b"pyroute_rel " + __version__.encode(), *parts):
        h.update(len(part).to_bytes(8, "little"))
        h.update(part)
    return h.hexdigest()[:32]


def stamp(path: Path) -> bytes:
    """What identifies a source file's version for a key: a SHA-256 of its content (read once per process for a
    given path, size and modification time)."""
    st = path.stat()
    return _content_digest(str(path), st.st_size, st.st_mtime_ns)


@kept_call("diskcache.digests", limit=64)
def _content_digest(path: str, size: int, mtime_ns: int) -> bytes:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return f"{size}:".encode() + h.hexdigest().encode()


def read(name: str) -> bytes | None:
    """The bytes of entry ``name``, or None when it is absent, unreadable, not verified, or the cache is not used."""
    folder = _usable_folder(create=False)
    if folder is None:
        return None
    try:
        data = (folder / name).read_bytes()
        secret = _secret(folder, create=False)
    except OSError:
        return None
    head = len(_MAGIC) + _DIGEST
    if secret is None or len(data) < head or not data.startswith(_MAGIC):
        return None
    payload = data[head:]
    if not hmac.compare_digest(data[len(_MAGIC) : head], _mac(secret, name, payload)):
        return None
    return payload


def load(name: str, decode: Callable[[bytes], T | None]) -> T | None:
    """Entry ``name`` decoded, or None when it is absent, unreadable, not verified, or ``decode`` fails on it (the
    caller then makes it again)."""
    data = read(name)
    if data is None:
        return None
    try:
        return decode(data)
    except Exception:
        return None


def write(name: str, save: Callable[[BinaryIO], None] | bytes, *, keep: int | None = None) -> None:
    """Store entry ``name`` atomically: ``save`` is the bytes, or a function writing to a binary file object.

    ``name`` is ``kind-<32 hex digits>.<ext>`` (:func:`key` makes the digits). With ``keep``, entries of the same
    kind beyond the ``keep`` newest are deleted.
    """
    if not _NAME.match(name):
        raise ValueError(f"cache entry names are 'kind-<32 hex digits>.<ext>' (got {name!r})")
    tmp = None
    try:
        folder = _usable_folder(create=True)
        if folder is None:
            return
        secret = _secret(folder, create=True)
        if secret is None:
            return
        fd, tmp = tempfile.mkstemp(prefix=".tmp-", dir=folder)
        with os.fdopen(fd, "w+b") as fh:
            fh.write(_MAGIC + b"\0" * _DIGEST)
            if isinstance(save, bytes):
                fh.write(save)
            else:
                save(fh)
            fh.seek(len(_MAGIC) + _DIGEST)
            payload = fh.read()
            fh.seek(len(_MAGIC))
            fh.write(_mac(secret, name, payload))
        os.replace(tmp, folder / name)
        tmp = None
        if keep is not None:
            _prune(folder, name.split("-", 1)[0] + "-", keep)
    except OSError:
        pass  # not writable: run without a disk cache
    finally:
        if tmp is not None:
            try:
                os.unlink(tmp)
            except OSError:
                pass


def _mac(secret: bytes, name: str, payload: bytes) -> bytes:
    return hmac.new(secret, name.encode() + b"\0" + payload, hashlib.sha256).digest()


def _prune(folder: Path, kind: str, keep: int) -> None:
    entries = sorted(
        (p for p in folder.iterdir() if p.name.startswith(kind) and _NAME.match(p.name)),
        key=lambda p: p.stat().st_mtime,
        reverse=True,
    )
    for old in entries[keep:]:
        old.unlink(missing_ok=True)


def _usable_folder(*, create: bool) -> Path | None:
    """The private entries folder when it (and the folder above it) can be trusted, else None (warning once)."""
    try:
        base = cache_dir()
    except RuntimeError as exc:  # e.g. PYROUTE_REL_CACHE_DIR=~nosuchuser/x: no such home folder
        _warn_once(os.environ.get(ENV, "?"), f"it cannot be resolved ({exc})")
        return None
    folder = base / ENTRIES
    try:
        if create:
            base.mkdir(mode=0o700, parents=True, exist_ok=True)
        why = _untrusted(base, shared_ok=True)
        if why is None and create:
            try:
                folder.mkdir(mode=0o700)
            except FileExistsError:
                pass
        if why is None and folder.exists():
            why = _untrusted(folder, shared_ok=False)
    except OSError:
        return None
    if why is not None:
        _warn_once(str(base), why)
        return None
    return folder if folder.is_dir() else None


def _untrusted(path: Path, *, shared_ok: bool) -> str | None:
    """Why ``path`` cannot hold trusted entries, or None. ``shared_ok``: a sticky, world-writable folder (``/tmp``)
    is fine, as other users cannot replace what is in it."""
    if not path.exists():
        return None
    st = path.lstat()
    if stat.S_ISLNK(st.st_mode):
        st = path.stat()
    if not stat.S_ISDIR(st.st_mode):
        return None  # not a folder: writing fails and the cache is skipped quietly
    sticky_shared = shared_ok and st.st_mode & stat.S_ISVTX
    if hasattr(os, "getuid") and st.st_uid != os.getuid() and not sticky_shared:
        return "it belongs to another user"
    if st.st_mode & (stat.S_IWGRP | stat.S_IWOTH) and not sticky_shared:
        return "other users may write in it"
    return None


@kept_call("diskcache.warned", limit=64)
def _warn_once(folder: str, why: str) -> None:
    warnings.warn(
        f"pyroute_rel: not using the disk cache {folder}: {why} (set {ENV} to a private folder); "
        "running without it costs only time",
        CacheWarning,
        stacklevel=4,
    )


def _secret(folder: Path, *, create: bool) -> bytes | None:
    """The key that signs the entries (made on first use, readable by the user only)."""
    path = folder / _KEY_FILE
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        if not create:
            return None
        data = secrets.token_bytes(32)
        try:
            fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        except FileExistsError:  # another process made it first
            data = path.read_bytes()
        else:
            with os.fdopen(fd, "wb") as fh:
                fh.write(data)
    return data if len(data) == 32 else None
