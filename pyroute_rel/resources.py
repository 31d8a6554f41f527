"""What a job may take from the machine: worker threads, and a memory budget checked before large arrays are made.

Threads
-------
Threads for the few hot spots where numpy or shapely release the GIL long enough to pay.

Used for arc costs over time-varying weather, arc geometry and the coastal-margin buffer; each caller splits
work whose pieces are independent, so results do not depend on the number of threads (tested per caller).
``$PYROUTE_REL_THREADS`` sets the number of threads (default: the CPUs this process may use; 1 turns them off).

Memory
------
A memory budget, checked before a route allocates its large arrays.

A route's peak memory follows from sizes known before anything large is allocated: the grid (ranks, nodes, candidate
arcs per node), the weather samples per arc, whether the weather varies in time, the obstacle masks and the failure
model's table. :func:`route_estimate` adds up the arrays the router keeps or builds at its peak, each counted from
the code that allocates it (:mod:`pyroute_rel.routing.solve`, :mod:`pyroute_rel.routing.cost`,
:mod:`pyroute_rel.obstacles.mask`); :func:`check_budget` refuses a route whose estimate exceeds the budget with a
:class:`MemoryBudgetError` that says how much it needs and which setting to turn.

What the arrays are (``A`` = candidate arcs of the whole grid, ``a`` = of the widest rank, ``s`` = samples per arc,
8 bytes per float64):

- **arc geometry**, cached on the grid for every rank (:func:`pyroute_rel.routing.solve.grid_geometry`): longitude,
  latitude and course at each sample, and one sub-segment length per arc: ``A (3 s + 1) 8`` bytes. This is the
  bulk of an all-to-all grid's memory.
- **obstacle masks**, cached per rank (:class:`pyroute_rel.routing.grid.ObstacleCache`): tested, hit (bool) and zone
  bits (uint64) per arc: ``10 A`` bytes.
- **one rank at work**: the weather at every sample of the arcs into a rank, the quantities and speeds derived
  from it, the per-sample times, p_f and flags (:func:`pyroute_rel.routing.cost.geometry_costs`), or, before that, the
  halving of the arcs into samples (:func:`pyroute_rel.routing.cost.geometry_from_xyz`): about
  :data:`RANK_ARRAYS_STEADY` (steady weather) or :data:`RANK_ARRAYS_TIMED` (time-varying weather: two passes and
  prepared sampling positions) float64 arrays of ``a s`` values at once, plus :data:`RANK_ARC_ARRAYS` arrays of ``a``
  values (departure times, totals, waits, flags of the DP step).
- **DP state**: arrival time, back-pointer and wait per node: ``24 n_ranks n_nodes`` bytes.
- **failure table**: the criteria-fired bits the cost kernel gathers next to the compiled table (uint32 per entry).

Not in the estimate, because they are kept only where they fit: the judgements of a failure model the compiled DP
step keeps between DPs on uniform weather (:class:`pyroute_rel._kernels.dp.Judged`, 2 bytes per arc of the grid,
at most 512 MiB in all), kept only when the estimate plus their size is within the budget.

Waiting (``max_wait_h`` on a time lattice) repeats the work of a rank once per wait step but keeps only the best so
far: it multiplies the time a route takes, not its memory.

The budget (:func:`budget_bytes`): ``max_memory`` where the router is called, else ``$PYROUTE_REL_MAX_MEMORY``
(bytes, or with a unit: ``8G``, ``500M``), else the memory the process already uses plus :data:`AVAILABLE_FRACTION`
of the memory available on the machine (``MemAvailable`` in ``/proc/meminfo``; half the physical memory where that
file is missing).
"""

from __future__ import annotations

import contextvars
import math
import os
import re
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from dataclasses import dataclass
from typing import TypeVar

from pyroute_rel.errors import MemoryBudgetError, ScenarioError
from pyroute_rel.store import current_store

