"""What pyroute_rel keeps between calls, and who owns it: one :class:`Store`.

A process that routes many times (a sweep's worker, an ensemble, a notebook) keeps what it would otherwise read or
build again: weather files opened and read, scenario and failure-model files parsed, land and zone indexes, the
course's grids. All of it lives in the *current store*, in named parts (a :class:`Shelf` of entries, or an object
that owns one concern such as the weather files held open), each entry keyed by the content it came from (a file's
resolved path, size and modification time; a hash of its bytes) or by a reference the entry holds itself, never by
an ``id()``. Derived data of an immutable object (a polar's compiled tables, a failure model's judging tables) is
kept by that object instead (:func:`kept_by`): it lives and dies with it.

Lifetime, and the one switch:

- By default the process has one store, kept for the life of the process; each shelf is bounded (least recently
  used entries dropped first).
- ``with pyroute_rel.kept():`` gives the block a store of its own: everything kept inside it is dropped, and its
  files closed, when the block ends. ``with pyroute_rel.kept(False):`` keeps nothing: every call reads and builds
  afresh (what to use when files change under a long-lived process faster than their modification times show).
- ``PYROUTE_REL_KEEP=0`` in the environment makes the process's store keep nothing (read when the store is first
  used); :func:`clear_kept` empties the current store. Keeping nothing is slower where a route reuses what it built
  (land and zone indexes are built again for each route, a sweep reads its weather files for every run).

What a store holds belongs to it: a :func:`~pyroute_rel.weather.cache.caching` block, files kept open for the next
ensemble members (:func:`~pyroute_rel.weather.io.readers.keep_files_open`) and the pool of threads are the current
store's, so a ``with kept():`` block starts without them and drops them at its end.

>>> from pyroute_rel.store import current_store, kept
>>> with kept() as store:
...     shelf = store.shelf("example")
...     shelf.get_or_make(("key",), lambda: [1, 2, 3])
...     len(shelf)
[1, 2, 3]
1
>>> with kept(False) as store:
...     store.shelf("example").get_or_make(("key",), lambda: "made") and len(store.shelf("example"))
0

The current store is a :class:`contextvars.ContextVar`, like the settings (:mod:`pyroute_rel.settings`): the threads
pyroute_rel starts run in a copy of the caller's context and share its store (every part takes a lock); worker
processes have their own.
"""

from __future__ import annotations

import functools
import os
import threading
from collections import OrderedDict
from collections.abc import Callable, Hashable, Iterator, Sequence
from contextlib import AbstractContextManager, contextmanager
from contextvars import ContextVar
from pathlib import Path
from typing import Any, TypeVar

__all__ = [
    "Held",
    "Shelf",
    "Store",
    "clear_kept",
    "current_store",
    "file_stamps",
    "kept",
    "kept_by",
    "kept_call",
    "ENV_KEEP",
]

T = TypeVar("T")

#: The environment variable that turns keeping off for the process's store (``0``, ``false``, ``no``, ``off``).
ENV_KEEP = "PYROUTE_REL_KEEP"

#: Entries a shelf keeps unless its owner says otherwise (least recently used dropped first).
DEFAULT_LIMIT = 32


class Held:
    """A shelf key for an object that hashes slowly (a coastline's geometry hashes its WKB) or not at all: equal only
    to a key holding that same object. The key keeps the object alive, so its identity is never another object's."""

    __slots__ = ("obj",)

    def __init__(self, obj: Any) -> None:
        self.obj = obj

    def __hash__(self) -> int:
        return id(self.obj)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Held) and other.obj is self.obj


