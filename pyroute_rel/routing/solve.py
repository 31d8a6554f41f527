"""Forward recursive dynamic program over the rank digraph (earliest arrival, back-pointers).

Equation (3) of Dickson et al. (2018) is a backward recursion over (node, time) pairs. On a rank digraph
it is solved forward, rank by rank: the earliest arrival at node ``j`` of rank ``k + 1`` is

    T[k+1, j] = min over arcs (i, j) of  T[k, i] + c(i, j, T[k, i])

where ``c(i, j, t)`` is the arc's sailing time when leaving ``i`` at time ``t``
(:func:`~pyroute_rel.routing.cost.arc_costs`). Every arc is evaluated exactly once, vectorised over all arcs into a
rank.

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

import dataclasses
import hashlib
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

import numpy as np
import numpy.typing as npt

from pyroute_rel import geodesy
from pyroute_rel.boat.manoeuvre import (
    PORT,
    STARBOARD,
    ManoeuvrePenalties,
    TrackManoeuvres,
    manoeuvre_kind,
    track_manoeuvres,
    wind_side,
)
from pyroute_rel.boat.polar import MIN_SPEED_KN, Polar, check_beyond
from pyroute_rel.errors import ScenarioError, brief, check_callable, check_flag, check_instance, check_numbers
from pyroute_rel.progress import progress_bar
from pyroute_rel.reliability.failure import FailureModel
from pyroute_rel.resources import MemoryEstimate, budget_bytes, check_budget, parse_bytes, route_estimate
from pyroute_rel.routing.cost import (
    REASONS,
    ArcCosts,
    ArcGeometry,
    PendingPieces,
    WaveLoss,
    arc_costs,
    arc_geometry,
    deferred_costs,
    geometry_costs,
    geometry_from_xyz,
)
from pyroute_rel.routing.grid import Grid
from pyroute_rel.settings import get_settings
from pyroute_rel.store import current_store, kept_by
from pyroute_rel.times import hours_after
from pyroute_rel.units import KN_PER_MS
from pyroute_rel.weather import Conditions, UniformWeather, WeatherSource
from pyroute_rel.weather.base import WEATHER_MEMBERS

__all__ = [
    "DPResult",
    "forward_dp",
    "RoutingProblem",
    "explain_cause",
    "explain_infeasible",
    "leg_costs",
    "leg_manoeuvres",
    "first_sample_wind",
    "label_min",
    "SideLabels",
    "path_costs",
    "grid_geometry",
    "route_memory",
    "steady_wind_costs",
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


def _check_departure(departure: Any) -> None:
    """A RoutingProblem's departure: one UTC time (a number, a word, a date out of range is a ScenarioError)."""
    try:
        dep: Any = np.asarray(departure).astype("datetime64[s]")
    except (TypeError, ValueError, OverflowError):
        dep = np.asarray(np.datetime64("NaT"))
    if dep.shape != () or np.isnat(dep) or isinstance(departure, bool | int | float | complex | np.number):
        raise ScenarioError(
            f"departure must be a UTC time (numpy datetime64 or ISO 8601 string) (got {brief(departure)})"
        )
    if not _FIRST_TIME <= dep <= _LAST_TIME:  # numpy wraps a year past 2.9e11 around without a word
        raise ScenarioError(
            f"departure must be a UTC time in the years 1 to 9999 (got {brief(departure)}, read as {dep})"
        )