__all__ = [
    "default_workers",
    "end_with_parent",
    "pool_worker_init",
    "thread_map",
    "row_blocks",
    "MEMORY_ENV",
    "AVAILABLE_FRACTION",
    "MemoryEstimate",
    "parse_bytes",
    "format_bytes",
    "available_bytes",
    "resident_bytes",
    "budget_bytes",
    "route_estimate",
    "table_estimate",
    "check_budget",
]


T = TypeVar("T")
R = TypeVar("R")
A = TypeVar("A")


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


def end_with_parent(parent_pid: int, poll_s: float = 0.5) -> None:
    """In a pool's worker process: exit as soon as the process ``parent_pid`` that made the pool is gone, however it
    ended (SIGKILL included), so that no worker outlives the command. Orphaned workers of a killed sweep kept its
    output pipe open, and ``pyroute-rel sweep ... | cat`` never ended (issue 34). The pool's own process is watched,
    not this one's parent: a forkserver's workers hold the pipe that would end the forkserver, so the forkserver
    ends after them. Not for processes a user starts (a ``dask worker``)."""

    def gone() -> bool:
        try:
            os.kill(parent_pid, 0)
        except ProcessLookupError:
            return True
        except PermissionError:  # (alive, another user's: a reused number)
            return False
        try:  # killed but not yet reaped by its own parent: a zombie (Linux)
            with open(f"/proc/{parent_pid}/stat", "rb") as fh:
                return fh.read().rsplit(b")", 1)[-1].split()[0] == b"Z"
        except (OSError, IndexError):
            return False

    def watch() -> None:
        while not gone():
            time.sleep(poll_s)
        os._exit(1)

    threading.Thread(target=watch, name="pyroute-rel-end-with-parent", daemon=True).start()


def pool_worker_init(parent_pid: int, setup: Callable[[A], object], arg: A) -> None:
    """A local process pool's initializer: the worker ends with the process that made the pool
    (:func:`end_with_parent`; a dask worker, which its user starts, does not), then ``setup(arg)`` (the sweep's and
    the ensemble's set-up of a worker process)."""
    end_with_parent(parent_pid)
    setup(arg)


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


#: Environment variable that sets the budget [bytes, or with a unit K, M, G, T (powers of 1024)].
MEMORY_ENV = "PYROUTE_REL_MAX_MEMORY"
#: Share of the machine's available memory a route may take by default.
AVAILABLE_FRACTION = 0.75
#: Float64 arrays of one value per sample alive at once while the arcs into a rank are costed (steady weather):
#: the sampled conditions (7 fields), sample positions, TWA, boat speed, speed over ground, per-sample time and
#: p_f, flags, the failure table's gather index, temporaries of ``np.where``; the same bound covers the halving
#: of arcs into samples (sub-arc ends and midpoints as x, y, z). An upper count: ``benchmarks/memory.py`` measures
#: 14-16 on all-to-all grids (square 80 with 32 samples, square 240 with 8).
RANK_ARRAYS_STEADY = 24
#: As :data:`RANK_ARRAYS_STEADY` with time-varying weather: sample times of both passes, elapsed times and the
#: prepared sampling positions (cell indices and weights) kept between the passes.
RANK_ARRAYS_TIMED = 36
#: Arrays of one value per arc of a rank alive in a DP step (departure, total and best times, waits, flags, costs).
RANK_ARC_ARRAYS = 16

_UNITS = {"": 1, "K": 1024, "M": 1024**2, "G": 1024**3, "T": 1024**4}
_BYTES = re.compile(r"^\s*([0-9]+(?:\.[0-9]*)?|\.[0-9]+)\s*([KMGT]?)(?:I?B)?\s*$", re.IGNORECASE)