class Shelf:
    """Entries of one kind, by key (content, or a reference the key holds), least recently used dropped first
    beyond ``limit`` entries (and, with ``nbytes``, beyond ``max_bytes`` in total); ``on_drop(value)`` is called
    for each entry dropped (to close a file). A shelf of a store that keeps nothing stores nothing."""

    def __init__(
        self,
        *,
        keep: bool = True,
        limit: int = DEFAULT_LIMIT,
        max_bytes: int | None = None,
        nbytes: Callable[[Any], int] | None = None,
        on_drop: Callable[[Any], None] | None = None,
    ) -> None:
        self.keep = keep
        self.limit = limit
        self.max_bytes = max_bytes
        self._nbytes = nbytes
        self._on_drop = on_drop
        self._entries: OrderedDict[Hashable, tuple[Any, int]] = OrderedDict()
        self._bytes = 0
        self._lock = threading.RLock()
        self.hits = 0
        self.misses = 0

    def __len__(self) -> int:
        return len(self._entries)

    def __contains__(self, key: Hashable) -> bool:
        return key in self._entries

    def keys(self) -> list[Hashable]:
        """The keys, least recently used first."""
        with self._lock:
            return list(self._entries)

    def get(self, key: Hashable, default: Any = None) -> Any:
        """The entry under ``key`` (now the most recently used), else ``default``."""
        with self._lock:
            entry = self._entries.get(key)
            if entry is None:
                self.misses += 1
                return default
            self._entries.move_to_end(key)
            self.hits += 1
            return entry[0]

    def put(self, key: Hashable, value: T, *, replace: bool = True, nbytes: int | None = None) -> T:
        """Keep ``value`` under ``key`` and return it; what was there is dropped (``replace`` False: what was there
        is kept and returned instead, and ``value`` dropped). ``nbytes``: its size for ``max_bytes`` (default: the
        shelf's ``nbytes(value)``, else 0)."""
        if not self.keep:
            return value
        size = int(nbytes) if nbytes is not None else int(self._nbytes(value)) if self._nbytes is not None else 0
        with self._lock:
            old = self._entries.pop(key, None)
            if old is not None and not replace:  # (made meanwhile by another thread: the first one stays)
                self._entries[key] = old
                self._drop((value, 0))
                return old[0]  # type: ignore[no-any-return]
            if old is not None:
                self._drop(old)
            self._entries[key] = (value, size)
            self._bytes += size
            while len(self._entries) > max(self.limit, 1) or (
                self.max_bytes is not None and self._bytes > self.max_bytes and len(self._entries) > 1
            ):
                self._drop(self._entries.popitem(last=False)[1])
        return value

    def get_or_make(self, key: Hashable, make: Callable[[], T]) -> T:
        """The entry under ``key``, made by ``make()`` (and kept) when there is none. An exception from ``make`` keeps
        nothing: the next call tries again."""
        missing = object()
        value = self.get(key, missing)
        if value is not missing:
            return value  # type: ignore[no-any-return]
        return self.put(key, make(), replace=False)

    def pop(self, key: Hashable, default: Any = None) -> Any:
        """Remove the entry under ``key`` and return it, without ``on_drop`` (the caller takes it over)."""
        with self._lock:
            entry = self._entries.pop(key, None)
            if entry is None:
                return default
            self._bytes -= entry[1]
            return entry[0]

    def discard(self, key: Hashable) -> None:
        """Drop the entry under ``key`` (with ``on_drop``), if any."""
        with self._lock:
            entry = self._entries.pop(key, None)
            if entry is not None:
                self._drop(entry)

    def clear(self) -> None:
        """Drop every entry (with ``on_drop``) and reset the counts."""
        with self._lock:
            while self._entries:
                self._drop(self._entries.popitem(last=False)[1])
            self.hits = self.misses = 0

    def _drop(self, entry: tuple[Any, int]) -> None:
        self._bytes -= entry[1]
        if self._on_drop is not None:
            self._on_drop(entry[0])


class Store:
    """The owner of what is kept (see the module notes): named parts, made on first use, emptied by :meth:`clear`.

    Parameters
    ----------
    keep : False: nothing is kept (every :class:`Shelf` stores nothing; parts are told so by :attr:`keep`).
    """

    def __init__(self, *, keep: bool = True) -> None:
        self.keep = bool(keep)
        self._parts: dict[str, Any] = {}
        self._lock = threading.Lock()

    def part(self, name: str, make: Callable[[Store], T]) -> T:
        """The store's part ``name``, made by ``make(store)`` on first use. A part is any object with a ``clear()``
        method (called by :meth:`clear`)."""
        part = self._parts.get(name)
        if part is None:
            with self._lock:
                part = self._parts.get(name)
                if part is None:
                    part = self._parts[name] = make(self)
        return part  # type: ignore[no-any-return]

    def shelf(
        self,
        name: str,
        *,
        limit: int = DEFAULT_LIMIT,
        max_bytes: int | None = None,
        nbytes: Callable[[Any], int] | None = None,
        on_drop: Callable[[Any], None] | None = None,
    ) -> Shelf:
        """The store's :class:`Shelf` ``name`` (made with these options on first use)."""
        return self.part(
            name,
            lambda store: Shelf(keep=store.keep, limit=limit, max_bytes=max_bytes, nbytes=nbytes, on_drop=on_drop),
        )

    def clear(self) -> None:
        """Empty every part (files kept open are closed)."""
        with self._lock:
            parts = list(self._parts.values())
        for part in parts:
            part.clear()

    def sizes(self) -> dict[str, int]:
        """Entries kept in each shelf, by name."""
        return {name: len(part) for name, part in self._parts.items() if isinstance(part, Shelf)}


