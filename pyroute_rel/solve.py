"""Forward recursive dynamic program over the rank digraph (earliest arrival, back-pointers).

Equation (3) of Dickson et al. (2018) is a backward recursion over (node, time) pairs. On a rank digraph
it is solved forward, rank by rank: the earliest arrival at node ``j`` of rank ``k + 1`` is

    T[k+1, j] = min over arcs (i, j) of  T[k, i] + c(i, j, T[k, i])

where ``c(i, j, t)`` is the arc's sailing time when leaving ``i`` at time ``t`` (:func:`~pyroute_rel.cost.arc_costs`).
Every arc is evaluated exactly once, vectorised over all arcs into a rank.

When is earliest arrival optimal?
    Always with steady weather (the graph is then a plain shortest-path problem, and the result equals
    networkx's Dijkstra on the exported graph). With time-varying weather it is exactly optimal when arc
    costs satisfy the FIFO property -- leaving later never arrives earlier, ``t + c(i, j, t)``
    non-decreasing in ``t`` -- which holds for slowly varying wind but not, for example, when an arc is
    forbidden now and open later (a storm that passes). :func:`solve_time_expanded` handles that case
    exactly on a time grid, including waiting at a node.

References
----------
Bellman, R. (1957). Dynamic Programming. Princeton University Press.
Philpott, A. and Mason, A. (2001). Optimising yacht routes under uncertainty. 15th Chesapeake Sailing Yacht Symp.
Dickson, T., Blake, J. and Sear, D. (2018). Reliability informed routing for Autonomous Sailing Craft, eq. (3).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

import numpy as np
import numpy.typing as npt

from . import geodesy
from .cost import (
    REASONS,
    ArcCosts,
    ArcGeometry,
    WaveLoss,
    arc_costs,
    arc_quantities,
    geometry_costs,
    geometry_from_xyz,
)
from .errors import ScenarioError
from .failure import FailureModel
from .grid import Grid
from .memory import MemoryEstimate, check_budget, parse_bytes, route_estimate
from .polar import Polar, check_beyond
from .progress import progress_bar
from .times import hours_after
from .units import KN_PER_MS
from .weather import Conditions, WeatherSource

__all__ = [
    "DPResult",
    "forward_dp",
    "RoutingProblem",
    "explain_infeasible",
    "leg_costs",
    "path_costs",
    "grid_geometry",
    "route_memory",
]

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]


@runtime_checkable
class ArcMask(Protocol):
    """What the solver asks of an obstacle mask (:class:`pyroute_rel.obstacles.mask.ObstacleMask` implements it).

    Every array is laid out as the arcs into rank ``k`` (the shape of ``grid.arcs(k)``'s ``src``); ``times`` are the
    arcs' departure times (``datetime64``, UTC) of that shape, or None when nothing depends on time.
    """

    @property
    def grid(self) -> Grid:
        """The grid whose arcs the mask answers for; the solver refuses to use the mask on another."""
        ...

    @property
    def timed(self) -> bool:
        """True when the answer depends on the departure times (zones with time windows)."""
        ...

    def __call__(self, k: int, times: npt.NDArray[np.datetime64] | None) -> BoolArray:
        """Every arc into rank ``k`` that is blocked at its departure time (all tested now)."""
        ...

    def known(self, k: int) -> BoolArray:
        """Which arcs into rank ``k`` have been tested."""
        ...

    def learn(self, k: int, select: BoolArray | None = None) -> None:
        """Test the selected arcs into rank ``k`` (default all) not tested yet."""
        ...

    def hits(self, k: int, times: npt.NDArray[np.datetime64] | None) -> BoolArray:
        """Arcs into rank ``k`` known to be blocked at their departure times (untested arcs count as free)."""
        ...


@dataclass(frozen=True)
class RoutingProblem:
    """Everything the solver needs besides the grid; validated once here.

    Parameters
    ----------
    departure : Departure time (UTC).
    weather : Weather source.
    polar : Boat polar.
    failure : Compiled failure model or None.
    apf : Acceptable probability of failure in [0, 1].
    samples : Sub-segments per arc for weather sampling (>= 1).
    beyond : Polar behaviour outside its table (``"clamp"`` or ``"forbid"``).
    blocked : Optional obstacle mask for this problem's grid (an :class:`ArcMask`, e.g.
        :func:`pyroute_rel.obstacles.mask.obstacle_mask`).
    time_step_h : None (default) for continuous time: the plain earliest-arrival DP. A step [h] switches to
        the time-expanded DP: times live on the lattice ``0, step, 2 step, ...`` (arrivals are rounded *up*
        to it, so every reported time is achievable) and the craft may wait at a node.
    max_wait_h : Longest wait at one node [h] (multiples of ``time_step_h``; 0 = never wait).
    wave_loss : Optional speed loss in waves (:class:`~pyroute_rel.cost.WaveLoss`).
    prune : Cost only the arcs that can still win (default; False costs every arc). An arc takes at least its
        length over the fastest speed over ground possible (the polar's top speed plus the strongest current), so
        once each destination's few most promising arcs are costed, an arc whose bound exceeds the best of them
        cannot be the earliest arrival and is skipped. The route is the same (exact, tested); ``arcs_evaluated``
        and the forbidden counts then cover the arcs costed only. Applied where a node has more than
        :data:`PRUNE_MIN_WIDTH` candidate arcs (all-to-all grids), and not with waiting, a finish line, or a
        weather source whose bound on currents (``max_current_ms``) is not finite.
    max_memory : Memory budget of a route [bytes, or a string with a unit: ``"8G"``, ``"500M"``]; None:
        ``$PYROUTE_REL_MAX_MEMORY``, else a share of the available memory (:func:`pyroute_rel.memory.budget_bytes`).
        :func:`forward_dp` refuses a grid whose estimated peak (:func:`route_memory`) exceeds it before allocating.
    """

    departure: np.datetime64
    weather: WeatherSource
    polar: Polar
    failure: FailureModel | None = None
    apf: float = 1.0
    samples: int = 1
    beyond: str = "clamp"
    blocked: ArcMask | None = field(default=None, repr=False)
    time_step_h: float | None = None
    max_wait_h: float = 0.0
    wave_loss: WaveLoss | None = None
    prune: bool = True
    max_memory: int | str | None = None

    def __post_init__(self) -> None:
        if self.max_memory is not None:
            parse_bytes(self.max_memory, "RoutingProblem.max_memory")
        if self.time_step_h is not None and not (
            isinstance(self.time_step_h, int | float) and 0.0 < float(self.time_step_h) <= 48.0
        ):
            raise ScenarioError(f"time_step_h must be in (0, 48] [h] (got {self.time_step_h!r})")
        if not (isinstance(self.max_wait_h, int | float) and 0.0 <= float(self.max_wait_h) <= 24.0 * 60):
            raise ScenarioError(f"max_wait_h must be in [0, 1440] [h] (got {self.max_wait_h!r})")
        if self.time_step_h is not None and self.max_wait_h / self.time_step_h > 10_000:
            raise ScenarioError(
                f"max_wait_h / time_step_h must be at most 10000 wait steps per node (got {self.max_wait_h:g} h / "
                f"{self.time_step_h:g} h): use a larger time_step_h"
            )
        if self.max_wait_h > 0 and self.time_step_h is None:
            raise ScenarioError("max_wait_h > 0 needs time_step_h (waiting is modelled on a time lattice)")
        if not (isinstance(self.apf, int | float) and 0.0 <= float(self.apf) <= 1.0):
            raise ScenarioError(f"apf must be a probability in [0, 1] (got {self.apf!r})")
        if isinstance(self.samples, bool) or not isinstance(self.samples, int) or not 1 <= self.samples <= 64:
            raise ScenarioError(f"samples_per_arc must be a whole number in [1, 64] (got {self.samples!r})")
        check_beyond(self.beyond, "RoutingProblem.beyond")
        try:
            dep: Any = np.asarray(self.departure).astype("datetime64[s]")
        except (TypeError, ValueError):
            dep = np.asarray(np.datetime64("NaT"))
        if dep.shape != () or np.isnat(dep) or isinstance(self.departure, bool | int | float):
            raise ScenarioError(
                f"departure must be a UTC time (numpy datetime64 or ISO 8601 string) (got {self.departure!r})"
            )
        for name, value, ok, what in (
            (
                "weather",
                self.weather,
                isinstance(self.weather, WeatherSource),
                "a weather source (UniformWeather, GriddedWeather, ...)",
            ),
            ("polar", self.polar, isinstance(self.polar, Polar), "a Polar (pyroute_rel.polar.get_polar)"),
            (
                "failure",
                self.failure,
                self.failure is None or isinstance(self.failure, FailureModel),
                "a FailureModel (pyroute_rel.failure.load_failure_model) or None",
            ),
            (
                "blocked",
                self.blocked,
                self.blocked is None or isinstance(self.blocked, ArcMask),
                "an obstacle mask callback (an ArcMask: pyroute_rel.obstacles.mask.obstacle_mask) or None",
            ),
            (
                "wave_loss",
                self.wave_loss,
                self.wave_loss is None or isinstance(self.wave_loss, WaveLoss),
                "a WaveLoss or None",
            ),
        ):
            if not ok:
                raise ScenarioError(f"RoutingProblem.{name} must be {what} (got {type(value).__name__})")

    @property
    def n_wait(self) -> int:
        """Number of wait steps considered at each node (0: no waiting)."""
        if self.time_step_h is None:
            return 0
        return int(math.floor(self.max_wait_h / self.time_step_h + 1e-9))

    def speed_bound_kn(self) -> float | None:
        """The fastest speed over ground possible anywhere [kn] (polar top speed plus the strongest current), or
        None when the weather's bound on currents (``max_current_ms``) is not finite."""
        current = float(self.weather.max_current_ms)
        if not math.isfinite(current):
            return None
        return float(np.max(self.polar.speed_kn)) + current * KN_PER_MS

    def arrive(self, t_h: Any) -> Any:
        """Arrival time on the time lattice (rounded up), or unchanged in continuous time."""
        if self.time_step_h is None:
            return t_h
        step = float(self.time_step_h)
        with np.errstate(invalid="ignore"):
            return np.ceil(np.asarray(t_h) / step - 1e-9) * step

    def _cost_options(self) -> dict[str, Any]:
        """The settings both cost functions take from this problem (keyword arguments)."""
        return {
            "departure": self.departure,
            "weather": self.weather,
            "polar": self.polar,
            "failure": self.failure,
            "apf": float(self.apf),
            "beyond": self.beyond,
            "wave_loss": self.wave_loss,
        }

    def geometry_costs(self, geom: ArcGeometry, t0_h: Any) -> ArcCosts:
        """Arc costs on precomputed geometry (the DP's: an arc's p_f is exact where it can forbid the arc)."""
        return geometry_costs(geom, t0_h, **self._cost_options(), exact_p_f=False)

    def costs(self, lon0: Any, lat0: Any, lon1: Any, lat1: Any, t0_h: Any) -> ArcCosts:
        """Arc costs for this problem (see :func:`~pyroute_rel.cost.arc_costs`)."""
        return arc_costs(lon0, lat0, lon1, lat1, t0_h, samples=self.samples, **self._cost_options())

    def weather_at(self, lon_deg: Any, lat_deg: Any, t_h: Any) -> Conditions:
        """The weather at points [deg] and times [h after departure] (at the departure when it is steady)."""
        if self.weather.steady:
            return self.weather.sample(lon_deg, lat_deg, self.departure)
        return self.weather.sample(lon_deg, lat_deg, hours_after(self.departure, np.asarray(t_h, dtype=float)))


@dataclass
class DPResult:
    """Raw output of the forward DP.

    Attributes
    ----------
    arrival_h : Earliest arrival time at every node, shape (n_ranks, n_nodes) [h after departure];
        ``inf`` where unreachable.
    back : Source node index on the previous rank for every node, shape (n_ranks, n_nodes) (-1 where
        unreachable; rank 0's source is the start).
    finish_h : Earliest arrival at the finish [h] (inf when unreachable).
    finish_back : Last-rank node the finish is reached from (-1 when unreachable).
    arcs_evaluated : Arcs whose cost was computed (from reachable nodes).
    arcs_forbidden : Of those, how many were forbidden.
    arcs_pruned : Arcs from reachable nodes not costed because they could not win (``RoutingProblem.prune``).
    forbidden_by_reason : Forbidden arc counts per :data:`~pyroute_rel.cost.REASONS` name (an arc may count
        under several).
    forbidden_by_criterion : For arcs forbidden by the failure model, how many had each criterion fired somewhere
        along them (keys: the criteria's descriptions, e.g. ``"WH: hs_m >= 4 m"``).
    dead_rank : First rank (0..n_ranks, n_ranks = finish) with no reachable node, or None.
    wait_h : Wait at the source node before the best arc into each node, shape (n_ranks + 1, n_nodes) [h]
        (row n_ranks, column 0: before the arc into the finish); zeros without waiting.
    end_rank, end_node, end_src, end_fraction, end_wait_h : With a finish line, the arc on which the voyage
        ends: it goes into rank ``end_rank`` (``n_ranks`` = the finish point) node ``end_node`` from node
        ``end_src`` of the previous rank (a start point when ``end_rank`` is 0) and crosses the line at
        ``end_fraction`` of its length, after a wait of ``end_wait_h``. None without a finish line.
    """

    arrival_h: FloatArray
    back: npt.NDArray[np.intp]
    finish_h: float
    finish_back: int
    arcs_evaluated: int
    arcs_forbidden: int
    forbidden_by_reason: dict[str, int]
    dead_rank: int | None
    wait_h: FloatArray | None = None
    forbidden_by_criterion: dict[str, int] = field(default_factory=dict)
    end_rank: int | None = None
    end_node: int = -1
    end_src: int = -1
    end_fraction: float = 1.0
    end_wait_h: float = 0.0
    arcs_pruned: int = 0

    def waits(self) -> FloatArray:
        """Wait before each leg of the optimal path [h] (one value per leg)."""
        nodes = self.path()
        k_end = len(nodes)
        if self.wait_h is None:
            return np.zeros(k_end + 1)
        last = self.end_wait_h if self.end_rank is not None else self.wait_h[k_end, 0]
        return np.concatenate([self.wait_h[np.arange(k_end), nodes], [last]])

    def path(self) -> npt.NDArray[np.intp]:
        """Node index on each rank the optimal path visits (follows back-pointers from its end).

        All ranks normally; with a finish line, ranks ``0 .. end_rank - 1``.
        """
        n_ranks = self.arrival_h.shape[0]
        k_end = n_ranks if self.end_rank is None else self.end_rank
        node = self.finish_back if self.end_rank is None else self.end_src
        nodes = np.empty(k_end, dtype=np.intp)
        for k in range(k_end - 1, -1, -1):
            nodes[k] = node
            node = int(self.back[k, node])
        return nodes

    def start_index(self) -> int:
        """Which start point the optimal path leaves from (0 without a start line)."""
        nodes = self.path()
        if len(nodes) == 0:
            return max(self.end_src, 0)
        return int(self.back[0, nodes[0]])

    def points(self, grid: Grid) -> tuple[FloatArray, FloatArray]:
        """Track points [deg] of the optimal path: start point, one node per rank visited, end point."""
        from . import geodesy as _g

        nodes = self.path()
        s_lon, s_lat = grid.start_points
        i0 = self.start_index()
        ranks = np.arange(len(nodes))
        lon = [s_lon[i0], *grid.lon_deg[ranks, nodes]]
        lat = [s_lat[i0], *grid.lat_deg[ranks, nodes]]
        if self.end_rank is None:
            lon.append(grid.finish[0])
            lat.append(grid.finish[1])
        else:
            k = self.end_rank
            dst = grid.finish if k == grid.n_ranks else (grid.lon_deg[k, self.end_node], grid.lat_deg[k, self.end_node])
            e_lon, e_lat = _g.intermediate_point(lon[-1], lat[-1], dst[0], dst[1], self.end_fraction)
            lon.append(float(e_lon))
            lat.append(float(e_lat))
        return np.asarray(lon, dtype=float), np.asarray(lat, dtype=float)


def forward_dp(
    grid: Grid,
    problem: RoutingProblem,
    *,
    progress: bool = False,
    cost_hook: Callable[[int, ArcCosts], None] | None = None,
) -> DPResult:
    """Run the forward DP (earliest arrival per node) without building a Route.

    Each rank is one step (:func:`_rank_step`): the arcs into it are costed (:class:`_Pricing`: pruning, obstacle
    masks eager or lazy), at each departure a wait allows (:func:`_best_over_waits`), the finish line watched
    (:class:`_FinishLine`) and the forbidden arcs counted (:class:`_Tally`); the earliest arrival at each node
    and its source are kept.

    ``cost_hook(k, costs)`` is called with the costs of the arcs into rank k (for tests and diagnostics).
    """
    n_ranks, n_nodes = grid.n_ranks, grid.n_nodes
    if problem.blocked is not None and problem.blocked.grid is not grid:
        raise ValueError(
            "the problem's obstacle mask was built for another grid: build the problem for this grid "
            "(Scenario.problem(grid=...))"
        )
    check_budget(route_memory(grid, problem), max_memory=problem.max_memory, knobs=_memory_knobs(grid, problem))
    arrival = np.full((n_ranks, n_nodes), np.inf)
    back = np.full((n_ranks, n_nodes), -1, dtype=np.intp)
    finish_h, finish_back = np.inf, -1
    dead: int | None = None
    t_prev = np.zeros(grid.start_points[0].size)
    wait_into = np.zeros((n_ranks + 1, n_nodes)) if problem.n_wait else None
    line = _FinishLine(grid) if grid.finish_line is not None else None
    pricing = _Pricing.of(problem, cost_hook, finish_line=line is not None)
    tally = _Tally()
    bar = progress_bar(n_ranks + 1, enabled=progress)
    try:
        for k in range(n_ranks + 1):
            t_new, src_best, wait_best = _rank_step(grid, problem, k, t_prev, pricing, line, tally)
            if wait_into is not None:
                wait_into[k, : len(t_new)] = wait_best
            if k < n_ranks:
                arrival[k] = t_new
                back[k] = np.where(np.isfinite(t_new), src_best, -1)
                t_prev = t_new
            else:
                finish_h = float(t_new[0])
                finish_back = int(src_best[0]) if np.isfinite(finish_h) else -1
            bar.update(1)
            if not np.isfinite(t_new).any():
                dead = k
                break
            if line is not None and k < n_ranks and np.all(t_new >= line.best_h):
                break  # every node of this rank is reached after the line was crossed: nothing can beat it
    finally:
        bar.close()
    end: dict[str, Any] = {}
    if line is not None:
        finish_h, end, crossed = line.end(finish_h, finish_back, wait_into)
        dead = None if crossed else dead
    return DPResult(
        arrival_h=arrival,
        back=back,
        finish_h=finish_h,
        finish_back=finish_back,
        arcs_evaluated=tally.evaluated,
        arcs_forbidden=tally.forbidden,
        arcs_pruned=tally.pruned,
        forbidden_by_reason=tally.by_reason,
        forbidden_by_criterion=tally.by_criterion,
        dead_rank=dead,
        wait_h=wait_into,
        **end,
    )


def route_memory(grid: Grid, problem: RoutingProblem) -> MemoryEstimate:
    """Estimated peak memory of :func:`forward_dp` on a grid [bytes], from sizes alone (nothing is allocated): the
    process as it is, the arc geometry not cached on the grid yet, obstacle masks, the arrays of one rank at work,
    the DP state and the failure table (:func:`pyroute_rel.memory.route_estimate`)."""
    n_ranks, n_nodes = grid.n_ranks, grid.n_nodes

    def arcs_into(k: int) -> int:  # candidate arcs into rank k: from the start points, between ranks, to the finish
        return n_nodes * (grid.start_points[0].size if k == 0 else grid.width if k < n_ranks else 1)

    cached = sum(arcs_into(k) for k, samples in grid.cache.geometry if samples == problem.samples)
    todo = arcs_into(0) + (n_ranks - 1) * arcs_into(1) + arcs_into(n_ranks) - cached
    failure = problem.failure
    return route_estimate(
        n_ranks=n_ranks,
        n_nodes=n_nodes,
        arcs=todo,
        rank_arcs=max(arcs_into(0), arcs_into(min(1, n_ranks))),
        samples=problem.samples,
        steady=bool(problem.weather.steady),
        obstacles=problem.blocked is not None,
        table_entries=0 if failure is None else math.prod(len(c.states) + 1 for c in failure.criteria),
    )


def _memory_knobs(grid: Grid, problem: RoutingProblem) -> str:
    """What lowers a route's memory, for :class:`~pyroute_rel.errors.MemoryBudgetError`."""
    knobs = []
    if problem.samples > 1:
        knobs.append("fewer samples per arc (--samples, or a larger --sample-km)")
    knobs.append("fewer ranks or nodes (--n-ranks, --n-nodes, --half-width-km)")
    if grid.max_deviation_deg is None:
        knobs.append("banded arcs (--max-deviation 45)")
    return "use " + ", ".join(knobs)


@dataclass(frozen=True)
class _RankArcs:
    """The arcs into rank ``k``: source nodes, which leave a reached node, their departure times [h] (0 where not
    live) and their sampling geometry."""

    k: int
    src: npt.NDArray[np.intp]
    live: BoolArray
    t_src: FloatArray
    geom: ArcGeometry


@dataclass(frozen=True)
class _Priced:
    """Arcs into a rank costed at one set of departure times.

    ``time_h`` sailing time [h] and ``total_h`` arrival [h] (inf where forbidden or not live), ``reason`` flags
    (0 where not live), ``counted`` which arcs were costed (pruning skips some), ``fired`` the failure criteria
    fired along each arc (or None)."""

    time_h: FloatArray
    total_h: FloatArray
    reason: npt.NDArray[np.uint8]
    counted: BoolArray
    fired: npt.NDArray[np.uint32] | None


@dataclass(frozen=True)
class _Pricing:
    """How the arcs into a rank are costed: pruning (``bound_kn``, None: cost every arc), the obstacle mask tested
    lazily (only the arcs the DP would pick) or eagerly (every arc, when a hook sees the costs), and the hook."""

    problem: RoutingProblem
    bound_kn: float | None
    lazy: bool
    cost_hook: Callable[[int, ArcCosts], None] | None

    @classmethod
    def of(
        cls, problem: RoutingProblem, cost_hook: Callable[[int, ArcCosts], None] | None, *, finish_line: bool
    ) -> _Pricing:
        """The strategies that apply: pruning needs a positive speed bound, and no waiting, finish line or hook."""
        bound = problem.speed_bound_kn() if problem.prune else None
        prune = bound is not None and bound > 0.0 and problem.n_wait == 0 and not finish_line and cost_hook is None
        lazy = problem.blocked is not None and cost_hook is None
        return cls(problem=problem, bound_kn=bound if prune else None, lazy=lazy, cost_hook=cost_hook)

    def price(self, arcs: _RankArcs, t0: FloatArray, *, first: bool) -> _Priced:
        """Cost the arcs leaving at ``t0`` [h]; ``first``: the first departure tried (the hook sees only that)."""
        problem, k, live = self.problem, arcs.k, arcs.live
        counted = live
        if self.bound_kn is not None and live.shape[1] > PRUNE_MIN_WIDTH:
            costs, counted = _pruned_costs(problem, k, arcs.geom, t0, live, self.bound_kn, self.lazy)
        else:
            costs = problem.geometry_costs(arcs.geom, t0)
        reason = np.where(live, costs.reason, 0).astype(np.uint8)
        time_h = costs.time_h
        if problem.blocked is not None and not self.lazy:
            hit = problem.blocked(k, _block_times(problem, t0)) & live
            reason = reason | np.where(hit, REASONS["obstacle"], 0).astype(np.uint8)
            time_h = np.where(hit, np.inf, time_h)
        if self.cost_hook is not None and first:
            self.cost_hook(k, ArcCosts(time_h=np.where(live, time_h, np.inf), p_f=costs.p_f, reason=reason))
        total = np.where(live, problem.arrive(t0 + time_h), np.inf)
        if self.lazy:
            hit = _lazy_obstacles(problem.blocked, k, total, _block_times(problem, t0))
            reason = reason | np.where(hit & live, REASONS["obstacle"], 0).astype(np.uint8)
            total = np.where(hit, np.inf, total)
            time_h = np.where(hit, np.inf, time_h)
        return _Priced(time_h=time_h, total_h=total, reason=reason, counted=counted, fired=costs.fired_bits)


class _FinishLine:
    """Where a route first crosses the finish line: the earliest crossing seen so far, on which arc and after
    which wait."""

    def __init__(self, grid: Grid) -> None:
        self.grid = grid
        self.best_h = np.inf
        self.at: tuple[int, int, int, float, float] | None = None  # rank, node, source node, fraction, wait [h]

    def observe(self, arcs: _RankArcs, t0: FloatArray, priced: _Priced, wait_h: float) -> None:
        """Keep the earliest crossing among the arcs into a rank (not the finish) leaving at ``t0`` [h]."""
        frac = _crossing(self.grid, arcs.k)
        cand = np.where(np.isfinite(frac) & np.isfinite(priced.total_h), t0 + frac * priced.time_h, np.inf)
        if cand.size and np.min(cand) < self.best_h:
            jj, cc = np.unravel_index(np.argmin(cand), cand.shape)
            self.best_h = float(cand[jj, cc])
            self.at = (arcs.k, int(jj), int(arcs.src[jj, cc]), float(frac[jj, cc]), wait_h)

    def end(
        self, finish_h: float, finish_back: int, wait_into: FloatArray | None
    ) -> tuple[float, dict[str, Any], bool]:
        """(voyage time [h], the :class:`DPResult` fields of the voyage's end, whether it ends on the line)."""
        n_ranks = self.grid.n_ranks
        end: dict[str, Any] = {
            "end_rank": n_ranks,
            "end_node": 0,
            "end_src": finish_back,
            "end_fraction": 1.0,
            "end_wait_h": 0.0 if wait_into is None else float(wait_into[n_ranks, 0]),
        }
        if self.at is not None and self.best_h < finish_h:
            k_c, j_c, i_c, f_c, w_c = self.at
            end = {"end_rank": k_c, "end_node": j_c, "end_src": i_c, "end_fraction": f_c, "end_wait_h": w_c}
            return self.best_h, end, True
        return finish_h, (end if np.isfinite(finish_h) else {}), False


@dataclass
class _Tally:
    """Arcs costed, skipped by pruning and forbidden (per reason and per failure criterion) over the ranks."""

    evaluated: int = 0
    pruned: int = 0
    forbidden: int = 0
    by_reason: dict[str, int] = field(default_factory=lambda: dict.fromkeys(REASONS, 0))
    by_criterion: dict[str, int] = field(default_factory=dict)

    def add(
        self,
        live: BoolArray,
        counted: BoolArray,
        reason: npt.NDArray[np.uint8],
        fired: npt.NDArray[np.uint32] | None,
        failure: FailureModel | None,
    ) -> None:
        """Count one rank's arcs: ``reason`` the flags of arcs forbidden at every departure tried, ``fired`` the
        criteria fired along each arc at the first."""
        self.evaluated += int(counted.sum())
        self.pruned += int(live.sum()) - int(counted.sum())
        bad = live & (reason != 0)
        self.forbidden += int(bad.sum())
        if not bad.any():
            return
        values = np.bincount(reason[bad], minlength=256)  # one pass: arcs per combination of flags
        flags = np.arange(256)
        for name, bit in REASONS.items():
            self.by_reason[name] += int(values[(flags & bit) != 0].sum())
        any_failed = values[(flags & REASONS["failure"]) != 0].any()
        if failure is not None and fired is not None and any_failed:
            failed = bad & (reason & REASONS["failure"] != 0)
            bits = np.broadcast_to(fired, failed.shape)[failed]
            for i, c in enumerate(failure.criteria):
                n = int(np.count_nonzero(bits & np.uint32(1 << i)))
                self.by_criterion[c.describe()] = self.by_criterion.get(c.describe(), 0) + n


def _rank_step(
    grid: Grid,
    problem: RoutingProblem,
    k: int,
    t_prev: FloatArray,
    pricing: _Pricing,
    line: _FinishLine | None,
    tally: _Tally,
) -> tuple[FloatArray, npt.NDArray[np.intp], FloatArray | None]:
    """One step of the DP: from the arrival times ``t_prev`` [h] at rank k - 1 (the start points for k = 0), the
    earliest arrival at each node of rank k [h], the source node it comes from, and the wait before it [h] (None
    without waiting)."""
    src, valid = grid.pattern(k)
    t_src = t_prev[src]
    live = valid & np.isfinite(t_src)
    arcs = _RankArcs(
        k=k, src=src, live=live, t_src=np.where(live, t_src, 0.0), geom=grid_geometry(grid, k, problem.samples)
    )
    total, wait, reason, counted, fired = _best_over_waits(arcs, pricing, line if k < grid.n_ranks else None)
    tally.add(live, counted, reason, fired, problem.failure)
    best = np.argmin(total, axis=1)[:, None]
    t_new = np.take_along_axis(total, best, axis=1)[:, 0]
    src_best = np.take_along_axis(src, best, axis=1)[:, 0]
    wait_best = np.take_along_axis(wait, best, axis=1)[:, 0] if problem.n_wait else None
    return t_new, src_best, wait_best


def _best_over_waits(
    arcs: _RankArcs, pricing: _Pricing, line: _FinishLine | None
) -> tuple[FloatArray, FloatArray, npt.NDArray[np.uint8], BoolArray, npt.NDArray[np.uint32] | None]:
    """Waiting: each arc left after 0, 1, ... ``n_wait`` time steps; per arc the earliest arrival [h], the wait it
    takes [h], the reason flags where every departure is forbidden, which arcs were costed and the criteria fired
    at the first departure."""
    problem = pricing.problem
    step = problem.time_step_h or 0.0
    total = np.full(arcs.live.shape, np.inf)
    wait = np.zeros(arcs.live.shape)
    reason = np.zeros(arcs.live.shape, dtype=np.uint8)
    counted, fired = arcs.live, None
    for w in range(problem.n_wait + 1):
        t0 = arcs.t_src + w * step
        priced = pricing.price(arcs, t0, first=w == 0)
        if w == 0:
            fired = priced.fired
        if line is not None:
            line.observe(arcs, t0, priced, w * step)
        better = priced.total_h < total
        total = np.where(better, priced.total_h, total)
        wait = np.where(better, w * step, wait)
        # an arc counts as forbidden when it is forbidden at every departure time tried
        reason = priced.reason if w == 0 else np.where(np.isfinite(total), 0, reason | priced.reason).astype(np.uint8)
        counted = priced.counted
    return total, wait, reason, counted, fired


def _crossing(grid: Grid, k: int) -> FloatArray:
    """Fraction along each arc into rank k where it crosses the finish line (NaN: no crossing); cached."""
    cache = grid.cache.crossings
    frac = cache.get(k)
    if frac is None:
        lon0, lat0, lon1, lat1, src, _ = grid.arcs(k)
        assert grid.finish_line is not None
        (c_lon, c_lat), (d_lon, d_lat) = grid.finish_line
        # a minor arc with both ends strictly on one side of the line's great circle cannot cross the line:
        # only the arcs with ends on opposite sides (or on it, within eps) get the exact test
        normal = np.cross(geodesy.to_xyz(c_lon, c_lat), geodesy.to_xyz(d_lon, d_lat))
        side0 = geodesy.to_xyz(*np.broadcast_arrays(lon0, lat0)) @ normal
        side1 = geodesy.to_xyz(*np.broadcast_arrays(lon1, lat1)) @ normal
        eps = 1e-9  # [rad], about 6 mm: points this near the great circle count as on it (the exact test decides)
        maybe = np.broadcast_to(((side0 <= eps) & (side1 >= -eps)) | ((side0 >= -eps) & (side1 <= eps)), src.shape)
        frac = np.full(src.shape, np.nan)
        if maybe.any():
            a0, b0, a1, b1 = (np.broadcast_to(a, src.shape)[maybe] for a in (lon0, lat0, lon1, lat1))
            frac[maybe] = geodesy.crossing_fraction(a0, b0, a1, b1, c_lon, c_lat, d_lon, d_lat)
        cache[k] = frac
    return frac


def grid_geometry(grid: Grid, k: int, samples: int) -> ArcGeometry:
    """Sampling geometry of the arcs into rank k, computed once per grid and cached on it."""
    cache = grid.cache
    geom: ArcGeometry | None = cache.geometry.get((k, samples))
    if geom is None:
        xyz = cache.node_xyz
        if xyz is None:
            xyz = cache.node_xyz = geodesy.to_xyz(grid.lon_deg, grid.lat_deg)
        if k == 0:
            a = geodesy.to_xyz(*grid.start_points)[None, :, :]
            b = xyz[0][:, None, :]
        elif k == grid.n_ranks:
            a = xyz[-1][None, :, :]
            b = geodesy.to_xyz(*grid.finish)[None, None, :]
        else:
            a = xyz[k - 1][grid.src_index]
            b = xyz[k][:, None, :]
        geom = geometry_from_xyz(a, b, samples=samples, workers=None)  # threads for big blocks
        cache.geometry[k, samples] = geom
    return geom


#: Pruning is applied to ranks whose nodes have more candidate arcs than this (the paper's square grid: 160). On
#: banded grids (a dozen arcs per node) it skips a third of the arcs and costs more than that saves (measured).
PRUNE_MIN_WIDTH = 32


def _pruned_costs(
    problem: RoutingProblem, k: int, geom: ArcGeometry, t0: FloatArray, live: BoolArray, bound_kn: float, lazy: bool
) -> tuple[ArcCosts, BoolArray]:
    """Costs of the arcs into rank k that can still win (see ``RoutingProblem.prune``), and which were evaluated.

    Each destination's four arcs of smallest lower bound (departure + length / ``bound_kn``) are costed first,
    obstacles included; then every arc whose bound does not exceed the best of them. A skipped arc arrives after
    its bound, which is later than an arc already costed: it cannot be the minimum, nor tie with it. Skipped arcs
    get an infinite time, NaN p_f and no reason flags."""
    shape = live.shape
    length_nm = np.broadcast_to(geom.seg_nm[..., 0] * geom.samples, shape)
    with np.errstate(invalid="ignore"):
        lower = np.where(live, problem.arrive(t0 + length_nm / bound_kn), np.inf)
    m = min(4, shape[1])
    first = np.zeros(shape, dtype=bool)
    rows = np.arange(shape[0])[:, None]
    first[rows, np.argpartition(lower, m - 1, axis=1)[:, :m] if m < shape[1] else slice(None)] = True
    first &= live
    costs = _costs_of(problem, geom, t0, first)
    total = np.where(first, problem.arrive(t0 + costs.time_h), np.inf)
    if lazy:
        total[_lazy_obstacles(problem.blocked, k, total, _block_times(problem, t0))] = np.inf
    best = total.min(axis=1)
    rest = live & ~first & (lower <= best[:, None])
    if rest.any():
        more = _costs_of(problem, geom, t0, rest)
        costs = ArcCosts(
            time_h=np.where(rest, more.time_h, costs.time_h),
            p_f=np.where(rest, more.p_f, costs.p_f),
            reason=np.where(rest, more.reason, costs.reason).astype(np.uint8),
            fired_bits=None
            if costs.fired_bits is None and more.fired_bits is None
            else np.where(rest, more.bits(), costs.bits()),
        )
    return costs, first | rest


def _costs_of(problem: RoutingProblem, geom: ArcGeometry, t0: FloatArray, pick: BoolArray) -> ArcCosts:
    """Costs of the picked arcs of a block, laid out on the whole block (others: inf, NaN, no flags)."""
    shape = pick.shape
    sub = ArcGeometry(
        *(
            None if a is None else np.broadcast_to(a, shape + (a.shape[-1],))[pick]
            for a in (geom.lon_deg, geom.lat_deg, geom.course_deg, geom.seg_nm, geom.a_xyz, geom.b_xyz)
        )
    )
    c = problem.geometry_costs(sub, np.broadcast_to(t0, shape)[pick])
    time_h = np.full(shape, np.inf)
    p_f = np.full(shape, np.nan)
    reason = np.zeros(shape, dtype=np.uint8)
    time_h[pick], p_f[pick], reason[pick] = c.time_h, c.p_f, c.reason
    fired = None
    if c.fired_bits is not None:
        fired = np.zeros(shape, dtype=np.uint32)
        fired[pick] = c.fired_bits
    return ArcCosts(time_h=time_h, p_f=p_f, reason=reason, fired_bits=fired)


def _block_times(problem: RoutingProblem, t0: FloatArray) -> npt.NDArray[np.datetime64] | None:
    """Departure times for obstacle masks that depend on time (None when neither weather nor zones do)."""
    if problem.weather.steady and not (problem.blocked is not None and problem.blocked.timed):
        return None
    return hours_after(problem.departure, t0)


def _lazy_obstacles(blocked: Any, k: int, total: FloatArray, times: npt.NDArray[np.datetime64] | None) -> BoolArray:
    """Obstacle hits among the arcs the DP would pick: for each destination its cheapest arcs are checked
    (4, then 16, 64, ...) until its best arc is known to be free, so the minimum is exactly that of the fully
    checked arcs while most arcs far from the optimum are never tested."""
    tot = total.copy()
    width = tot.shape[1]
    rows = np.arange(tot.shape[0])
    m = 4
    hit = blocked.hits(k, times)
    tot[hit] = np.inf
    while True:
        best = np.argmin(tot, axis=1)
        known = blocked.known(k)
        need = np.isfinite(tot[rows, best]) & ~known[rows, best]
        if not need.any():
            break
        r = rows[need]
        mm = min(m, width)
        idx = (
            np.argpartition(tot[r], mm - 1, axis=1)[:, :mm]
            if mm < width
            else np.broadcast_to(np.arange(width), (r.size, width))
        )
        select = np.zeros(tot.shape, dtype=bool)
        select[r[:, None], idx] = True
        select &= np.isfinite(tot)
        blocked.learn(k, select)
        hit = blocked.hits(k, times)
        tot[hit] = np.inf
        m *= 4
    return hit


def explain_infeasible(grid: Grid, problem: RoutingProblem, result: DPResult) -> str:
    """One-line explanation of why no route exists: where the front died and what forbade the arcs."""
    k = result.dead_rank if result.dead_rank is not None else grid.n_ranks
    lon0, lat0, lon1, lat1, src, valid = grid.arcs(k)
    t_prev = np.zeros(grid.start_points[0].size) if k == 0 else result.arrival_h[k - 1]
    t0 = t_prev[src]
    live = valid & np.isfinite(t0)
    t0 = np.where(live, t0, 0.0)
    costs = problem.costs(lon0, lat0, lon1, lat1, t0)
    reason = np.where(live, costs.reason, 0)
    if problem.blocked is not None:
        reason = reason | np.where(problem.blocked(k, _block_times(problem, t0)) & live, REASONS["obstacle"], 0)
    where = "the finish" if k == grid.n_ranks else f"rank {k + 1} of {grid.n_ranks}"
    along = grid.rank_spacing_km * (k + 1)
    mid = grid.n_nodes // 2
    pos = (
        f"lon {grid.finish[0]:.2f}, lat {grid.finish[1]:.2f}"
        if k == grid.n_ranks
        else f"near lon {grid.lon_deg[k, mid]:.2f}, lat {grid.lat_deg[k, mid]:.2f}"
    )
    n_live = int(live.sum())
    parts: list[str] = []
    failure_arcs = live & (reason & REASONS["failure"] != 0)
    if problem.failure is not None and failure_arcs.any():
        counts = _criteria_counts(grid, problem, k, t0, failure_arcs)
        crit = ", ".join(f"{name} on {n} arcs" for name, n in counts.items() if n)
        parts.append(f"failure model {problem.failure.name!r} (p_f > apf {problem.apf:g}: {crit})")
    labels = {
        "polar": "no boat speed in the polar",
        "weather": "missing weather data (NaN)",
        "current": "current too strong to hold the course",
        "obstacle": "land or exclusion zones",
    }
    for name, label in labels.items():
        n = int(np.count_nonzero(live & (reason & REASONS[name] != 0)))
        if n:
            parts.append(f"{label} on {n} arcs")
    if n_live == 0:
        detail = "no arc into it starts from a reachable node"
        earlier = [
            f"{labels.get(name, 'the failure model (p_f > apf)')} on {n} arcs"
            for name, n in result.forbidden_by_reason.items()
            if n
        ]
        if earlier:
            detail += " (the reachable nodes were cut off before: " + "; ".join(earlier) + ")"
        if grid.max_deviation_deg is not None:
            detail += f"; arcs may deviate at most {grid.max_deviation_deg:g} deg from the rank direction"
    else:
        detail = f"all {n_live} arcs into it from reachable nodes are forbidden: " + "; ".join(parts)
    hint = ""
    weather_arcs = live & (reason & REASONS["weather"] != 0)
    short = _coverage_short(grid, problem, k, t0, weather_arcs) if weather_arcs.any() else None
    if short is not None:
        hint = f" (the weather does not cover these arcs: {short})"
    elif problem.failure is not None and failure_arcs.any():
        hint = " (raise --apf, or widen the grid to go around)"
    elif np.any(live & (reason & REASONS["obstacle"] != 0)):
        hint = " (widen the grid: [grid].half_width_km / --half-width-km, to go around)"
    return f"no feasible route: the front died at {where} ({along:.0f} km along the route, {pos}); {detail}{hint}"


def _coverage_short(grid: Grid, problem: RoutingProblem, k: int, t0: FloatArray, arcs: BoolArray) -> str | None:
    """Why arcs with missing weather lack it, when the reason is the weather's extent: they (or the time they take,
    at least length / the polar's top speed) lie outside what the source covers. None when it covers them (NaN
    inside the data, e.g. a land mask or a hole)."""
    from .errors import WeatherCoverageError

    lon0, lat0, lon1, lat1, src, _ = grid.arcs(k)
    ends = [np.broadcast_to(a, src.shape)[arcs] for a in (lon0, lat0, lon1, lat1)]
    lon = np.concatenate([ends[0], ends[2]])
    lat = np.concatenate([ends[1], ends[3]])
    speed = problem.speed_bound_kn()
    sail_h = geodesy.distance_nm(*ends) / speed if speed else np.zeros(ends[0].size)
    first, last = hours_after(problem.departure, np.array([t0[arcs].min(), (t0[arcs] + sail_h).max()]))
    lon_range = (float(lon.min()), float(lon.max())) if np.ptp(lon) <= 180.0 else (-180.0, 180.0)
    try:
        problem.weather.check_coverage(lon_range, (float(lat.min()), float(lat.max())), (first, last))
    except WeatherCoverageError as exc:
        return str(exc)
    return None


def _criteria_counts(grid: Grid, problem: RoutingProblem, k: int, t0: FloatArray, arcs: BoolArray) -> dict[str, int]:
    """How many of the given arcs have each failure criterion fired somewhere along them."""
    model = problem.failure
    assert model is not None
    lon0, lat0, lon1, lat1, _, _ = grid.arcs(k)
    sel = np.nonzero(arcs)
    a = [np.asarray(np.broadcast_to(x, arcs.shape))[sel] for x in (lon0, lat0, lon1, lat1, t0)]
    frac = (np.arange(problem.samples) + 0.5) / problem.samples
    lon_s, lat_s = geodesy.intermediate_point(a[0][:, None], a[1][:, None], a[2][:, None], a[3][:, None], frac)
    course = geodesy.initial_bearing_deg(lon_s, lat_s, a[2][:, None], a[3][:, None])
    time = (
        problem.departure
        if problem.weather.steady
        else hours_after(problem.departure, np.broadcast_to(a[4][:, None], lon_s.shape))
    )
    cond = problem.weather.sample(lon_s, lat_s, time)
    q = arc_quantities(cond, course)
    fired = np.asarray(model.fired({name: q[name] for name in model.quantities}))
    per_arc = np.asarray(fired.any(axis=-1))
    return {c.describe(): int(per_arc[i].sum()) for i, c in enumerate(model.criteria)}


def path_costs(
    grid: Grid, problem: RoutingProblem, nodes: Sequence[int], waits: Sequence[float] | None = None
) -> tuple[FloatArray, ArcCosts]:
    """Recompute the legs of a path (start, node per rank, finish) from their end points.

    ``waits`` [h] (n_ranks + 1 values) is the wait at each leg's start before sailing it. Returns the arrival
    time at each point [h after departure] (n_ranks + 2 values; on the time lattice when the problem has
    one) and the legs' :class:`ArcCosts`. Legs are chained one after the other, independently of the DP.
    """
    lon = np.concatenate([[grid.start[0]], grid.lon_deg[np.arange(grid.n_ranks), nodes], [grid.finish[0]]])
    lat = np.concatenate([[grid.start[1]], grid.lat_deg[np.arange(grid.n_ranks), nodes], [grid.finish[1]]])
    return leg_costs(problem, lon, lat, waits)


def leg_costs(
    problem: RoutingProblem, lon_deg: FloatArray, lat_deg: FloatArray, waits: npt.ArrayLike | None = None
) -> tuple[FloatArray, ArcCosts]:
    """Chain great-circle legs through the given points (see :func:`path_costs`)."""
    lon, lat = np.asarray(lon_deg, dtype=float), np.asarray(lat_deg, dtype=float)
    n_legs = len(lon) - 1
    wait = np.zeros(n_legs) if waits is None else np.asarray(waits, dtype=float)
    elapsed = np.zeros(n_legs + 1)
    times = np.empty(n_legs)
    p_f = np.empty(n_legs)
    reason = np.empty(n_legs, dtype=np.uint8)
    steady = bool(problem.weather.steady)
    if steady and problem.time_step_h is None:
        c = problem.costs(lon[:-1], lat[:-1], lon[1:], lat[1:], np.zeros(n_legs))
        times, p_f, reason = c.time_h, c.p_f, c.reason
        elapsed[1:] = np.cumsum(times)
    else:
        for i in range(n_legs):
            t0 = elapsed[i] + wait[i]
            c = problem.costs(lon[i], lat[i], lon[i + 1], lat[i + 1], t0)
            times[i], p_f[i], reason[i] = float(c.time_h), float(c.p_f), int(c.reason)
            elapsed[i + 1] = problem.arrive(t0 + times[i])
    return elapsed, ArcCosts(time_h=times, p_f=p_f, reason=reason)