def parse_bytes(value: object, where: str = MEMORY_ENV) -> int:
    """A memory size [bytes] from a number of bytes or a string with a unit (K, M, G, T: powers of 1024).

    >>> parse_bytes("8G"), parse_bytes("500M"), parse_bytes("1.5 GiB"), parse_bytes(4096)
    (8589934592, 524288000, 1610612736, 4096)
    """
    if isinstance(value, bool):
        raise ScenarioError(f"{where} must be a memory size such as 8G or 500M (got {value!r})")
    if isinstance(value, int | float):
        number, unit = float(value), ""
    else:
        m = _BYTES.match(str(value)) if isinstance(value, str) and len(value) < 40 else None
        if m is None:
            raise ScenarioError(f"{where} must be a memory size such as 8G, 500M or 1073741824 (got {value!r:.60})")
        number, unit = float(m.group(1)), m.group(2).upper()
    size = number * _UNITS[unit]
    if not (math.isfinite(size) and 1 <= size < 2**62):
        raise ScenarioError(
            f"{where} must be a memory size of at least 1 byte and below 4 EiB, such as 8G or 500M (got {value!r:.60})"
        )
    return int(size)


def format_bytes(n: float) -> str:
    """A size [bytes] for a message: ``'21.3 GiB'``, ``'512 MiB'``.

    >>> format_bytes(21.3 * 1024**3), format_bytes(512 * 1024**2), format_bytes(3 * 1024**5)
    ('21.3 GiB', '512 MiB', '3072.0 TiB')
    >>> format_bytes(1000), format_bytes(2048)  # below 1 MiB: not "0 MiB"
    ('1000 bytes', '2.0 KiB')
    """
    if n < 1024:
        return f"{n:.0f} bytes"
    if n < 1024**2:
        return f"{n / 1024:.1f} KiB"
    if n < 1024**3:
        return f"{n / 1024**2:.0f} MiB"
    if n < 1024**4:
        return f"{n / 1024**3:.1f} GiB"
    return f"{n / 1024**4:.1f} TiB"


def available_bytes() -> int | None:
    """Memory the machine can still give [bytes]: ``MemAvailable`` of ``/proc/meminfo``, else half the physical
    memory, else None."""
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")) // 2
    except (AttributeError, OSError, ValueError):
        return None


def resident_bytes() -> int:
    """Memory this process uses now [bytes] (resident set of ``/proc/self/statm``; 0 where unknown)."""
    try:
        with open("/proc/self/statm", encoding="ascii") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError, AttributeError):
        return 0


#: Budget when neither a setting nor the machine's memory is known [bytes].
FALLBACK_BUDGET = 8 * 1024**3


def budget_bytes(max_memory: int | str | None = None) -> tuple[int, str]:
    """The memory budget [bytes] and where it comes from (for messages).

    Parameters
    ----------
    max_memory : A size [bytes, or a string with a unit, see :func:`parse_bytes`]; None: ``$PYROUTE_REL_MAX_MEMORY``,
        else what the process uses plus :data:`AVAILABLE_FRACTION` of the available memory.
    """
    if max_memory is not None:
        return parse_bytes(max_memory, "max_memory"), "the budget"
    env = os.environ.get(MEMORY_ENV, "").strip()
    if env:
        return parse_bytes(env, f"environment variable {MEMORY_ENV}"), f"the budget {MEMORY_ENV}"
    free = available_bytes()
    if free is None:
        return FALLBACK_BUDGET, "the default budget"
    return resident_bytes() + int(AVAILABLE_FRACTION * free), (
        f"the default budget ({AVAILABLE_FRACTION:.0%} of the available memory)"
    )


@dataclass(frozen=True)
class MemoryEstimate:
    """Estimated peak memory of a route [bytes], by part, and a short description of its size.

    Attributes
    ----------
    parts : Bytes per part (``"process"``: what the process uses already; ``"arc geometry"``, ...).
    what : The sizes that matter, e.g. ``"grid 250 x 400, 64 samples per arc"``.
    subject : What needs the memory, as the message names it.
    """

    parts: dict[str, int]
    what: str
    subject: str = "this route"

    @property
    def total_bytes(self) -> int:
        """Estimated peak [bytes]: the sum of the parts."""
        return sum(self.parts.values())