def _keep_from_env() -> bool:
    return os.environ.get(ENV_KEEP, "1").strip().lower() not in {"0", "false", "no", "off"}


class _ProcessStore:
    """The process's store, made on first use (after a fork, the child makes its own)."""

    def __init__(self) -> None:
        self._store: Store | None = None
        self._pid = 0
        self._lock = threading.Lock()

    def get(self) -> Store:
        store = self._store
        if store is None or self._pid != os.getpid():
            with self._lock:
                if self._store is None or self._pid != os.getpid():
                    self._store, self._pid = Store(keep=_keep_from_env()), os.getpid()
                store = self._store
        return store


_PROCESS = _ProcessStore()
_CURRENT: ContextVar[Store | None] = ContextVar("pyroute_rel_store", default=None)


def current_store() -> Store:
    """The store of the current context: the innermost :func:`kept` block's, else the process's."""
    store = _CURRENT.get()
    return _PROCESS.get() if store is None else store


def kept(keep: bool = True) -> AbstractContextManager[Store]:
    """A store of its own for the ``with`` block (``keep`` False: one that keeps nothing), emptied when it ends."""
    if not isinstance(keep, bool):
        from pyroute_rel.errors import ScenarioError

        raise ScenarioError(f"kept: keep must be True or False (got {keep!r})")
    return _current_for(Store(keep=keep))


@contextmanager
def _current_for(store: Store) -> Iterator[Store]:
    token = _CURRENT.set(store)
    try:
        yield store
    finally:
        try:
            store.clear()  # (while it is current: what its parts close looks it up)
        finally:
            _CURRENT.reset(token)


def clear_kept() -> None:
    """Empty the current store: the next calls read and build everything afresh."""
    current_store().clear()


def kept_by(owner: Any, name: str, make: Callable[[], T]) -> T:
    """What ``make()`` derives from the immutable object ``owner``, made once and kept in the object's own
    ``__dict__`` under ``name`` (as :func:`functools.cached_property` keeps it): it lives and dies with the object,
    and no table outside it is keyed by the object's identity."""
    kept = owner.__dict__
    if name not in kept:
        kept[name] = make()
    return kept[name]  # type: ignore[no-any-return]


def kept_call(name: str, *, limit: int = DEFAULT_LIMIT) -> Callable[[Callable[..., T]], Callable[..., T]]:
    """A function of hashable positional arguments whose results are kept in the current store's shelf ``name``, by
    those arguments (for functions of content: file stamps, package data, geometry bytes); the store's
    :func:`functools.lru_cache`. The wrapped function stays at ``.uncached``; ``.cache_clear()`` empties its shelf in
    the current store."""

    def wrap(fn: Callable[..., T]) -> Callable[..., T]:
        def shelf() -> Shelf:
            return current_store().shelf(name, limit=limit)

        @functools.wraps(fn)
        def call(*args: Hashable) -> T:
            return shelf().get_or_make(args, lambda: fn(*args))

        call.uncached = fn  # type: ignore[attr-defined]
        call.cache_clear = lambda: shelf().clear()  # type: ignore[attr-defined]
        return call

    return wrap


def file_stamps(paths: Sequence[str | os.PathLike[str]]) -> tuple[tuple[str, int, int], ...]:
    """``(resolved path, size [bytes], modification time [ns])`` of each file: the key of what is kept from it (a
    changed file gets a new key).

    A file that cannot be examined gets ``(-1, -1)``: reading it reports the problem.
    """
    out = []
    for p in paths:
        path = Path(p)
        try:
            st = path.stat()
            out.append((str(path.resolve()), int(st.st_size), int(st.st_mtime_ns)))
        except OSError:
            out.append((str(path), -1, -1))
    return tuple(out)
