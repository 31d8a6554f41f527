"""A per-process cache of opened weather files, for processes that route many times (sweeps).

Opening a gridded weather file costs about 2 s (imports, reading, building the compiled sampler), several times the
route itself. A process that routes many runs over the same files (a sweep's worker, :mod:`pyroute_rel.batch.sweep`)
turns the cache on with :func:`caching`; from then on :func:`~pyroute_rel.weather.io.readers.weather_from_mapping`
keeps each weather it reads, keyed by the files' resolved paths, sizes and modification times and the reading
options (variables, member, box), and hands the same prepared sampler to every later run. With the cache on, the
whole time range of the files is read (not only the route's window), so that runs departing at different times
share one entry. Entries beyond :data:`MAX_BYTES` in total are dropped, least recently used first.

Off (the default), nothing is kept: a single route reads only its box and time window, as before. The entries
belong to the current store (:mod:`pyroute_rel.store`): ``with pyroute_rel.kept():`` drops them at its end.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Hashable, Iterator
from contextlib import contextmanager
from typing import TypeVar

from pyroute_rel.store import Shelf, Store, current_store, file_stamps

__all__ = ["caching", "enabled", "file_stamps", "cached", "clear", "stats", "MAX_BYTES"]

T = TypeVar("T")

#: Largest total size of the cached weather [bytes] (2 GB): beyond it the least recently used entries are dropped.
MAX_BYTES = 2_000_000_000


class _WeatherKept:
    """The store's part that keeps opened weather (:mod:`pyroute_rel.store`): the entries, and how many
    :func:`caching` blocks are open."""

    def __init__(self, store: Store) -> None:
        self.entries = Shelf(keep=store.keep, limit=1 << 30, max_bytes=MAX_BYTES)
        self.depth = 0
        self.lock = threading.Lock()

    def clear(self) -> None:
        self.entries.clear()


def _kept() -> _WeatherKept:
    return current_store().part("weather.cache", _WeatherKept)


@contextmanager
def caching() -> Iterator[None]:
    """Keep opened weather for the duration of the ``with`` block (nested blocks are fine); entries are kept after
    it, in the current store (:mod:`pyroute_rel.store`), for the next block (:func:`clear` drops them)."""
    part = _kept()
    with part.lock:
        part.depth += 1
    try:
        yield
    finally:
        with part.lock:
            part.depth -= 1


def enabled() -> bool:
    """Whether weather is being cached in this context (inside :func:`caching`)."""
    return _kept().depth > 0


def cached(key: Hashable, build: Callable[[], T], *, nbytes: Callable[[T], int] | None = None) -> T:
    """The value stored under ``key``, built by ``build()`` (and stored) on the first call.

    ``nbytes(value)`` gives its size for the :data:`MAX_BYTES` budget (default: counted as 0).
    An exception from ``build`` is not stored: the next call tries again.
    """
    shelf = _kept().entries
    missing = object()
    kept = shelf.get(key, missing)
    if kept is not missing:
        return kept  # type: ignore[no-any-return]
    value = build()  # outside any lock: reading may take seconds
    shelf.put(key, value, nbytes=0 if nbytes is None else int(nbytes(value)))
    return value


def clear() -> None:
    """Drop every entry and reset :func:`stats`."""
    _kept().clear()


def stats() -> dict[str, int]:
    """``{"hits": .., "misses": .., "entries": ..}`` since the last :func:`clear`: how often a weather was reused
    and how often it was read.

    >>> clear(); cached("k", lambda: 1); cached("k", lambda: 2); stats()
    1
    1
    {'hits': 1, 'misses': 1, 'entries': 1}
    >>> clear()
    """
    shelf = _kept().entries
    return {"hits": shelf.hits, "misses": shelf.misses, "entries": len(shelf)}