def route_estimate(
    *,
    n_ranks: int,
    n_nodes: int,
    arcs: int,
    rank_arcs: int,
    samples: int,
    steady: bool = True,
    obstacles: bool = False,
    table_entries: int = 0,
    resident: int | None = None,
) -> MemoryEstimate:
    """Estimated peak memory of the forward DP on a grid (see the module notes for each part).

    Parameters
    ----------
    n_ranks, n_nodes : Ranks and nodes per rank.
    arcs : Candidate arcs of the grid, start and finish arcs included (the dense ``(n_nodes, width)`` blocks).
    rank_arcs : Candidate arcs into the widest rank.
    samples : Weather samples per arc.
    steady : Whether the weather is steady (time-varying weather costs arcs in two passes).
    obstacles : Whether an obstacle mask is cached per arc.
    table_entries : Entries of the failure model's compiled table (0: no model).
    resident : Memory the process uses already [bytes] (None: :func:`resident_bytes`).

    >>> e = route_estimate(n_ranks=10, n_nodes=10, arcs=1000, rank_arcs=100, samples=2, resident=0)
    >>> e.parts["arc geometry"], e.total_bytes  # 1000 arcs x (3 x 2 + 1) x 8 bytes; + 100 x (24 x 2 + 16) x 8 + 2400
    (56000, 109600)
    """
    per_sample = RANK_ARRAYS_STEADY if steady else RANK_ARRAYS_TIMED
    parts = {
        "process": resident_bytes() if resident is None else int(resident),
        "arc geometry": arcs * (3 * samples + 1) * 8,
        "obstacle masks": 10 * arcs if obstacles else 0,
        "one rank at work": rank_arcs * (per_sample * samples + RANK_ARC_ARRAYS) * 8,
        "DP state": 24 * n_ranks * n_nodes,
        "failure table": 4 * table_entries,
    }
    plural = "s" if samples != 1 else ""
    return MemoryEstimate(parts=parts, what=f"grid {n_ranks} x {n_nodes}, {samples} sample{plural} per arc")


def table_estimate(criteria_states: list[int], target_states: int, label: str = "") -> MemoryEstimate:
    """Estimated peak memory of compiling a failure model's table [bytes] (:mod:`pyroute_rel.reliability.failure`).

    The network's joint of target and criteria (``target_states x prod(states)`` float64), grown by one "unobserved"
    slot per criterion (``prod(states + 1)``) in two copies per target state, then the evidence and the table.

    ``label`` names the model's file in the message.

    >>> table_estimate([2, 2], 2).parts["failure table"]  # 3 x 3 entries x (2 x 2 + 2) arrays x 8 bytes
    432
    """
    entries = math.prod(n + 1 for n in criteria_states)
    return MemoryEstimate(
        parts={"process": resident_bytes(), "failure table": 8 * entries * (2 * target_states + 2)},
        what=f"a table of {entries:.3g} entries for {len(criteria_states)} criteria",
        subject=f"{label}: compiling this failure model" if label else "compiling this failure model",
    )


def check_budget(estimate: MemoryEstimate, *, max_memory: int | str | None = None, knobs: str) -> None:
    """Refuse a route whose estimate exceeds the budget (:func:`budget_bytes`).

    Raises
    ------
    MemoryBudgetError
        One line: the estimate, the budget and ``knobs`` (the settings that lower the need), then how to raise the
        budget.
    """
    budget, source = budget_bytes(max_memory)
    need = estimate.total_bytes
    if need > budget:
        raise MemoryBudgetError(
            f"{estimate.subject} needs about {format_bytes(need)} ({estimate.what}) but {source} is "
            f"{format_bytes(budget)}: {knobs}, or raise {MEMORY_ENV} / --max-memory"
        )