_FIRST_TIME, _LAST_TIME = np.datetime64("0001-01-01T00:00:00", "s"), np.datetime64("9999-12-31T23:59:59", "s")


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
    wave_loss : Optional speed loss in waves (:class:`~pyroute_rel.routing.cost.WaveLoss`).
    prune : Cost only the arcs that can still win (default; False costs every arc). An arc takes at least its
        length over the fastest speed over ground possible (the polar's top speed plus the strongest current), so
        once each destination's few most promising arcs are costed, an arc whose bound exceeds the best of them
        cannot be the earliest arrival and is skipped. The route is the same (exact, tested); ``arcs_evaluated``
        and the forbidden counts then cover the arcs costed only. Applied where a node has more than
        :data:`PRUNE_MIN_WIDTH` candidate arcs (all-to-all grids), and not with waiting, a finish line, or a
        weather source whose bound on currents (``max_current_ms``) is not finite.
    max_memory : Memory budget of a route [bytes, or a string with a unit: ``"8G"``, ``"500M"``]; None:
        ``$PYROUTE_REL_MAX_MEMORY``, else a share of the available memory
        (:func:`pyroute_rel.resources.budget_bytes`). :func:`forward_dp` refuses a grid whose estimated peak
        (:func:`route_memory`) exceeds it before allocating.
    manoeuvres : Time lost by tacks and gybes (:class:`~pyroute_rel.boat.manoeuvre.ManoeuvrePenalties`); when any is
        non-zero the DP's label is (node, side of the wind) (:mod:`pyroute_rel.boat.manoeuvre`), without pruning.
    initial_side : The side the craft is on at the start (:data:`~pyroute_rel.boat.manoeuvre.PORT` or
        :data:`~pyroute_rel.boat.manoeuvre.STARBOARD`; a course's later legs start on the side the previous leg ended
        on); None: either, at no cost.
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
    manoeuvres: ManoeuvrePenalties | None = None
    initial_side: int | None = None

    def __post_init__(self) -> None:
        if self.manoeuvres is not None and not isinstance(self.manoeuvres, ManoeuvrePenalties):
            raise ScenarioError(
                f"RoutingProblem.manoeuvres must be a ManoeuvrePenalties or None (got {type(self.manoeuvres).__name__})"
            )
        if self.initial_side is not None and (
            isinstance(self.initial_side, bool) or self.initial_side not in (PORT, STARBOARD)
        ):
            raise ScenarioError(
                f"RoutingProblem.initial_side must be 0 (port), 1 (starboard) or None (got {self.initial_side!r})"
            )
        if self.max_memory is not None:
            parse_bytes(self.max_memory, "RoutingProblem.max_memory")
        if self.time_step_h is not None and (
            isinstance(self.time_step_h, bool)
            or not (isinstance(self.time_step_h, int | float) and 0.0 < float(self.time_step_h) <= 48.0)
        ):
            raise ScenarioError(f"time_step_h must be in (0, 48] [h] (got {self.time_step_h!r})")
        if isinstance(self.max_wait_h, bool) or not (
            isinstance(self.max_wait_h, int | float) and 0.0 <= float(self.max_wait_h) <= 24.0 * 60
        ):
            raise ScenarioError(f"max_wait_h must be in [0, 1440] [h] (got {self.max_wait_h!r})")
        if self.time_step_h is not None and self.max_wait_h / self.time_step_h > 10_000:
            raise ScenarioError(
                f"max_wait_h / time_step_h must be at most 10000 wait steps per node (got {self.max_wait_h:g} h / "
                f"{self.time_step_h:g} h): use a larger time_step_h"
            )
        if self.max_wait_h > 0 and self.time_step_h is None:
            raise ScenarioError("max_wait_h > 0 needs time_step_h (waiting is modelled on a time lattice)")
        if isinstance(self.apf, bool) or not (isinstance(self.apf, int | float) and 0.0 <= float(self.apf) <= 1.0):
            raise ScenarioError(f"apf must be a probability in [0, 1] (got {self.apf!r})")
        if isinstance(self.samples, bool) or not isinstance(self.samples, int) or not 1 <= self.samples <= 64:
            raise ScenarioError(f"samples_per_arc must be a whole number in [1, 64] (got {self.samples!r})")
        check_beyond(self.beyond, "RoutingProblem.beyond")
        check_flag(self.prune, "RoutingProblem.prune", ScenarioError)
        _check_departure(self.departure)
        for name, value, ok, what in (
            (
                "weather",
                self.weather,
                isinstance(self.weather, WeatherSource),
                "a weather source (UniformWeather, GriddedWeather, ...)",
            ),
            ("polar", self.polar, isinstance(self.polar, Polar), "a Polar (pyroute_rel.boat.polar.get_polar)"),
            (
                "failure",
                self.failure,
                self.failure is None or isinstance(self.failure, FailureModel),
                "a FailureModel (pyroute_rel.reliability.failure.load_failure_model) or None",
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
                got = type(value).__name__
                if name == "weather":
                    lacks = [m for m in WEATHER_MEMBERS if not hasattr(value, m)]
                    if lacks and len(lacks) < len(WEATHER_MEMBERS):
                        got += f", which lacks {', '.join(lacks)}: subclass pyroute_rel.weather.WeatherBase"
                raise ScenarioError(f"RoutingProblem.{name} must be {what} (got {got})")

    @property
    def sides(self) -> bool:
        """True when the DP keeps the side of the wind as state (a tack or gybe costs time)."""
        return self.manoeuvres is not None and self.manoeuvres.active

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
        """Arc costs on precomputed geometry (the DP's: an arc's p_f is exact where it can forbid the arc;
        :func:`steady_wind_costs` where it applies: the same numbers)."""
        fast = steady_wind_costs(self, geom)
        return fast if fast is not None else geometry_costs(geom, t0_h, **self._cost_options(), exact_p_f=False)

    def costs(self, lon0: Any, lat0: Any, lon1: Any, lat1: Any, t0_h: Any) -> ArcCosts:
        """Arc costs for this problem (see :func:`~pyroute_rel.routing.cost.arc_costs`); the points [deg] and departures
        [h after departure; inf: not reached, the arc costs inf] are numbers (NaN: missing), else a ScenarioError naming
        the argument."""
        lon0, lat0, lon1, lat1 = (
            check_numbers(v, f"RoutingProblem.costs {n}", ScenarioError, unit="deg")
            for v, n in ((lon0, "lon0"), (lat0, "lat0"), (lon1, "lon1"), (lat1, "lat1"))
        )
        t0_h = check_numbers(
            t0_h, "RoutingProblem.costs t0_h", ScenarioError, infinite=True, unit="h"
        )  # inf: not reached
        try:
            arcs = np.broadcast_shapes(lon0.shape, lat0.shape, lon1.shape, lat1.shape)
            fits = np.broadcast_shapes(arcs, t0_h.shape) == arcs
        except ValueError:
            fits = False
        if not fits:
            shapes = ", ".join(str(a.shape) for a in (lon0, lat0, lon1, lat1, t0_h))
            raise ScenarioError(
                f"RoutingProblem.costs: lon0, lat0, lon1, lat1 must broadcast together and t0_h to their shape "
                f"(got shapes {shapes})"
            )
        return arc_costs(lon0, lat0, lon1, lat1, t0_h, samples=self.samples, **self._cost_options())

    def weather_at(self, lon_deg: Any, lat_deg: Any, t_h: Any) -> Conditions:
        """The weather at points [deg] and times [h after departure] (at the departure when it is steady)."""
        if self.weather.steady:
            return self.weather.sample(lon_deg, lat_deg, self.departure)
        return self.weather.sample(lon_deg, lat_deg, hours_after(self.departure, np.asarray(t_h, dtype=float)))


def steady_wind_costs(problem: RoutingProblem, geom: ArcGeometry) -> ArcCosts | None:
    """:func:`~pyroute_rel.routing.cost.geometry_costs` of steady weather with wind only (no failure model, wave speed
    loss or current), with TWA, polar speed and time from the compiled kernel
    (:func:`pyroute_rel._kernels.cost.sail_wind`, bit-identical to numpy's arithmetic): the same numbers, 10-40x faster
    per arc (measured on the square 160 x 160 grid). None where it does not apply (the caller uses the numpy kernel);
    numba is imported only when it does."""
    if not problem.weather.steady or problem.failure is not None or problem.wave_loss is not None:
        return None
    if {"current_u_ms", "current_v_ms"} & problem.weather.fields and problem.weather.max_current_ms != 0.0:
        return None
    cond = problem.weather.sample(geom.lon_deg, geom.lat_deg, problem.departure)
    if cond.has_current:
        return None
    from pyroute_rel._kernels.cost import sail_wind

    _, v, dt = sail_wind(cond.tws_kn, cond.twd_deg, geom.course_deg, geom.seg_nm, problem.polar, beyond=problem.beyond)
    # the numpy kernel's flags: missing wind, else no speed (below MIN_SPEED_KN or NaN)
    missing = ~np.isfinite(cond.tws_kn) | ~np.isfinite(cond.twd_deg)
    reason = np.where(missing, REASONS["weather"], np.where(v >= MIN_SPEED_KN, 0, REASONS["polar"])).astype(np.uint8)
    time_h, arc_reason = dt[..., 0].copy(), reason[..., 0].copy()
    for k in range(1, dt.shape[-1]):  # summed in the numpy kernel's order
        time_h += dt[..., k]
        arc_reason |= reason[..., k]
    if dt.shape[-1] > 1:
        time_h[arc_reason != 0] = np.inf
    return ArcCosts(time_h=time_h, p_f=np.zeros(time_h.shape), reason=arc_reason, fired_bits=None)


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
    forbidden_by_reason : Forbidden arc counts per :data:`~pyroute_rel.routing.cost.REASONS` name (an arc may count
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
    labels : With manoeuvre penalties (``RoutingProblem.sides``), the DP over (node, side) labels
        (:class:`SideLabels`); ``arrival_h``, ``back`` and ``wait_h`` then hold each node's best label. None
        otherwise.
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
    labels: SideLabels | None = None

    def waits(self) -> FloatArray:
        """Wait before each leg of the optimal path [h] (one value per leg)."""
        nodes, sides, _ = self._walk()
        k_end = len(nodes)
        lab = self.labels
        if lab is not None and lab.wait_h is not None:
            last = self.end_wait_h if self.end_rank is not None else lab.wait_h[k_end, 0, lab.finish_side]
            return np.concatenate([lab.wait_h[np.arange(k_end), nodes, sides], [last]])
        if self.wait_h is None:
            return np.zeros(k_end + 1)
        last = self.end_wait_h if self.end_rank is not None else self.wait_h[k_end, 0]
        return np.concatenate([self.wait_h[np.arange(k_end), nodes], [last]])

    def path(self) -> npt.NDArray[np.intp]:
        """Node index on each rank the optimal path visits (follows back-pointers from its end).

        All ranks normally; with a finish line, ranks ``0 .. end_rank - 1``.
        """
        return self._walk()[0]

    def path_sides(self) -> npt.NDArray[np.int8] | None:
        """With side labels, the side of each arc of the optimal path (into each rank visited, then the last arc);
        None without."""
        if self.labels is None:
            return None
        _, sides, _ = self._walk()
        last = self.labels.end_side if self.end_rank is not None else self.labels.finish_side
        return np.concatenate([sides, [last]]).astype(np.int8)

    def _walk(self) -> tuple[npt.NDArray[np.intp], npt.NDArray[np.intp], int]:
        """Nodes and label sides of the optimal path on ranks ``0 .. k_end - 1``, and the start point reached."""
        n_ranks = self.arrival_h.shape[0]
        k_end = n_ranks if self.end_rank is None else self.end_rank
        node = self.finish_back if self.end_rank is None else self.end_src
        nodes = np.empty(k_end, dtype=np.intp)
        sides = np.zeros(k_end, dtype=np.intp)
        lab = self.labels
        side = 0 if lab is None else (lab.finish_from if self.end_rank is None else lab.end_from)
        for k in range(k_end - 1, -1, -1):
            nodes[k] = node
            sides[k] = side
            if lab is None:
                node = int(self.back[k, node])
            else:
                node, side = int(lab.back[k, node, side]), int(lab.from_side[k, node, side])
        return nodes, sides, node

    def start_index(self) -> int:
        """Which start point the optimal path leaves from (0 without a start line)."""
        nodes, _, start = self._walk()
        if len(nodes) == 0:
            return max(self.end_src, 0)
        return start

    def points(self, grid: Grid) -> tuple[FloatArray, FloatArray]:
        """Track points [deg] of the optimal path: start point, one node per rank visited, end point."""
        from pyroute_rel import geodesy as _g

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


@dataclass
class SideLabels:
    """The DP over (node, side of the wind) labels (:mod:`pyroute_rel.boat.manoeuvre`).

    Attributes
    ----------
    arrival_h : Earliest arrival at each label, shape (n_ranks, n_nodes, 2) [h] (side index
        :data:`~pyroute_rel.boat.manoeuvre.PORT`, :data:`~pyroute_rel.boat.manoeuvre.STARBOARD`).
    back : Source node of each label's best arc (a start point at rank 0), same shape (-1: unreachable).
    from_side : Side label of that source (at rank 0: 0), same shape.
    wait_h : Wait before each label's best arc [h], shape (n_ranks + 1, n_nodes, 2) (row n_ranks: the finish), or
        None without waiting.
    finish_side, finish_from : The finish's best label: the side of the arc into it, and its source's side.
    end_side, end_from : With a finish line, the same for the arc the voyage ends on.
    """

    arrival_h: FloatArray
    back: npt.NDArray[np.intp]
    from_side: npt.NDArray[np.intp]
    wait_h: FloatArray | None
    finish_side: int = 0
    finish_from: int = 0
    end_side: int = 0
    end_from: int = 0


def _check_dp_args(grid: Any, problem: Any, progress: Any, cost_hook: Any) -> bool:
    """The arguments of :func:`forward_dp`, checked before any work: a ScenarioError naming the argument."""
    check_instance(grid, Grid, "grid", ScenarioError, expected="a Grid (pyroute_rel.make_grid)")
    check_instance(problem, RoutingProblem, "problem", ScenarioError, expected="a RoutingProblem")
    if cost_hook is not None:
        check_callable(cost_hook, "cost_hook", ScenarioError)
    if problem.blocked is not None and problem.blocked.grid is not grid:
        raise ScenarioError(
            "the problem's obstacle mask was built for another grid: build the problem for this grid "
            "(Scenario.problem(grid=...))"
        )
    return check_flag(progress, "progress", ScenarioError)


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
    progress = _check_dp_args(grid, problem, progress, cost_hook)
    n_ranks, n_nodes = grid.n_ranks, grid.n_nodes
    estimate = route_memory(grid, problem)
    check_budget(estimate, max_memory=problem.max_memory, knobs=_memory_knobs(grid, problem))
    n_lab = 2 if problem.sides else 1
    arrival = np.full((n_ranks, n_nodes, n_lab), np.inf)
    back = np.full((n_ranks, n_nodes, n_lab), -1, dtype=np.intp)
    from_side = np.zeros((n_ranks, n_nodes, n_lab), dtype=np.intp)
    finish = (np.inf, -1, 0, 0)  # time, source node, side of the arc into the finish, its source's side
    dead: int | None = None
    t_prev = np.zeros((grid.start_points[0].size, 1))
    # the labels a rank's arcs leave from: no side (-1) without manoeuvres and at the start, else port, starboard
    prev_sides: tuple[int, ...] = (-1,) if problem.initial_side is None else (problem.initial_side,)
    wait_into = np.zeros((n_ranks + 1, n_nodes, n_lab)) if problem.n_wait else None
    line = _FinishLine(grid, problem) if grid.finish_line is not None else None
    pricing = _Pricing.of(problem, cost_hook, finish_line=line is not None, grid=grid, need_bytes=estimate.total_bytes)
    tally = _Tally()
    bar = progress_bar(n_ranks + 1, enabled=progress)
    try:
        for k in range(n_ranks + 1):
            t_new, src_best, lab_best, wait_best = _rank_step(
                grid, problem, k, t_prev, prev_sides, pricing, line, tally
            )
            if wait_into is not None:
                wait_into[k, : len(t_new)] = wait_best
            if k < n_ranks:
                arrival[k] = t_new
                back[k] = np.where(np.isfinite(t_new), src_best, -1)
                from_side[k] = np.maximum(lab_best, 0)
                t_prev = t_new
                prev_sides = (PORT, STARBOARD) if n_lab == 2 else (-1,)
            else:
                s = int(np.argmin(t_new[0]))
                ok = np.isfinite(t_new[0, s])
                finish = (float(t_new[0, s]), int(src_best[0, s]) if ok else -1, s, max(int(lab_best[0, s]), 0))
            bar.update(1)
            if not np.isfinite(t_new).any():
                dead = k
                break
            if line is not None and k < n_ranks and np.all(t_new >= line.best_h):
                break  # every node of this rank is reached after the line was crossed: nothing can beat it
    finally:
        pricing.release()
        bar.close()
    return _result(arrival, back, from_side, wait_into, finish, line, tally, dead)


def _result(
    arrival: FloatArray,
    back: npt.NDArray[np.intp],
    from_side: npt.NDArray[np.intp],
    wait_into: FloatArray | None,
    finish: tuple[float, int, int, int],
    line: _FinishLine | None,
    tally: _Tally,
    dead: int | None,
) -> DPResult:
    """The :class:`DPResult` of the DP's label arrays (last axis: one label, or port and starboard)."""
    finish_h, finish_back, finish_side, finish_from = finish
    best = np.argmin(arrival, axis=2)[..., None]
    node_wait = None if wait_into is None else wait_into[..., 0]
    labels = None
    if arrival.shape[2] == 2:
        labels = SideLabels(
            arrival_h=arrival,
            back=back,
            from_side=from_side,
            wait_h=wait_into,
            finish_side=finish_side,
            finish_from=finish_from,
        )
        if wait_into is not None:
            node_wait = np.concatenate(
                [np.take_along_axis(wait_into[:-1], best, axis=2)[..., 0], wait_into[-1:, :, finish_side]]
            )
    end: dict[str, Any] = {}
    if line is not None:
        finish_h, end, crossed = line.end(finish_h, finish_back, node_wait)
        dead = None if crossed else dead
        if labels is not None:
            labels.end_side, labels.end_from = end.get("end_side", finish_side), end.get("end_from", finish_from)
    end.pop("end_from", None)
    end.pop("end_side", None)
    return DPResult(
        arrival_h=np.take_along_axis(arrival, best, axis=2)[..., 0],
        back=np.take_along_axis(back, best, axis=2)[..., 0],
        finish_h=finish_h,
        finish_back=finish_back,
        arcs_evaluated=tally.evaluated,
        arcs_forbidden=tally.forbidden,
        arcs_pruned=tally.pruned,
        forbidden_by_reason=tally.by_reason,
        forbidden_by_criterion=tally.by_criterion,
        dead_rank=dead,
        wait_h=node_wait,
        labels=labels,
        **end,
    )


def route_memory(grid: Grid, problem: RoutingProblem) -> MemoryEstimate:
    """Estimated peak memory of :func:`forward_dp` on a grid [bytes], from sizes alone (nothing is allocated): the
    process as it is, the arc geometry not cached on the grid yet, obstacle masks, the arrays of one rank at work,
    the DP state and the failure table (:func:`pyroute_rel.resources.route_estimate`)."""
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
    side: npt.NDArray[np.int8] | None = None
    penalty_h: FloatArray | None = None


def _arc_sides(problem: RoutingProblem, geom: ArcGeometry, t0: FloatArray) -> tuple[npt.NDArray[np.int8], FloatArray]:
    """The side each arc is sailed on and the time a change of side onto it costs [h]
    (:mod:`pyroute_rel.boat.manoeuvre`): from the wind at the arc's first sample, at its departure ``t0`` [h]."""
    assert problem.manoeuvres is not None
    side, twa, tws = first_sample_wind(problem, geom, t0)
    return side, problem.manoeuvres.penalty_h(manoeuvre_kind(twa), tws)


@dataclass(frozen=True)
class _Pricing:
    """How the arcs into a rank are costed: pruning (``bound_kn``, None: cost every arc), the obstacle mask tested
    lazily (only the arcs the DP would pick) or eagerly (every arc, when a hook sees the costs), the arcs judged on
    the pieces they cross lazily (``lazy_pieces``: only the arcs the DP would pick) or eagerly, and the hook."""

    problem: RoutingProblem
    bound_kn: float | None
    lazy: bool
    cost_hook: Callable[[int, ArcCosts], None] | None
    lazy_pieces: bool = False
    memo: dict[int, tuple[_Costed, Any]] = field(default_factory=dict)
    compiled: bool = False
    #: With the compiled step on uniform weather: its wind (:meth:`~pyroute_rel.weather.UniformWeather.wind_boxes`),
    #: sampled in the kernel.
    wind_boxes: tuple[float, float, FloatArray, FloatArray] | None = None
    #: With the compiled step and a failure model (uniform weather with patches): the fields and classifier it judges
    #: arcs with (:func:`~pyroute_rel._kernels.crossings.box_fields`).
    fail_fields: Any = None
    #: With ``fail_fields``: the judgements of the grid's arcs kept from earlier DPs (a
    #: :class:`~pyroute_rel._kernels.dp.Judged` this DP holds, :func:`_kept_judgements`), None: judged afresh.
    judged: Any = None
    #: With ``fail_fields``: the failure model's criteria as the tally names them (``describe()``, in order).
    fail_names: tuple[str, ...] = ()

    @classmethod
    def of(
        cls,
        problem: RoutingProblem,
        cost_hook: Callable[[int, ArcCosts], None] | None,
        *,
        finish_line: bool,
        grid: Grid | None = None,
        need_bytes: int = 0,
    ) -> _Pricing:
        """The strategies that apply: pruning needs a positive speed bound, and no waiting, finish line, hook or side
        labels (it bounds each node's best arc, not each label's). With ``grid``, a failure model's judgements kept
        for it are taken (:func:`_kept_judgements`; ``need_bytes``: the DP's estimated peak [bytes],
        :func:`route_memory`, which they must fit beside); the caller then calls :meth:`release`."""
        bound = problem.speed_bound_kn() if problem.prune else None
        prune = (
            bound is not None
            and bound > 0.0
            and problem.n_wait == 0
            and not finish_line
            and cost_hook is None
            and not problem.sides
        )
        lazy = problem.blocked is not None and cost_hook is None
        engines = get_settings()
        lazy_pieces = engines.lazy_pieces and problem.failure is not None and cost_hook is None and not finish_line
        fail_fields = None
        if (  # a failure model on uniform weather with patches: judged in the compiled step (one label, pruning)
            engines.compiled_rank_step
            and problem.failure is not None
            and lazy_pieces
            and prune
            and type(problem.weather) is UniformWeather
        ):
            from pyroute_rel._kernels.crossings import box_fields

            fail_fields = box_fields(problem.weather, problem.failure, problem.apf)
        compiled = (
            engines.compiled_rank_step
            and problem.weather.steady
            and (problem.failure is None or fail_fields is not None)
            and problem.wave_loss is None
            and problem.blocked is None
            and problem.time_step_h is None
            and not finish_line
            and cost_hook is None
            and problem.weather.max_current_ms == 0.0
        )
        if compiled:  # the compiled step prunes side labels too (each label against its own best)
            prune = bound is not None and bound > 0.0
        boxes = problem.weather.wind_boxes() if compiled and type(problem.weather) is UniformWeather else None
        fail_fields = fail_fields if compiled else None
        judged = None
        if fail_fields is not None and grid is not None:
            judged = _kept_judgements(grid, problem, fail_fields, need_bytes)
        names = (
            ()
            if fail_fields is None or problem.failure is None
            else tuple(c.describe() for c in problem.failure.criteria)
        )
        return cls(
            problem=problem,
            bound_kn=bound if prune else None,
            lazy=lazy,
            cost_hook=cost_hook,
            lazy_pieces=lazy_pieces,
            compiled=compiled,
            wind_boxes=boxes,
            fail_fields=fail_fields,
            judged=judged,
            fail_names=names,
        )

    def release(self) -> None:
        """The DP is done with its kept judgements (another may take them)."""
        if self.judged is not None:
            self.judged.lock.release()

    def price(self, arcs: _RankArcs, t0: FloatArray, *, first: bool, from_side: int = -1) -> _Priced:
        """Cost the arcs leaving at ``t0`` [h]; ``first``: the first departure tried (the hook sees only that);
        ``from_side``: the side label they leave from (-1: none), which a change of side costs time from."""
        problem, k, live = self.problem, arcs.k, arcs.live
        counted = live
        side = change_h = None
        steady = problem.weather.steady and problem.time_step_h is None
        if self.bound_kn is not None and live.shape[1] > PRUNE_MIN_WIDTH:
            costed, counted = _pruned_costs(problem, k, arcs.geom, t0, live, self.bound_kn, self.lazy, self.lazy_pieces)
        elif steady and k in self.memo:  # the other side label's departures: the same costs in steady weather
            costed, (side, change_h) = self.memo[k]
        else:
            costed = _Costed.of(problem, arcs.geom, t0, self.lazy_pieces)
            if problem.sides:
                side, change_h = _arc_sides(problem, arcs.geom, t0)
                if steady:
                    self.memo.clear()
                    self.memo[k] = (costed, (side, change_h))
        pen = None if side is None or change_h is None or from_side < 0 else np.where(side != from_side, change_h, 0.0)
        time_h = costed.costs.time_h
        hit = None
        if problem.blocked is not None and not self.lazy:
            hit = problem.blocked(k, _block_times(problem, t0)) & live
            time_h = np.where(hit, np.inf, time_h)
        if self.cost_hook is not None and first:
            reason = np.where(live, costed.costs.reason, 0).astype(np.uint8)
            if hit is not None:
                reason = reason | np.where(hit, REASONS["obstacle"], 0).astype(np.uint8)
            self.cost_hook(k, ArcCosts(time_h=np.where(live, time_h, np.inf), p_f=costed.costs.p_f, reason=reason))
        total = np.where(live, problem.arrive(t0 + time_h if pen is None else (t0 + time_h) + pen), np.inf)
        if self.lazy or costed.pending:
            judged = bool(costed.pending)
            times = _block_times(problem, t0) if self.lazy else None
            for s in (None,) if side is None else (PORT, STARBOARD):  # each label's best arc must be judged
                total, found = _settle(costed, total, side, s, problem.blocked if self.lazy else None, k, times)
                hit = found if found is not None else hit
            if judged:  # (nothing judged on pieces: the times are those of the costs)
                time_h = np.where(np.isfinite(costed.costs.time_h), time_h, np.inf)  # forbidden on pieces now
            if self.lazy:
                assert hit is not None  # (a lazy obstacle mask always answers)
                total = np.where(hit, np.inf, total)
                time_h = np.where(hit, np.inf, time_h)
        reason = np.where(live, costed.costs.reason, np.uint8(0)).astype(np.uint8, copy=False)
        if hit is not None:
            np.bitwise_or(reason, np.uint8(REASONS["obstacle"]), out=reason, where=hit & live)
        return _Priced(
            time_h=time_h,
            total_h=total,
            reason=reason,
            counted=counted,
            fired=costed.costs.fired_bits,
            side=side,
            penalty_h=pen,
        )


#: How many of each node's earliest arrivals not judged yet :func:`_lazy_pieces` judges at first (then 4 times more
#: each round). One call judges a batch at a fixed cost of a few ms with gridded weather: 4 judged 4x the arcs of 1
#: (the ERA5 example at apf 0.2) and was 10 % faster where many best arcs are forbidden, 6 % slower where few are
#: (members 0 and 1 of the sweep benchmark's ensemble, 160 ranks, apf 0.2, measured under load): 1, the best arc.
LAZY_FIRST = 1


@dataclass
class _Costed:
    """The costs of the arcs into a rank at one set of departures and the arcs still to judge on the pieces they
    cross (in parts, each its own :class:`~pyroute_rel.routing.cost.PendingPieces`; none when judged eagerly);
    :meth:`judge` updates the costs."""

    costs: ArcCosts
    pending: list[PendingPieces] = field(default_factory=list)

    @classmethod
    def of(cls, problem: RoutingProblem, geom: ArcGeometry, t0: FloatArray, lazy_pieces: bool) -> _Costed:
        """The arcs' costs, judged on pieces eagerly or (``lazy_pieces``) left pending."""
        if not lazy_pieces:
            return cls(problem.geometry_costs(geom, t0))
        costs, pending = deferred_costs(geom, t0, **problem._cost_options())
        return cls(costs, [] if pending is None else [pending])

    def waiting(self, shape: tuple[int, ...]) -> BoolArray:
        """The arcs not judged yet, over the block."""
        size = math.prod(shape)
        out = np.zeros(size, dtype=bool)
        for part in self.pending:
            out |= part.waiting(size)
        return out.reshape(shape)

    def judge(self, flat: npt.NDArray[np.intp]) -> npt.NDArray[np.intp]:
        """Judge the arcs at flat indices ``flat`` (increasing, waiting) on their pieces; returns those that are
        forbidden, whose time becomes inf, flags get the failure reason and criteria those fired along them."""
        over = np.zeros(flat.size, dtype=bool)
        bits = np.zeros(flat.size, dtype=np.uint32)
        for part in self.pending:
            mine = np.isin(flat, part.index, assume_unique=True) if len(self.pending) > 1 else slice(None)
            over[mine], bits[mine] = part.judge(flat[mine])
        bad = flat[over]
        if bad.size:
            c = self.costs
            shape = np.shape(c.time_h)
            time_h = np.array(c.time_h, dtype=float)
            reason = np.array(c.reason, dtype=np.uint8)
            fired = np.array(c.bits(), dtype=np.uint32).reshape(shape)
            time_h.reshape(-1)[bad] = np.inf
            reason.reshape(-1)[bad] |= np.uint8(REASONS["failure"])
            fired.reshape(-1)[bad] |= bits[over]
            self.costs = ArcCosts(time_h=time_h, p_f=c.p_f, reason=reason, fired_bits=fired)
        return bad


#: Judgements kept for the compiled failure step (:func:`_kept_judgements`): at most this many, of at most this many
#: bytes in all [bytes] (the store's shelf ``dp.judged``; least recently used dropped first).
JUDGED_KEPT = 4
JUDGED_MAX_BYTES = 512 * 1024**2


def _kept_judgements(grid: Grid, problem: RoutingProblem, fields: Any, need_bytes: int) -> Any:
    """The judgements of the grid's arcs kept for this failure model, weather and apf (a
    :class:`~pyroute_rel._kernels.dp.Judged`, held by the caller until :meth:`_Pricing.release`), made empty on first
    use; None where nothing is to be kept: the store keeps nothing (``kept(False)``), the model has more criteria than
    a judgement holds (:attr:`~pyroute_rel._kernels.dp.Judged.MAX_CRITERIA`), they would not fit in
    :data:`JUDGED_MAX_BYTES` or beside the DP's peak ``need_bytes`` [bytes] in the memory budget
    (:func:`~pyroute_rel.resources.budget_bytes`), or another DP holds them (it runs in another thread).

    They live in the current store (:mod:`pyroute_rel.store`), keyed by content: the grid's (:func:`_grid_key`), the
    samples per arc and the fields the arcs are judged with (:meth:`~pyroute_rel._kernels.crossings.BoxFields.key`:
    weather, failure model, apf). What they hold does not depend on time (steady weather), so every DP on the same
    grid, samples and fields may take them."""
    store = current_store()
    if not store.keep:
        return None
    from pyroute_rel._kernels.dp import Judged

    shelf = store.shelf("dp.judged", limit=JUDGED_KEPT, max_bytes=JUDGED_MAX_BYTES, nbytes=lambda j: j.nbytes)
    key = (_grid_key(grid), problem.samples, fields.key())
    judged = shelf.get(key)
    if judged is None:
        arcs = grid.start_pattern.size + (grid.n_ranks - 1) * grid.n_nodes * grid.width + grid.n_nodes  # every rank's
        nbytes = Judged.BYTES_PER_ARC * arcs
        if fields.base.size > Judged.MAX_CRITERIA or nbytes > JUDGED_MAX_BYTES:
            return None
        if need_bytes + nbytes > budget_bytes(problem.max_memory)[0]:
            return None
        judged = shelf.put(key, Judged(nbytes), replace=False)
    return judged if judged.lock.acquire(blocking=False) else None


def _grid_key(grid: Grid) -> str:
    """A digest of a grid's content (every field but its cache: name, and the dtype, shape and bytes of an array or
    the repr of anything else), which its arcs' geometry follows from; kept by the grid (:func:`kept_by`)."""

    def make() -> str:
        digest = hashlib.blake2b(digest_size=16)
        for f in dataclasses.fields(grid):
            if f.name == "cache":
                continue
            value = getattr(grid, f.name)
            if isinstance(value, np.ndarray):
                a = np.ascontiguousarray(value)
                digest.update(f"{f.name}:{a.dtype.str}:{a.shape}:".encode())
                digest.update(a.tobytes())
            else:
                digest.update(f"{f.name}={value!r};".encode())
        return digest.hexdigest()

    return kept_by(grid, "_content_key", make)  # type: ignore[no-any-return]


def _settle(
    costed: _Costed,
    total: FloatArray,
    side: npt.NDArray[np.int8] | None,
    label: int | None,
    blocked: Any,
    k: int,
    times: npt.NDArray[np.datetime64] | None,
) -> tuple[FloatArray, BoolArray | None]:
    """Judge arcs lazily until each destination's best arc into the label ``label`` (its arcs: those sailed on that
    side; None: all) is known free of obstacles (``blocked``: tested lazily, None: no lazy mask) and judged on its
    pieces. Returns ``total`` [h] with the arcs found forbidden on pieces at inf, and the obstacle hits known (None
    without a lazy mask)."""
    hit = None
    while True:
        cand = total if label is None else np.where(side == label, total, np.inf)
        if blocked is not None:
            hit = _lazy_obstacles(blocked, k, cand, times)
            if not costed.pending:  # nothing to judge on pieces
                return total, hit
            cand = np.where(hit, np.inf, cand)
        bad = _lazy_pieces(costed, cand)
        if bad.size:
            total = total.copy()
            total.reshape(-1)[bad] = np.inf
        if not bad.size or blocked is None:  # else the new best arcs may be untested for obstacles
            return total, hit


def _lazy_pieces(costed: _Costed, total: FloatArray) -> npt.NDArray[np.intp]:
    """Arcs forbidden on the pieces they cross among those the DP would pick (flat indices): for each destination
    whose best arc is not judged yet, its :data:`LAZY_FIRST` earliest arrivals not judged yet are judged (then 4
    times more each round) until its best arc is judged allowed, so the minimum, and the arc reaching it, are those
    of the fully judged arcs (an arc not judged arrives no earlier than the best; on a tie, after it) while most arcs
    are never judged."""
    if not costed.pending:
        return np.zeros(0, dtype=np.intp)
    tot = total.copy()
    shape = tot.shape
    rows = np.arange(shape[0])
    waiting = costed.waiting(shape)
    found = []
    m = LAZY_FIRST
    while True:
        best = np.argmin(tot, axis=1)
        need = np.isfinite(tot[rows, best]) & waiting[rows, best]
        if not need.any():
            break
        r = rows[need]
        select = np.zeros(shape, dtype=bool)
        if m == 1:  # its best arc
            select[r, best[r]] = True
        else:
            mm = min(m, shape[1])
            cand = np.where(waiting[r], tot[r], np.inf)
            idx = np.argpartition(cand, mm - 1, axis=1)[:, :mm] if mm < shape[1] else slice(None)
            select[r[:, None], idx] = True
            select &= waiting & np.isfinite(tot)
        flat = np.flatnonzero(select)
        bad = costed.judge(flat)
        waiting.reshape(-1)[flat] = False
        tot.reshape(-1)[bad] = np.inf
        found.append(bad)
        m *= 4
    return np.concatenate(found) if found else np.zeros(0, dtype=np.intp)


class _FinishLine:
    """Where a route first crosses the finish line: the earliest crossing seen so far, on which arc and after
    which wait."""

    def __init__(self, grid: Grid, problem: RoutingProblem) -> None:
        self.grid = grid
        self.problem = problem
        self.best_h = np.inf
        # rank, node, source node, fraction, wait [h], side of the arc, side label of its source
        self.at: tuple[int, int, int, float, float, int, int] | None = None

    def observe(
        self,
        arcs: _RankArcs,
        t0: FloatArray,
        priced: _Priced,
        wait_h: float,
        from_side: int = -1,
        blocked: Callable[[int, int], bool] | None = None,
    ) -> None:
        """Keep the earliest crossing among the arcs into a rank (not the finish) leaving at ``t0`` [h] (from the
        side label ``from_side``; a manoeuvre at the arc's start delays the crossing by its penalty).

        ``blocked(node, arc)``: whether an arc meets an obstacle, when the obstacles are tested lazily (the costs
        then leave untested the arcs that are not a node's best, and one of them may cross the line first)."""
        frac = _crossing(self.grid, arcs.k)
        crosses = np.isfinite(frac) & np.isfinite(priced.total_h)
        if not crosses.any():
            return
        along = np.broadcast_to(t0, frac.shape) + self._to_line(arcs, t0, frac, crosses)
        if priced.penalty_h is not None:
            along = along + priced.penalty_h
        # on a time lattice the crossing is rounded up as every arrival is (the route's last leg reports it so)
        cand = np.where(crosses, self.problem.arrive(along), np.inf)
        while cand.size and np.min(cand) < self.best_h:
            jj, cc = np.unravel_index(np.argmin(cand), cand.shape)
            if blocked is not None and blocked(int(jj), int(cc)):
                cand[jj, cc] = np.inf
                continue
            self.best_h = float(cand[jj, cc])
            side = 0 if priced.side is None else int(priced.side[jj, cc])
            self.at = (arcs.k, int(jj), int(arcs.src[jj, cc]), float(frac[jj, cc]), wait_h, side, max(from_side, 0))
            break

    def _to_line(self, arcs: _RankArcs, t0: FloatArray, frac: FloatArray, crosses: BoolArray) -> FloatArray:
        """The time from each crossing arc's departure to the line [h]: the arc from its start to the crossing point
        costed as a leg of the route (:func:`leg_manoeuvres` costs the route's last leg so), at the time it leaves
        (in time-varying weather the craft's speed along an arc is not uniform: a fraction of the arc's time is
        not the time to the line)."""
        out = np.full(frac.shape, np.inf)
        lon0, lat0, lon1, lat1, _, _ = self.grid.arcs(arcs.k)
        a0, b0, a1, b1, t = (np.broadcast_to(a, frac.shape)[crosses] for a in (lon0, lat0, lon1, lat1, t0))
        e_lon, e_lat = geodesy.intermediate_point(a0, b0, a1, b1, frac[crosses])
        out[crosses] = self.problem.costs(a0, b0, e_lon, e_lat, t).time_h
        return out

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
            k_c, j_c, i_c, f_c, w_c, s_c, l_c = self.at
            end = {"end_rank": k_c, "end_node": j_c, "end_src": i_c, "end_fraction": f_c, "end_wait_h": w_c}
            end.update(end_side=s_c, end_from=l_c)
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
        n_counted = int(np.count_nonzero(counted))
        self.evaluated += n_counted
        self.pruned += int(np.count_nonzero(live)) - n_counted
        bad = live & (reason != 0)
        n_bad = int(np.count_nonzero(bad))
        self.forbidden += n_bad
        if not n_bad:
            return
        values = np.bincount(reason[bad], minlength=256)  # one pass: arcs per combination of flags
        per_reason = (_REASON_OF_FLAGS @ values).tolist()  # arcs with each reason's bit among their flags
        for name, n in zip(REASONS, per_reason, strict=True):
            self.by_reason[name] += n
        any_failed = per_reason[_FAILURE_ROW] > 0
        if failure is not None and fired is not None and any_failed:
            failed = bad & (reason & REASONS["failure"] != 0)
            bits = np.broadcast_to(fired, failed.shape)[failed]
            for i, c in enumerate(failure.criteria):
                n = int(np.count_nonzero(bits & np.uint32(1 << i)))
                self.by_criterion[c.describe()] = self.by_criterion.get(c.describe(), 0) + n


# : Per reason of :data:`~pyroute_rel.routing.cost.REASONS` (rows), which of the 256 combinations of flags hold its bit
# (1).
_REASON_OF_FLAGS = np.array([(np.arange(256) & bit) != 0 for bit in REASONS.values()], dtype=np.intp)
_FAILURE_ROW = list(REASONS).index("failure")


def _rank_step(
    grid: Grid,
    problem: RoutingProblem,
    k: int,
    t_prev: FloatArray,
    prev_sides: tuple[int, ...],
    pricing: _Pricing,
    line: _FinishLine | None,
    tally: _Tally,
) -> tuple[FloatArray, npt.NDArray[np.intp], npt.NDArray[np.intp], FloatArray | None]:
    """One step of the DP: from the arrival times ``t_prev`` [h] at the labels of rank k - 1 (the start points for
    k = 0), shape (nodes, labels), whose sides are ``prev_sides`` (-1: no side), the earliest arrival at each label
    of rank k [h] (one label, or port and starboard), the source node and the source label's side it comes from,
    and the wait before it [h] (None without waiting)."""
    src, valid = grid.pattern(k)
    geom = grid_geometry(grid, k, problem.samples)
    if pricing.compiled:
        done = _compiled_step(problem, k, src, valid, geom, t_prev, prev_sides, pricing, tally)
        if done is not None:
            return done
    cols = []
    for c, from_side in enumerate(prev_sides):
        t_src = t_prev[:, c][src]
        live = valid & np.isfinite(t_src)
        arcs = _RankArcs(k=k, src=src, live=live, t_src=np.where(live, t_src, 0.0), geom=geom)
        cols.append((live, *_best_over_waits(arcs, pricing, line if k < grid.n_ranks else None, from_side)))
    _tally_columns(tally, cols, problem.failure)
    t_new, j_best, c_best = label_min(cols[0][1][None] if len(cols) == 1 else np.stack([c[1] for c in cols]))
    src_best = src[np.arange(src.shape[0])[:, None], j_best]  # np.take_along_axis(src, j_best, axis=1)
    lab_best = np.asarray(prev_sides, dtype=np.intp)[c_best]
    wait_best = None
    if problem.n_wait:
        waits = np.stack([c[2] for c in cols])  # (source labels, labels, destinations, arcs)
        n_dst, n_lab = t_new.shape
        wait_best = waits[c_best, np.arange(n_lab)[None, :], np.arange(n_dst)[:, None], j_best]
    return t_new, src_best, lab_best, wait_best


def _compiled_step(
    problem: RoutingProblem,
    k: int,
    src: npt.NDArray[np.intp],
    valid: BoolArray,
    geom: ArcGeometry,
    t_prev: FloatArray,
    prev_sides: tuple[int, ...],
    pricing: _Pricing,
    tally: _Tally,
) -> tuple[FloatArray, npt.NDArray[np.intp], npt.NDArray[np.intp], None] | None:
    """:func:`_rank_step` of a steady wind-only problem, or of a failure model on uniform weather with patches, in
    compiled code (:func:`pyroute_rel._kernels.dp.rank_step`): the weather sampled here, at the arcs the step asks
    for (with pruning, only those it costs), the rest there; a failure model's judgements of the arcs into rank
    ``k`` kept from earlier DPs where ``pricing`` holds them. None when the weather turns out to have a current there
    (NaN included), or a failure model's rank is too narrow to prune and has nodes of more than four arcs (the
    kernel, which prunes, would cost fewer arcs than the numpy path): the numpy path then costs the rank."""
    from pyroute_rel._kernels.dp import BoxWind, FailureJudge, rank_step

    shape = valid.shape + (geom.samples,)

    def full(a: npt.NDArray[Any], to: tuple[int, ...]) -> npt.NDArray[Any]:  # no copy where it has the shape
        return a if a.shape == to else np.broadcast_to(a, to)

    wind: Callable[[npt.NDArray[np.intp] | None], tuple[FloatArray, FloatArray] | None] | BoxWind
    if pricing.wind_boxes is not None:  # uniform weather: its wind sampled in the kernel
        wind = BoxWind(*pricing.wind_boxes, full(geom.lon_deg, shape), full(geom.lat_deg, shape))
    else:
        wind = _sampler(problem, geom, shape)
    bound_kn = pricing.bound_kn
    prune = bound_kn if bound_kn is not None and valid.shape[1] > PRUNE_MIN_WIDTH else None
    failure = None
    if pricing.fail_fields is not None:
        if prune is None and bound_kn is not None and valid.shape[1] <= 4:
            prune = bound_kn  # (the kernel costs each node's first four live arcs: here all of them, as unpruned)
        if prune is None or geom.a_xyz is None or geom.b_xyz is None:
            return None  # a narrow rank that pruning would thin: the numpy path judges it
        a_xyz, b_xyz = _arc_ends(geom, valid.shape)
        judged = None if pricing.judged is None else pricing.judged.rank(k, valid.shape)
        failure = FailureJudge(pricing.fail_fields, a_xyz, b_xyz, judged)
    step = rank_step(
        wind, full(geom.course_deg, shape), full(geom.seg_nm[..., 0], valid.shape), t_prev, full(src, valid.shape),
        valid, problem.polar, beyond=problem.beyond, bound_kn=prune, from_sides=prev_sides,
        penalties=problem.manoeuvres if problem.sides else None, failure=failure,
    )  # fmt: skip
    if step is None:
        return None
    if step.by_criterion is not None and step.failed:
        assert problem.failure is not None
        tally.by_reason["failure"] += step.failed
        for name, n in zip(pricing.fail_names, step.by_criterion.tolist(), strict=True):
            tally.by_criterion[name] = tally.by_criterion.get(name, 0) + n
    tally.evaluated += step.costed
    tally.pruned += step.live - step.costed
    tally.forbidden += step.forbidden
    tally.by_reason["polar"] += step.no_speed
    tally.by_reason["weather"] += step.no_wind
    src_best = np.take_along_axis(src, step.j_best, axis=1)
    return step.t_best, src_best, np.asarray(prev_sides, dtype=np.intp)[step.c_best], None


def _arc_ends(geom: ArcGeometry, shape: tuple[int, ...]) -> tuple[FloatArray, FloatArray]:
    """The arcs' starts, shape ``shape + (3,)``, and each node's position (where its arcs end), shape (nodes, 3), as
    unit vectors in contiguous arrays, for the compiled failure step; kept by the geometry (:func:`kept_by`)."""

    def make() -> tuple[FloatArray, FloatArray]:
        assert geom.a_xyz is not None and geom.b_xyz is not None
        xyz = shape + (3,)
        a = geom.a_xyz if geom.a_xyz.shape == xyz else np.array(np.broadcast_to(geom.a_xyz, xyz), order="C")
        b = geom.b_xyz[:, 0, :]  # a node's arcs end at it
        return a, np.array(b if b.shape[0] == xyz[0] else np.broadcast_to(b, xyz[::2]), order="C")

    return kept_by(geom, f"_arc_ends{shape}", make)  # type: ignore[no-any-return]


def _sampler(
    problem: RoutingProblem, geom: ArcGeometry, shape: tuple[int, ...]
) -> Callable[[npt.NDArray[np.intp] | None], tuple[FloatArray, FloatArray] | None]:
    """:func:`_compiled_step`'s wind at the arcs ``pick`` (flat indices node * arcs + arc) or every arc (None),
    sampled by the weather: None where it has a current."""

    def full(a: npt.NDArray[Any], to: tuple[int, ...]) -> npt.NDArray[Any]:  # no copy where it has the shape
        return a if a.shape == to else np.broadcast_to(a, to)

    def wind(pick: npt.NDArray[np.intp] | None) -> tuple[FloatArray, FloatArray] | None:
        lon, lat = full(geom.lon_deg, shape), full(geom.lat_deg, shape)
        if pick is not None:  # the arcs' rows of (nodes * arcs, samples): a view where the geometry has the shape
            lon, lat = (np.take(a.reshape(-1, shape[-1]), pick, axis=0) for a in (lon, lat))
        cond = problem.weather.sample(lon, lat, problem.departure)
        return None if cond.has_current else (cond.tws_kn, cond.twd_deg)

    return wind


def _tally_columns(tally: _Tally, cols: list[tuple[Any, ...]], failure: FailureModel | None) -> None:
    """Count a rank's arcs once, whichever side labels they were sailed from: an arc's flags are those of the
    first label it leaves from."""
    live, _, _, reason, counted, fired = cols[0]
    for other in cols[1:]:
        o_live, _, _, o_reason, o_counted, o_fired = other
        new = o_live & ~live
        reason = np.where(new, o_reason, reason).astype(np.uint8)
        if o_fired is not None or fired is not None:
            z = np.zeros(live.shape, np.uint32)
            fired = np.where(new, z if o_fired is None else o_fired, z if fired is None else fired)
        live, counted = live | o_live, counted | o_counted
    tally.add(live, counted, reason, fired, failure)


def label_min(total_h: FloatArray) -> tuple[FloatArray, npt.NDArray[np.intp], npt.NDArray[np.intp]]:
    """The DP's minimum over the arcs into each label of a rank.

    Parameters
    ----------
    total_h : Arrival [h] at each destination label over each arc from each source label, shape (source labels,
        labels, destinations, arcs); ``inf`` where an arc does not reach that label (forbidden, or sailed on the
        other side). Labels: one per node, or two (port, starboard: :mod:`pyroute_rel.boat.manoeuvre`).

    Returns
    -------
    The earliest arrival at each (destination, label) [h], shape (destinations, labels), the arc index and the
    source label it comes from (on ties the first arc, then the first source label; 0 where unreachable).
    """
    n_src, n_lab, n_dst, _ = total_h.shape
    rows = np.arange(n_dst)
    t_out = np.full((n_dst, n_lab), np.inf)
    j_out = np.zeros((n_dst, n_lab), dtype=np.intp)
    c_out = np.zeros((n_dst, n_lab), dtype=np.intp)
    for s in range(n_lab):
        for c in range(n_src):
            j = total_h[c, s].argmin(axis=1)
            t = total_h[c, s][rows, j]
            if c == 0:
                t_out[:, s], j_out[:, s] = t, j
                continue
            better = t < t_out[:, s]
            t_out[:, s] = np.where(better, t, t_out[:, s])
            j_out[:, s] = np.where(better, j, j_out[:, s])
            c_out[:, s] = np.where(better, c, c_out[:, s])
    return t_out, j_out, c_out


def _best_over_waits(
    arcs: _RankArcs, pricing: _Pricing, line: _FinishLine | None, from_side: int = -1
) -> tuple[FloatArray, FloatArray, npt.NDArray[np.uint8], BoolArray, npt.NDArray[np.uint32] | None]:
    """Waiting: each arc left after 0, 1, ... ``n_wait`` time steps; per arc and destination label (one, or port
    and starboard: the side the arc is sailed on depends on when it leaves) the earliest arrival [h] and the wait it
    takes [h], shape (labels, ...); the reason flags where every departure is forbidden, which arcs were costed and
    the criteria fired at the first departure."""
    problem = pricing.problem
    step = problem.time_step_h or 0.0
    shape = arcs.live.shape
    n_lab = 2 if problem.sides else 1
    if problem.n_wait == 0 and n_lab == 1 and line is None:  # one departure, one label: the loop below, once
        priced = pricing.price(arcs, arcs.t_src, first=True, from_side=from_side)
        total_1 = np.where(priced.total_h < np.inf, priced.total_h, np.inf)  # (NaN: not better than inf)
        return total_1[None], np.zeros((1, *shape)), priced.reason, priced.counted, priced.fired
    total = np.full((n_lab, *shape), np.inf)
    wait = np.zeros((n_lab, *shape))
    reason = np.zeros(shape, dtype=np.uint8)
    counted, fired = arcs.live, None
    for w in range(problem.n_wait + 1):
        t0 = arcs.t_src + w * step
        priced = pricing.price(arcs, t0, first=w == 0, from_side=from_side)
        if w == 0:
            fired = priced.fired
        if line is not None:
            line.observe(arcs, t0, priced, w * step, from_side, blocked=_lazy_arc_check(pricing, arcs.k, t0))
        for s in range(n_lab):
            cand = priced.total_h if priced.side is None else np.where(priced.side == s, priced.total_h, np.inf)
            better = cand < total[s]
            total[s] = np.where(better, cand, total[s])
            wait[s] = np.where(better, w * step, wait[s])
        # an arc counts as forbidden when it is forbidden at every departure time tried
        done = np.isfinite(total).any(axis=0)
        reason = priced.reason if w == 0 else np.where(done, 0, reason | priced.reason).astype(np.uint8)
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
    problem: RoutingProblem,
    k: int,
    geom: ArcGeometry,
    t0: FloatArray,
    live: BoolArray,
    bound_kn: float,
    lazy: bool,
    lazy_pieces: bool = False,
) -> tuple[_Costed, BoolArray]:
    """Costs of the arcs into rank k that can still win (see ``RoutingProblem.prune``), and which were evaluated.

    Each destination's four arcs of smallest lower bound (departure + length / ``bound_kn``) are costed first,
    obstacles and pieces included (lazily where ``lazy``, ``lazy_pieces``: the best of them is judged); then every
    arc whose bound does not exceed the best of them. A skipped arc arrives after its bound, which is later than an
    arc already costed: it cannot be the minimum, nor tie with it. Skipped arcs get an infinite time, NaN p_f and
    no reason flags."""
    shape = live.shape
    length_nm = np.broadcast_to(geom.seg_nm[..., 0] * geom.samples, shape)
    with np.errstate(invalid="ignore"):
        lower = np.where(live, problem.arrive(t0 + length_nm / bound_kn), np.inf)
    m = min(4, shape[1])
    first = np.zeros(shape, dtype=bool)
    rows = np.arange(shape[0])[:, None]
    first[rows, np.argpartition(lower, m - 1, axis=1)[:, :m] if m < shape[1] else slice(None)] = True
    first &= live
    costed = _costs_of(problem, geom, t0, first, lazy_pieces)
    total = np.where(first, problem.arrive(t0 + costed.costs.time_h), np.inf)
    if lazy or costed.pending:
        blocked = problem.blocked if lazy else None
        total, hit = _settle(costed, total, None, None, blocked, k, _block_times(problem, t0) if lazy else None)
        if hit is not None:
            total[hit] = np.inf
    best = total.min(axis=1)
    rest = live & ~first & (lower <= best[:, None])
    if rest.any():
        more = _costs_of(problem, geom, t0, rest, lazy_pieces)
        c, m_c = costed.costs, more.costs
        costs = ArcCosts(
            time_h=np.where(rest, m_c.time_h, c.time_h),
            p_f=np.where(rest, m_c.p_f, c.p_f),
            reason=np.where(rest, m_c.reason, c.reason).astype(np.uint8),
            fired_bits=None
            if c.fired_bits is None and m_c.fired_bits is None
            else np.where(rest, m_c.bits(), c.bits()),
        )
        costed = _Costed(costs, costed.pending + more.pending)
    return costed, first | rest


def _costs_of(
    problem: RoutingProblem, geom: ArcGeometry, t0: FloatArray, pick: BoolArray, lazy_pieces: bool = False
) -> _Costed:
    """Costs of the picked arcs of a block, laid out on the whole block (others: inf, NaN, no flags)."""
    shape = pick.shape
    where = np.flatnonzero(pick)

    def picked(a: FloatArray) -> FloatArray:  # rows of the picked arcs (a take: faster than a mask)
        if a.shape[:-1] == shape and a.flags.c_contiguous:
            return np.take(a.reshape(-1, a.shape[-1]), where, axis=0)
        return np.broadcast_to(a, shape + (a.shape[-1],))[pick]

    sub = ArcGeometry(
        picked(geom.lon_deg),
        picked(geom.lat_deg),
        picked(geom.course_deg),
        picked(geom.seg_nm),
        None if geom.a_xyz is None else picked(geom.a_xyz),
        None if geom.b_xyz is None else picked(geom.b_xyz),
    )
    part = _Costed.of(problem, sub, np.broadcast_to(t0, shape)[pick], lazy_pieces)
    c = part.costs
    time_h = np.full(shape, np.inf)
    p_f = np.full(shape, np.nan)
    reason = np.zeros(shape, dtype=np.uint8)
    time_h[pick], p_f[pick], reason[pick] = c.time_h, c.p_f, c.reason
    fired = None
    if c.fired_bits is not None:
        fired = np.zeros(shape, dtype=np.uint32)
        fired[pick] = c.fired_bits
    pending = [p.moved(where) for p in part.pending]
    return _Costed(ArcCosts(time_h=time_h, p_f=p_f, reason=reason, fired_bits=fired), pending)


def _block_times(problem: RoutingProblem, t0: FloatArray) -> npt.NDArray[np.datetime64] | None:
    """Departure times for obstacle masks that depend on time (None when the mask does not: :attr:`ArcMask.timed`,
    whatever the weather)."""
    if problem.blocked is None or not problem.blocked.timed:
        return None
    return hours_after(problem.departure, t0)


def _lazy_arc_check(pricing: _Pricing, k: int, t0: FloatArray) -> Callable[[int, int], bool] | None:
    """With obstacles tested lazily, whether arc (node, arc) into rank k, leaving at ``t0`` [h], meets one (tested
    now if it was not); None when the costs already hold every arc's obstacles."""
    blocked = pricing.problem.blocked
    if not pricing.lazy or blocked is None:
        return None
    times = _block_times(pricing.problem, t0)

    def check(j: int, c: int) -> bool:
        known = blocked.known(k)
        if not known[j, c]:
            select = np.zeros(known.shape, dtype=bool)
            select[j, c] = True
            blocked.learn(k, select)
        return bool(blocked.hits(k, times)[j, c])

    return check


def _lazy_obstacles(blocked: Any, k: int, total: FloatArray, times: npt.NDArray[np.datetime64] | None) -> BoolArray:
    """Obstacle hits among the arcs the DP would pick: for each destination its cheapest arcs are checked
    (4, then 16, 64, ...) until its best arc is known to be free, so the minimum is exactly that of the fully
    checked arcs while most arcs far from the optimum are never tested."""
    width = total.shape[1]
    rows = np.arange(total.shape[0])
    m = 4
    hit = blocked.hits(k, times)
    tot = np.where(hit, np.inf, total)
    while True:
        best = tot.argmin(axis=1)
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
    cause, hint = explain_cause(grid, problem, result)
    return cause + hint


def explain_cause(grid: Grid, problem: RoutingProblem, result: DPResult) -> tuple[str, str]:
    """:func:`explain_infeasible`'s line in two parts: the cause (where the front died, what forbade the arcs there,
    the conditions met) and the hint that follows it (" (raise --apf, ...)", or "")."""
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
        # the criteria fired in the states above apf met along each arc, where and when the craft sails it (the
        # costs' own record: the march's steps and the pieces judged in space and time)
        bits = np.broadcast_to(costs.bits(), failure_arcs.shape)[failure_arcs]
        counts = {
            c.describe(): int(np.count_nonzero(bits & np.uint32(1 << i)))
            for i, c in enumerate(problem.failure.criteria)
        }
        crit = ", ".join(f"{name} on {n} arcs" for name, n in counts.items() if n) or (
            f"on {int(failure_arcs.sum())} arcs, conditions met along them as sailed"
        )
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
            met = _polar_met(problem, grid, k, t0, live & (reason & REASONS[name] != 0)) if name == "polar" else ""
            parts.append(f"{label} on {n} arcs{met}")
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
    return f"no feasible route: the front died at {where} ({along:.0f} km along the route, {pos}); {detail}", hint


def _polar_met(problem: RoutingProblem, grid: Grid, k: int, t0: FloatArray, arcs: BoolArray) -> str:
    """The wind met on arcs the polar gives no speed on (at their middles, when they leave), and the polar's columns
    that have no speed at all: " (wind there TWS 30.1-33.8 kn, TWA 40-95 deg; the polar's TWS 28 kn column has no
    speed, and winds above 28 kn use it)"."""
    lon0, lat0, lon1, lat1, src, _ = grid.arcs(k)
    ends = [np.broadcast_to(a, src.shape)[arcs] for a in (lon0, lat0, lon1, lat1)]
    mid_lon, mid_lat = geodesy.intermediate_point(ends[0], ends[1], ends[2], ends[3], 0.5)
    cond = problem.weather_at(mid_lon, mid_lat, np.broadcast_to(t0, src.shape)[arcs])
    course = geodesy.initial_bearing_deg(mid_lon, mid_lat, ends[2], ends[3])
    twa = geodesy.angle_diff_deg(cond.twd_deg, course)
    tws = np.asarray(cond.tws_kn, dtype=float)
    polar = problem.polar
    empty = [  # a column of no wind has no speed by nature: not named
        float(w)
        for w, col in zip(polar.tws_kn, np.asarray(polar.speed_kn).T, strict=True)
        if w > 0 and not np.any(col > 0)
    ]
    text = (
        f" (wind there TWS {np.nanmin(tws):.1f}-{np.nanmax(tws):.1f} kn, "
        f"TWA {np.nanmin(twa):.0f}-{np.nanmax(twa):.0f} deg"
    )
    if empty:
        cols = ", ".join(f"{w:g}" for w in empty)
        text += f"; the polar {polar.name!r} has no speed in its TWS {cols} kn column{'s' if len(empty) > 1 else ''}"
        top = float(polar.tws_kn[-1])
        if empty[-1] == top and np.nanmax(tws) > top and problem.beyond == "clamp":
            text += f", and winds above {top:g} kn use that column"
    return text + ")"


def _coverage_short(grid: Grid, problem: RoutingProblem, k: int, t0: FloatArray, arcs: BoolArray) -> str | None:
    """Why arcs with missing weather lack it, when the reason is the weather's extent: they (or the time they take,
    at least length / the polar's top speed) lie outside what the source covers. None when it covers them (NaN
    inside the data, e.g. a land mask or a hole)."""
    from pyroute_rel.errors import WeatherCoverageError

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
    """Chain great-circle legs through the given points (see :func:`path_costs`); a tack or gybe between legs
    costs its penalty (:func:`leg_manoeuvres`)."""
    elapsed, costs, _ = leg_manoeuvres(problem, lon_deg, lat_deg, waits)
    return elapsed, costs


def leg_manoeuvres(
    problem: RoutingProblem,
    lon_deg: FloatArray,
    lat_deg: FloatArray,
    waits: npt.ArrayLike | None = None,
    *,
    elapsed_guess_h: npt.ArrayLike | None = None,
) -> tuple[FloatArray, ArcCosts, TrackManoeuvres]:
    """:func:`leg_costs` and the manoeuvres along the legs (:func:`pyroute_rel.boat.manoeuvre.track_manoeuvres`): the
    side of each leg from the wind at its first weather sample when it leaves, a manoeuvre where the side changes
    (from ``problem.initial_side`` for the first leg), whose penalty delays the leg's arrival as in the DP.

    In time-varying weather a leg leaves when the previous one arrives, so the legs are costed in order. With
    ``elapsed_guess_h`` (the time at each point but the last [h], e.g. the DP's arrival times), every leg is costed
    in one vectorised call from the guessed times; the legs' chain of arrivals is then recomputed from those costs,
    and the legs after the first point whose guess is not exactly its arrival are costed again from the corrected
    times (a few passes, then one leg at a time): the numbers are those of costing the legs one by one.
    """
    lon, lat = np.asarray(lon_deg, dtype=float), np.asarray(lat_deg, dtype=float)
    n_legs = len(lon) - 1
    wait = np.zeros(n_legs) if waits is None else np.asarray(waits, dtype=float)
    geom = arc_geometry(lon[:-1], lat[:-1], lon[1:], lat[1:], samples=problem.samples)
    penalties = problem.manoeuvres if problem.sides else None
    if bool(problem.weather.steady) and problem.time_step_h is None:
        elapsed = np.zeros(n_legs + 1)
        c = problem.costs(lon[:-1], lat[:-1], lon[1:], lat[1:], np.zeros(n_legs))
        times, p_f, reason = c.time_h, c.p_f, c.reason
        side, twa, tws = first_sample_wind(problem, geom, np.zeros(n_legs))
        pen = track_manoeuvres(side, twa, tws, penalties, initial_side=problem.initial_side).penalty_h
        if penalties is None:
            elapsed[1:] = np.cumsum(times)
        else:
            for i in range(n_legs):  # the DP's order of additions: (departure + sailing) + penalty
                elapsed[i + 1] = (elapsed[i] + times[i]) + pen[i]
        man = track_manoeuvres(side, twa, tws, penalties, initial_side=problem.initial_side)
        return elapsed, ArcCosts(time_h=times, p_f=p_f, reason=reason), man
    guess = None if elapsed_guess_h is None else np.asarray(elapsed_guess_h, dtype=float)
    if guess is not None and guess.shape != (n_legs,):
        raise ScenarioError(f"leg_manoeuvres: elapsed_guess_h must hold {n_legs} times [h] (got shape {guess.shape})")
    return _timed_legs(problem, lon, lat, geom, wait, guess, penalties)


#: Vectorised passes of :func:`leg_manoeuvres` from guessed departure times before it costs one leg at a time.
GUESS_PASSES = 3


def _timed_legs(
    problem: RoutingProblem,
    lon: FloatArray,
    lat: FloatArray,
    geom: ArcGeometry,
    wait: FloatArray,
    guess: FloatArray | None,
    penalties: ManoeuvrePenalties | None,
) -> tuple[FloatArray, ArcCosts, TrackManoeuvres]:
    """Legs in time-varying weather: legs ``< done`` are costed at their true departure; each pass costs the legs
    from ``done`` on (all of them from the guessed times, or only leg ``done``) and extends the chain of arrivals."""
    n_legs = len(lon) - 1
    elapsed = np.zeros(n_legs + 1)
    times, p_f = np.empty(n_legs), np.empty(n_legs)
    reason = np.empty(n_legs, dtype=np.uint8)
    marks: FloatArray | None = None  # when the craft reaches each sub-segment end (time-varying weather)
    side, twa, tws = np.zeros(n_legs, dtype=np.int8), np.zeros(n_legs), np.zeros(n_legs)
    if guess is not None:
        guess = guess.copy()
        guess[0] = 0.0  # the first leg leaves at the departure whatever the guess
    done, passes = 0, 0
    while done < n_legs:
        guessed = guess if passes < GUESS_PASSES else None  # this pass's departures, when guessed
        many = guessed is not None
        idx = np.arange(done, n_legs if many else done + 1)
        # guess[done] == elapsed[done]
        t0 = (guessed[idx] if guessed is not None else np.full(1, elapsed[done])) + wait[idx]
        passes += many
        c = problem.costs(lon[idx], lat[idx], lon[idx + 1], lat[idx + 1], t0)
        times[idx], p_f[idx], reason[idx] = c.time_h, c.p_f, c.reason
        if c.marks_h is not None:
            if marks is None:
                marks = np.full((n_legs, c.marks_h.shape[-1]), np.nan)
            marks[idx] = c.marks_h
        one = ArcGeometry(geom.lon_deg[idx], geom.lat_deg[idx], geom.course_deg[idx], geom.seg_nm)
        side[idx], twa[idx], tws[idx] = first_sample_wind(problem, one, t0)
        pen = track_manoeuvres(side, twa, tws, penalties, initial_side=problem.initial_side).penalty_h
        stop = n_legs
        for i in idx:  # the legs' chain: exact up to the first leg costed from a wrong time
            t = elapsed[i] + wait[i]
            elapsed[i + 1] = (
                problem.arrive(t + times[i]) if penalties is None else problem.arrive((t + times[i]) + pen[i])
            )
            if stop == n_legs and i + 1 < n_legs and (guessed is None or elapsed[i + 1] != guessed[i + 1]):
                stop = int(i) + 1
        done = stop
        if many:
            guess = elapsed[:-1].copy()  # the next pass's departures: exact up to ``done``
    man = track_manoeuvres(side, twa, tws, penalties, initial_side=problem.initial_side)
    return elapsed, ArcCosts(time_h=times, p_f=p_f, reason=reason, marks_h=marks), man


def first_sample_wind(
    problem: RoutingProblem, geom: ArcGeometry, t0: FloatArray
) -> tuple[npt.NDArray[np.int8], FloatArray, FloatArray]:
    """Side, true wind angle [deg] and wind speed [kn] of each arc at its first weather sample, leaving at ``t0``."""
    lon, lat, course = geom.lon_deg[..., 0], geom.lat_deg[..., 0], geom.course_deg[..., 0]
    cond = problem.weather_at(lon, lat, np.broadcast_to(t0, lon.shape))
    side, twa = wind_side(cond.twd_deg, course)
    return side, twa, np.asarray(cond.tws_kn, dtype=float)
