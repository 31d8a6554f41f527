"""A per-process cache of opened weather files, for processes that route many times (sweeps).

Opening a gridded weather file costs about 2 s (imports, reading, building the compiled sampler), several times the
route itself. A process that routes many runs over the same files (a sweep's worker, :mod:`pyroute_rel.sweep`)
turns the cache on with :func:`caching`; from then on :func:`~pyroute_rel.weather.readers.weather_from_mapping`
keeps each weather it reads, keyed by the files' resolved paths, sizes and modification times and the reading
options (variables, member, box), and hands the same prepared sampler to every later run. With the cache on, the
whole time range of the files is read (not only the route's window), so that runs departing at different times
share one entry. Entries beyond :data:`MAX_BYTES` in total are dropped, least recently used first.

Off (the default), nothing is kept: a single route reads only its box and time window, as before.
"""

from __future__ import annotations

import os
import threading
from collections import OrderedDict
from collections.abc import Callable, Hashable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any, TypeVar

__all__ = ["caching", "enabled", "file_stamps", "cached", "clear", "stats", "MAX_BYTES"]

T = TypeVar("T")

#: Largest total size of the cached weather [bytes] (2 GB): beyond it the least recently used entries are dropped.
MAX_BYTES = 2_000_000_000

_LOCK = threading.Lock()
_ENTRIES: OrderedDict[Hashable, Any] = OrderedDict()
_STATS = {"hits": 0, "misses": 0}
_DEPTH = 0


@contextmanager
def caching() -> Iterator[None]:
    """Keep opened weather for the duration of the ``with`` block (nested blocks are fine); entries are kept after
    it, for the next block in this process (:func:`clear` drops them)."""
    global _DEPTH
    with _LOCK:
        _DEPTH += 1
    try:
        yield
    finally:
        with _LOCK:
            _DEPTH -= 1


def enabled() -> bool:
    """Whether weather is being cached in this process (inside :func:`caching`)."""
    return _DEPTH > 0


def file_stamps(paths: Sequence[str | os.PathLike[str]]) -> tuple[tuple[str, int, int], ...]:
    """``(resolved path, size [bytes], modification time [ns])`` of each file: a changed file gets a new key.

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


def cached(key: Hashable, build: Callable[[], T], *, nbytes: Callable[[T], int] | None = None) -> T:
    """The value stored under ``key``, built by ``build()`` (and stored) on the first call.

    ``nbytes(value)`` gives its size for the :data:`MAX_BYTES` budget (default: counted as 0).
    An exception from ``build`` is not stored: the next call tries again.
    """
    with _LOCK:
        if key in _ENTRIES:
            _ENTRIES.move_to_end(key)
            _STATS["hits"] += 1
            return _ENTRIES[key][0]  # type: ignore[no-any-return]
        _STATS["misses"] += 1
    value = build()  # outside the lock: reading may take seconds
    size = 0 if nbytes is None else int(nbytes(value))
    with _LOCK:
        _ENTRIES[key] = (value, size)
        total = sum(s for _, s in _ENTRIES.values())
        while total > MAX_BYTES and len(_ENTRIES) > 1:
            _, (_, dropped) = _ENTRIES.popitem(last=False)
            total -= dropped
    return value


def clear() -> None:
    """Drop every entry and reset :func:`stats`."""
    with _LOCK:
        _ENTRIES.clear()
        _STATS.update(hits=0, misses=0)


def stats() -> dict[str, int]:
    """``{"hits": .., "misses": .., "entries": ..}`` since the last :func:`clear`: how often a weather was reused
    and how often it was read.

    >>> clear(); cached("k", lambda: 1); cached("k", lambda: 2); stats()
    1
    1
    {'hits': 1, 'misses': 1, 'entries': 1}
    >>> clear()
    """
    with _LOCK:
        return {**_STATS, "entries": len(_ENTRIES)}
