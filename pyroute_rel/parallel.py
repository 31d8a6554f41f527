"""Threads for the few hot spots where numpy or shapely release the GIL long enough to pay.

Used for arc costs over time-varying weather, arc geometry and the coastal-margin buffer; each caller splits
work whose pieces are independent, so results do not depend on the number of threads (tested per caller).
``$PYROUTE_REL_THREADS`` sets the number of threads (default: the CPUs this process may use; 1 turns them off).
"""

from __future__ import annotations

import contextvars
import os
import threading
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from typing import TypeVar

from pyroute_rel.errors import ScenarioError
from pyroute_rel.store import current_store

__all__ = ["default_workers", "thread_map", "row_blocks"]

T = TypeVar("T")
R = TypeVar("R")


class _Threads:
    """The store's pool of threads (:mod:`pyroute_rel.store`): made at the first call that needs it and replaced by
    a larger one when a call asks for more threads. A pool replaced, or dropped when the store is emptied, is shut
    down once no call is using it (a call given a pool keeps it to its end)."""

    def __init__(self, store: object) -> None:
        self.pool: ThreadPoolExecutor | None = None
        self.size = 0
        self.users: dict[ThreadPoolExecutor, int] = {}  # calls using each pool, by the pool itself
        self.lock = threading.Lock()

    @contextmanager
    def use(self, workers: int) -> Iterator[ThreadPoolExecutor]:
        with self.lock:
            if self.pool is None or self.size < workers:
                self._retire()
                self.pool, self.size = (
                    ThreadPoolExecutor(max_workers=workers, thread_name_prefix="pyroute_rel"),
                    workers,
                )
            pool = self.pool
            self.users[pool] = self.users.get(pool, 0) + 1
        try:
            yield pool
        finally:
            with self.lock:
                self.users[pool] -= 1
                idle = self.users[pool] == 0
                if idle:
                    del self.users[pool]
            if idle and pool is not self.pool:  # replaced or dropped meanwhile: its last user shuts it down
                pool.shutdown(wait=False)

    def _retire(self) -> None:
        """Drop the current pool (under the lock), shut down at once if no call is using it."""
        if self.pool is not None and self.pool not in self.users:
            self.pool.shutdown(wait=False)
        self.pool, self.size = None, 0

    def clear(self) -> None:
        with self.lock:
            self._retire()


def default_workers() -> int:
    """Threads to use: ``$PYROUTE_REL_THREADS``, else the CPUs this process may use.

    >>> default_workers() >= 1
    True
    """
    env = os.environ.get("PYROUTE_REL_THREADS", "").strip()
    if env:
        try:
            n = int(env)
        except ValueError:
            n = 0
        if n < 1:
            raise ScenarioError(f"environment variable PYROUTE_REL_THREADS must be a whole number >= 1 (got {env!r})")
        return n
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


def thread_map(fn: Callable[[T], R], items: Iterable[T], workers: int) -> list[R]:
    """``[fn(x) for x in items]``, in a shared pool of ``workers`` threads when ``workers`` > 1 (the current store's,
    :mod:`pyroute_rel.store`); order kept. Each call runs in a copy of the caller's context (its
    :mod:`pyroute_rel.settings` among others)."""
    items = list(items)
    if workers <= 1 or len(items) <= 1:
        return [fn(x) for x in items]
    with current_store().part("threads", _Threads).use(workers) as pool:
        contexts = [contextvars.copy_context() for _ in items]  # (a context is entered by one thread at a time)
        return list(pool.map(lambda c, x: c.run(fn, x), contexts, items))


def row_blocks(n_rows: int, parts: int) -> list[slice]:
    """``parts`` contiguous slices covering ``range(n_rows)`` (fewer when there are fewer rows).

    >>> row_blocks(10, 3)
    [slice(0, 3, None), slice(3, 6, None), slice(6, 10, None)]
    """
    parts = max(1, min(parts, n_rows))
    cuts = [n_rows * i // parts for i in range(parts + 1)]
    return [slice(a, b) for a, b in zip(cuts[:-1], cuts[1:], strict=True)]
