"""Threads for the few hot spots where numpy or shapely release the GIL long enough to pay.

Used for arc costs over time-varying weather, arc geometry and the coastal-margin buffer; each caller splits
work whose pieces are independent, so results do not depend on the number of threads (tested per caller).
``$PYROUTE_REL_THREADS`` sets the number of threads (default: the CPUs this process may use; 1 turns them off).
"""

from __future__ import annotations

import contextvars
import os
from collections.abc import Callable, Iterable
from concurrent.futures import ThreadPoolExecutor
from typing import TypeVar

from .errors import ScenarioError

__all__ = ["default_workers", "thread_map", "row_blocks"]

T = TypeVar("T")
R = TypeVar("R")

_POOL: ThreadPoolExecutor | None = None
_POOL_SIZE = 0


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
    """``[fn(x) for x in items]``, in a shared pool of ``workers`` threads when ``workers`` > 1; order kept. Each
    call runs in a copy of the caller's context (its :mod:`pyroute_rel.settings` among others)."""
    global _POOL, _POOL_SIZE
    items = list(items)
    if workers <= 1 or len(items) <= 1:
        return [fn(x) for x in items]
    if _POOL is None or _POOL_SIZE < workers:
        _POOL, _POOL_SIZE = ThreadPoolExecutor(max_workers=workers, thread_name_prefix="pyroute_rel"), workers
    contexts = [contextvars.copy_context() for _ in items]  # (a context is entered by one thread at a time)
    return list(_POOL.map(lambda c, x: c.run(fn, x), contexts, items))


def row_blocks(n_rows: int, parts: int) -> list[slice]:
    """``parts`` contiguous slices covering ``range(n_rows)`` (fewer when there are fewer rows).

    >>> row_blocks(10, 3)
    [slice(0, 3, None), slice(3, 6, None), slice(6, 10, None)]
    """
    parts = max(1, min(parts, n_rows))
    cuts = [n_rows * i // parts for i in range(parts + 1)]
    return [slice(a, b) for a, b in zip(cuts[:-1], cuts[1:], strict=True)]
