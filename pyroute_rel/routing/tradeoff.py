"""Time against reliability: the exact Pareto fronts of a scenario, and what each failure criterion costs.

Two fronts answer "how many hours does each step of safety cost?":

**Bottleneck front** (voyage time, largest leg ``p_f``). The ``apf`` threshold forbids an arc when its ``p_f``
exceeds it, and an arc's ``p_f`` is a value of the failure model's compiled table, so only the table's distinct
values matter: the minimum-time route at every distinct threshold, with the dominated ones dropped, is the exact
front (the epsilon-constraint method on a criterion with finitely many values). It is found with one forward DP per
front point plus one: each run's route has a largest ``p_f`` ``m``, and the next threshold is the largest table
value below ``m`` (thresholds between give the same route). The runs share the grid, so its arc geometry and
obstacle masks are computed once.

**Voyage front** (voyage time, voyage failure probability). The voyage's failure probability is ``1 - exp(-H)``
with ``H`` the hazard accumulated along the track (:mod:`pyroute_rel.reliability.exposure`): a sum over arcs, so the
front is that of a bi-objective shortest-path problem. It is found by label setting in rank order (Martins 1984): every
node keeps the labels (arrival time, accumulated hazard) no other label at that node dominates; a label is extended
along every arc out of its node, and the labels arriving at a node are reduced to the non-dominated ones. An arc's
hazard is :func:`~pyroute_rel.reliability.exposure.arc_exposure`'s, the figure a routed voyage reports, so a front
point's voyage failure probability is that of its route (tested). Arcs with ``p_f > apf`` stay forbidden. With steady
weather only the arcs that need it are resolved on 1 km sub-arcs: an arc that meets no ``p_f > 0`` anywhere adds 0, and
one inside a single patch's conditions with every criterion in one bin adds its ``p_f`` over its whole time (the same to
rounding; ``_steady_hazards``), and each rank's labels are extended and reduced in one compiled pass that merges the
sorted runs of labels each arc brings to a node (:mod:`pyroute_rel._kernels.front`). The front's routes share most of
their legs: with steady weather their figures and tracks are computed at once, each distinct leg costed once by the
functions :func:`~pyroute_rel.routing.route.build_route` calls (the same figures to the last bit: tested), and a point's
:class:`~pyroute_rel.routing.route.Route` is built only when :attr:`FrontPoint.route` is read.

**Courses through waypoints** (:func:`course_bottleneck_front`, :func:`course_voyage_front`; one grid and problem per
leg, as :meth:`Scenario.leg_grids <pyroute_rel.scenario.Scenario.leg_grids>` plans them). The bottleneck front routes
the whole course at each threshold (:func:`course_route`: each leg departing when the previous one arrives, the
fastest course within the threshold under FIFO weather). The voyage front carries the non-dominated labels at each
mark into the next leg as its start labels (arrival time, accumulated hazard): the label setting runs on the legs'
graphs joined at the marks, so it is exact there whenever it is on one grid (tested against every path of a two-leg
course). :func:`refined_front` routes each bottleneck point again with corridor refinement (``tradeoff
--refine``).

When is it exact?
    With steady weather, always: arc times and hazards do not depend on the departure, and a dominated label's
    extensions are dominated by the same extensions of the label that dominates it (the front equals an enumeration
    of every path: tested). With time-varying weather each label is extended at its own arrival time, and dropping
    a dominated label is exact when leaving an arc later neither arrives earlier (FIFO in time) nor accumulates
    less hazard on it (FIFO in hazard: the arc's hazard does not decrease with the departure time). Without these
    the search returns true trade-offs between paths it kept, but a path whose later departure met less hazard
    may be missing (waiting is not modelled; the time-expanded DP's ``time_step_h`` is refused here).

The number of labels at a node can grow with the number of paths; :func:`voyage_front` refuses loudly
(:class:`~pyroute_rel.errors.LabelLimitError`) when a node holds more than ``max_labels`` (default
:data:`MAX_LABELS`, 1024; commercial routers cap their labels per state at 512) and reports the labels per node kept.

**Failure-mode sensitivity** (:func:`sensitivity`). For each criterion of the model: the hours it costs (the
route at the user's ``apf`` minus the route with that criterion removed, :meth:`FailureModel.without
<pyroute_rel.reliability.failure.FailureModel.without>`, two separate DP runs), the hours the route spends where the
criterion fires, and the legs it bends (where the two routes leave different nodes): the route "bounded" by that
criterion.

References
----------
Martins, E. Q. V. (1984). On a multicriteria shortest path problem. European Journal of Operational Research 16,
236-245.
Hamacher, H. W., Ruzika, S. and Tjandra, S. A. (2006). Algorithms for time-dependent bicriteria shortest path
problems. Discrete Optimization 3, 238-254 (FIFO conditions for label setting over time).
Skoglund, L., Kuttenkeuler, J. and Rosen, A. (2012). A comparative study of deterministic and ensemble weather
forecasts for weather routing. Journal of Marine Science and Technology (Pareto label-setting ship routes).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import Any, NamedTuple

import numpy as np
import numpy.typing as npt

from pyroute_rel import geodesy
from pyroute_rel.errors import (
    LabelLimitError,
    NoFeasibleRouteError,
    ScenarioError,
    check_callable,
    check_flag,
    check_instance,
)
from pyroute_rel.progress import progress_bar
from pyroute_rel.reliability.crossings import needs_pieces
from pyroute_rel.reliability.exposure import arc_exposure, hazard, leg_exposure
from pyroute_rel.routing.cost import ArcGeometry, geometry_costs
from pyroute_rel.routing.grid import Grid
from pyroute_rel.routing.relax import route_course
from pyroute_rel.routing.route import Route, build_route, join_routes, route_on_grid
from pyroute_rel.routing.solve import DPResult, RoutingProblem, grid_geometry
from pyroute_rel.times import iso_utc

__all__ = [
    "MAX_LABELS",
    "FrontPoint",
    "Front",
    "Sensitivity",
    "pareto_indices",
    "bottleneck_front",
    "voyage_front",
    "sensitivity",
    "course_route",
    "course_bottleneck_front",
    "course_voyage_front",
    "course_sensitivity",
    "refined_front",
    "bounding_criterion",
]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.intp]

#: Default cap on the non-dominated labels one node may hold in :func:`voyage_front` (``--max-labels``). Commercial
#: routers cap at 512 per state; the control course (``examples/microtransat_control.toml``) on its default grid needs
#: 711 at one node (105 on average), so 512 would refuse the documented example: 1024 lets it run with room, and
#: still bounds a rank's labels (nodes x 1024) to a few hundred thousand on default grids.
MAX_LABELS = 1024


@dataclass(frozen=True, eq=False)
class FrontPoint:
    """One route of a front: its figures and track, and the :class:`~pyroute_rel.routing.route.Route` built when asked
    for.

    Attributes
    ----------
    voyage_time_h : Voyage time [h].
    max_failure_probability : Largest leg ``p_f`` of the route [-].
    voyage_failure_probability : ``1 - exp(-hazard)`` [-].
    hazard : Hazard accumulated along the route [-] (:mod:`pyroute_rel.reliability.exposure`).
    distance_nm : Sailed distance [nm].
    lon_deg, lat_deg : Track points [deg].
    elapsed_h : Time at each track point [h after ``departure``].
    leg_p_f : Each leg's ``p_f`` [-] (one fewer than points).
    departure : Departure (UTC).
    make_route : Builds the route (called once, by :attr:`route`).
    apf : The threshold it was routed at (bottleneck front), else None.

    The figures are those of :attr:`route` (its ``voyage_time_h``, ``max_failure_probability``,
    ``voyage_failure_probability``, ``distance_nm``, track and leg ``p_f``, bit for bit: tested), computed for all
    the front's routes at once where the weather is steady; the route itself (legs' conditions, manoeuvres, DP
    counts) is built only when :attr:`route` is read.
    """

    voyage_time_h: float
    max_failure_probability: float
    voyage_failure_probability: float
    hazard: float
    distance_nm: float
    lon_deg: FloatArray
    lat_deg: FloatArray
    elapsed_h: FloatArray
    leg_p_f: FloatArray
    departure: np.datetime64
    make_route: Callable[[], Route] = field(repr=False)
    apf: float | None = None

    @cached_property
    def route(self) -> Route:
        """The route (built on first use)."""
        return self.make_route()

    def track(self) -> list[dict[str, Any]]:
        """The track as ``pyroute-rel route --json`` gives it: lon, lat, time and the ``p_f`` of the leg into each
        point (0 at the start)."""
        start = np.asarray(self.departure).astype("datetime64[s]")
        times = start + np.round(self.elapsed_h * 3600.0).astype("timedelta64[s]")  # as Route.time
        p_point = np.concatenate([[0.0], self.leg_p_f])
        return [
            {"lon": float(lo), "lat": float(la), "time": iso_utc(t), "p_f": float(p)}
            for lo, la, t, p in zip(self.lon_deg, self.lat_deg, times, p_point, strict=True)
        ]

    def as_dict(self) -> dict[str, Any]:
        """The JSON of a front point (``pyroute-rel tradeoff --json``); its track as ``pyroute-rel route --json``'s."""
        return {
            "voyage_time_h": self.voyage_time_h,
            "max_failure_probability": self.max_failure_probability,
            "voyage_failure_probability": self.voyage_failure_probability,
            "hazard": self.hazard,
            "distance_nm": self.distance_nm,
            "apf": self.apf,
            "track": self.track(),
        }


@dataclass(frozen=True)
class Front:
    """A Pareto front, sorted by voyage time (the second objective then decreases strictly).

    Attributes
    ----------
    kind : ``"bottleneck"`` (time against the largest leg ``p_f``) or ``"voyage"`` (time against the voyage's
        failure probability).
    points : The front's routes, fastest first.
    runs : Forward DP runs (bottleneck) or label-setting passes (voyage) it took.
    labels_mean, labels_max : Voyage front: non-dominated labels per reached node, mean and largest (None for the
        bottleneck front).
    """

    kind: str
    points: tuple[FrontPoint, ...]
    runs: int
    labels_mean: float | None = None
    labels_max: int | None = None


def pareto_indices(first: npt.ArrayLike, second: npt.ArrayLike) -> IntArray:
    """Indices of the points no other point dominates (both objectives minimised), sorted by ``first``.

    Of points with equal objectives the first one given is kept. The kept points' ``second`` decreases strictly.

    >>> pareto_indices([3.0, 1.0, 2.0, 2.0, 4.0], [0.0, 5.0, 1.0, 3.0, 0.0]).tolist()
    [1, 2, 0]
    """
    a, b = np.asarray(first, dtype=float), np.asarray(second, dtype=float)
    order = np.lexsort((np.arange(a.size), b, a))
    best = np.minimum.accumulate(b[order])
    keep = np.ones(a.size, dtype=bool)
    keep[1:] = b[order][1:] < best[:-1]
    return np.asarray(order[keep & np.isfinite(a[order])], dtype=np.intp)


def _point(route: Route, apf: float | None = None) -> FrontPoint:
    """A front point from a route (its hazard from its legs' failure probabilities)."""
    with np.errstate(divide="ignore"):
        h = float(-np.sum(np.log1p(-route.legs.p_fail_leg)))
    return FrontPoint(
        voyage_time_h=route.voyage_time_h,
        max_failure_probability=route.max_failure_probability,
        voyage_failure_probability=route.voyage_failure_probability + 0.0,  # never -0.0
        hazard=h + 0.0,
        distance_nm=route.distance_nm,
        lon_deg=route.lon_deg,
        lat_deg=route.lat_deg,
        elapsed_h=route.elapsed_h,
        leg_p_f=np.asarray(route.legs.p_f, dtype=float),
        departure=route.departure,
        make_route=lambda: route,
        apf=apf,
    )


def failure_levels(problem: RoutingProblem) -> FloatArray:
    """The thresholds that matter: the failure table's distinct values up to the problem's ``apf`` (``[apf]`` without
    a model)."""
    if problem.failure is None:
        return np.array([float(problem.apf)])
    p = np.unique(problem.failure.p_flat)
    return np.asarray(p[np.isfinite(p) & (p <= problem.apf)], dtype=float)


def bottleneck_front(grid: Grid, problem: RoutingProblem, *, progress: bool = False) -> Front:
    """The exact front of (voyage time, largest leg ``p_f``) over thresholds up to ``problem.apf`` (module notes).

    Raises
    ------
    NoFeasibleRouteError
        When no route exists at ``problem.apf`` itself.
    """
    return course_bottleneck_front([(grid, problem)], progress=progress)


def course_bottleneck_front(legs: Sequence[tuple[Grid, RoutingProblem]], *, progress: bool = False) -> Front:
    """:func:`bottleneck_front` of a course through waypoints: one :func:`course_route` per front point plus one.

    The course's route at a threshold is its legs' routes at that threshold, each departing when the previous one
    arrives: with FIFO weather the fastest course among those whose every arc has ``p_f`` at most the threshold, so
    the epsilon-constraint argument of the module notes holds for the course. The thresholds are those of the first
    leg's problem (``apf`` and failure table; the legs share them).
    """
    legs = _check_legs(legs, progress)
    problem = legs[0][1]
    levels = failure_levels(problem)
    points: list[FrontPoint] = []
    apf = float(problem.apf)
    bar = progress_bar(len(levels), enabled=progress, desc="thresholds", unit="route")
    try:
        while True:
            try:
                route = _course_route(legs, apf=apf)
            except NoFeasibleRouteError:
                if not points:
                    raise
                break
            bar.update(1)
            points.append(_point(route, apf))
            below = levels[levels < route.max_failure_probability]
            if below.size == 0:
                break
            apf = float(below[-1])
    finally:
        bar.close()
    keep = pareto_indices([p.voyage_time_h for p in points], [p.max_failure_probability for p in points])
    return Front(kind="bottleneck", points=tuple(points[i] for i in keep), runs=len(points))


def refined_front(front: Front, route_at: Callable[[float], Route], *, progress: bool = False) -> Front:
    """A bottleneck front with each route refined: ``route_at(m)`` for each point's largest leg ``p_f`` ``m``, the
    dominated results dropped.

    ``route_at`` routes the course at a threshold with corridor refinement, e.g. ``lambda apf:
    scenario.with_options(apf=apf, refine=2).route(grids=grids)`` (``pyroute-rel tradeoff --refine``), so each point
    is the route ``pyroute-rel route --apf m --refine N`` gives. What is exact: each refined route is the corridor
    DP's minimum time at its threshold, no longer than the grid route it refines (refinement keeps the grid route
    when no corridor improves on it) and with no leg ``p_f`` above ``m``, so every point of ``front`` is dominated by
    or equal to a point of the result (tested). What is not: the front of the continuous problem (each corridor is
    a grid around one route, and a threshold whose grid route is dominated is not refined).

    Raises
    ------
    ScenarioError
        For a front that is not a bottleneck front (the voyage front is not refined).
    """
    check_instance(front, Front, "front", ScenarioError, expected="a Front (bottleneck_front)")
    if front.kind != "bottleneck":
        raise ScenarioError("only the bottleneck front is refined (the voyage front is exact on its grid)")
    check_callable(route_at, "route_at", ScenarioError)
    points = []
    bar = progress_bar(len(front.points), enabled=check_flag(progress, "progress", ScenarioError), desc="refine")
    try:
        for p in front.points:
            points.append(_point(route_at(p.max_failure_probability), p.max_failure_probability))
            bar.update(1)
    finally:
        bar.close()
    keep = pareto_indices([p.voyage_time_h for p in points], [p.max_failure_probability for p in points])
    return Front(kind="bottleneck", points=tuple(points[i] for i in keep), runs=front.runs + len(points))


def course_route(legs: Sequence[tuple[Grid, RoutingProblem]]) -> Route:
    """The course's minimum-time route on its legs' grids: each leg routed by the forward DP
    (:func:`~pyroute_rel.routing.route.route_on_grid`) departing when the previous one arrives (on the side of the wind
    it ended on), the legs joined (:func:`~pyroute_rel.routing.route.join_routes`): :meth:`Scenario.route
    <pyroute_rel.scenario.Scenario.route>` without corridor refinement, on grids given (and their caches reused).
    """
    return _course_route(_check_legs(legs, False))


def _course_route(legs: list[tuple[Grid, RoutingProblem]], **changes: Any) -> Route:
    """:func:`course_route` with ``changes`` made to every leg's problem (e.g. ``apf``, ``failure``)."""
    return route_course(legs, **changes)


@dataclass(frozen=True)
class _Labels:
    """The non-dominated labels of one rank, sorted by node then time: node, arrival [h], hazard [-] and the label
    of the previous rank each extends (the start point for rank 0)."""

    node: IntArray
    t: FloatArray
    h: FloatArray
    parent: IntArray


@dataclass(frozen=True)
class _Candidates:
    """Labels extended along arcs into a rank: destination node, arrival [h], hazard [-], the label extended."""

    node: IntArray
    t: FloatArray
    h: FloatArray
    parent: IntArray


class _Ends(NamedTuple):
    """The end points of a rank's arcs [deg], one value per arc (flat)."""

    lon0: FloatArray
    lat0: FloatArray
    lon1: FloatArray
    lat1: FloatArray

    def take(self, index: IntArray) -> _Ends:
        """The end points of the arcs ``index``."""
        return _Ends(*(e[index] for e in self))


def voyage_front(grid: Grid, problem: RoutingProblem, *, max_labels: int = MAX_LABELS, progress: bool = False) -> Front:
    """The front of (voyage time, voyage failure probability) on the grid by label setting (module notes).

    Parameters
    ----------
    grid : The rank digraph (no finish line).
    problem : The routing problem (continuous time: no ``time_step_h``; no tack or gybe penalties); arcs with
        ``p_f > apf`` are forbidden.
    max_labels : Most non-dominated labels a node may hold (>= 1).
    progress : Show a progress bar.

    Raises
    ------
    LabelLimitError
        When a node would hold more than ``max_labels`` labels (names the rank, the count and ``--max-labels``).
    NoFeasibleRouteError
        When no route reaches the finish.
    ScenarioError
        For a finish line, a time lattice or manoeuvre penalties, which the label setting does not model.
    """
    return course_voyage_front([(grid, problem)], max_labels=max_labels, progress=progress)


def course_voyage_front(
    legs: Sequence[tuple[Grid, RoutingProblem]], *, max_labels: int = MAX_LABELS, progress: bool = False
) -> Front:
    """:func:`voyage_front` of a course through waypoints: its legs' grids and problems, sailed one after another.

    The labels of a leg's finish (the next mark) are the start labels of the next leg (arrival time, hazard), so
    the label setting runs on the concatenated graph and the front is as exact as on one grid (module notes). Every
    leg's problem counts time from the voyage's departure (each ``problem.departure`` is the course's, as
    :meth:`Scenario.problem <pyroute_rel.scenario.Scenario.problem>` gives it); the marks after the start must be
    points (one start point per later leg). A front point's route is the legs' routes joined
    (:func:`~pyroute_rel.routing.route.join_routes`), each leg departing when the previous one arrives, as
    :meth:`Scenario.route <pyroute_rel.scenario.Scenario.route>` sails a course. With time-varying weather a point's
    figures other than its hazard are its route's, whose later legs depart at the arrival rounded to the second (as
    :meth:`Scenario.route <pyroute_rel.scenario.Scenario.route>`'s do); the labels carry the unrounded time.
    """
    legs = _check_legs(legs, progress)
    for grid, problem in legs:
        _check_voyage_problem(grid, problem, max_labels)
    for i, (grid, _) in enumerate(legs[1:], start=1):
        if grid.start_points[0].size != 1:
            raise ScenarioError(f"legs[{i}]: a leg after the first must start from one point (a waypoint)")
    n_start = legs[0][0].start_points[0].size
    labels = _Labels(node=np.arange(n_start), t=np.zeros(n_start), h=np.zeros(n_start), parent=np.full(n_start, -1))
    histories: list[list[_Labels]] = []
    counts = [0, 0, 0]  # labels summed over reached nodes, reached nodes, most labels at a node
    bar = progress_bar(sum(g.n_ranks + 1 for g, _ in legs), enabled=progress, desc="ranks", unit="rank")
    try:
        for i, (grid, problem) in enumerate(legs):
            where = f" of leg {i + 1} of {len(legs)}" if len(legs) > 1 else ""
            history = _leg_labels(grid, problem, labels, max_labels, counts, where, bar)
            histories.append(history)
            labels = replace(
                history[-1],
                node=np.zeros(history[-1].node.size, dtype=np.intp),
                parent=np.arange(history[-1].node.size),
            )
    finally:
        bar.close()
    return Front(
        kind="voyage",
        points=tuple(_front_points(legs, histories)),
        runs=1,
        labels_mean=counts[0] / max(counts[1], 1),
        labels_max=counts[2],
    )


def _leg_labels(
    grid: Grid,
    problem: RoutingProblem,
    labels: _Labels,
    max_labels: int,
    counts: list[int],
    where: str,
    bar: Any,
) -> list[_Labels]:
    """The label setting over one grid from its start labels: every rank's non-dominated labels, the finish's last
    (``counts`` updated: labels summed over reached nodes, reached nodes, most labels at a node)."""
    history: list[_Labels] = []
    for k in range(grid.n_ranks + 1):
        cand = _extend(grid, problem, k, labels)
        labels = cand if isinstance(cand, _Labels) else _reduce(cand)
        per_node = np.bincount(labels.node) if labels.node.size else np.zeros(0, dtype=np.intp)
        per_node = per_node[per_node > 0]
        if per_node.size and per_node.max() > max_labels:
            at = "the finish" if k == grid.n_ranks else f"rank {k + 1} of {grid.n_ranks}"
            held = counts[0] + int(per_node.sum())
            mean = held / (counts[1] + per_node.size)
            raise LabelLimitError(
                f"the voyage front needs {int(per_node.max())} non-dominated labels at a node of {at}{where}, more "
                f"than the cap of {max_labels} per node (it held {held} labels by then, {mean:.0f} a node on "
                "average; time and memory grow with them): raise --max-labels (max_labels) step by step, or use fewer "
                "nodes (--n-ranks, --half-width-km, --aspect), or the bottleneck front (--front bottleneck)"
            )
        counts[0] += int(per_node.sum())
        counts[1] += per_node.size
        counts[2] = max(counts[2], int(per_node.max()) if per_node.size else 0)
        history.append(labels)
        bar.update(1)
        if labels.node.size == 0:  # no path: the DP says where its front died and why
            raise NoFeasibleRouteError(route_on_grid_reason(grid, problem) or f"no path reaches rank {k}{where}")
    return history


@dataclass(frozen=True)
class _Paths:
    """The front's paths on one leg of the course: start point, node on each rank, arrival there [h] and at the
    finish [h] (one row per front point)."""

    start: IntArray
    nodes: IntArray
    times: FloatArray
    finish_h: FloatArray


def _trace(histories: list[list[_Labels]]) -> list[_Paths]:
    """Every finish label's path, leg by leg, followed back along the labels' parents in one pass per rank."""
    idx = np.arange(histories[-1][-1].node.size)
    out: list[_Paths] = []
    for leg in range(len(histories) - 1, -1, -1):
        history = histories[leg]
        n = len(history) - 1
        nodes = np.empty((idx.size, n), dtype=np.intp)
        times = np.empty((idx.size, n))
        finish_h = history[n].t[idx]
        idx = history[n].parent[idx]
        for k in range(n - 1, -1, -1):
            nodes[:, k], times[:, k] = history[k].node[idx], history[k].t[idx]
            idx = history[k].parent[idx]
        start = idx if leg == 0 else np.zeros(idx.size, dtype=np.intp)  # later legs: from their one start point
        out.append(_Paths(start=np.asarray(start, dtype=np.intp), nodes=nodes, times=times, finish_h=finish_h))
    return out[::-1]


def _front_points(legs: list[tuple[Grid, RoutingProblem]], histories: list[list[_Labels]]) -> list[FrontPoint]:
    """The front's points, fastest first: with steady weather their figures for all routes at once
    (:func:`_steady_figures`), the routes built when asked for; otherwise each route built and its figures read."""
    paths = _trace(histories)
    h = histories[-1][-1].h
    makers = [_route_maker(legs, paths, i) for i in range(h.size)]
    if not all(p.weather.steady and not p.sides for _, p in legs):
        return [replace(_point(make()), hazard=float(h[i]) + 0.0) for i, make in enumerate(makers)]
    fig = _steady_figures(legs, paths)
    departure = np.datetime64(legs[0][1].departure).astype("datetime64[s]")
    with np.errstate(divide="ignore"):  # a leg with p_fail_leg = 1: certain failure
        log_survival = np.log1p(-fig["p_fail_leg"])
    return [
        FrontPoint(
            voyage_time_h=float(fig["elapsed_h"][i, -1]),
            max_failure_probability=float(np.max(fig["p_f"][i])),
            voyage_failure_probability=float(0.0 - np.expm1(np.sum(log_survival[i]))) + 0.0,
            hazard=float(h[i]) + 0.0,
            distance_nm=float(fig["distance_nm"][i].sum()),
            lon_deg=fig["lon_deg"][i],
            lat_deg=fig["lat_deg"][i],
            elapsed_h=fig["elapsed_h"][i],
            leg_p_f=fig["p_f"][i],
            departure=departure,
            make_route=make,
        )
        for i, make in enumerate(makers)
    ]


def _steady_figures(legs: list[tuple[Grid, RoutingProblem]], paths: list[_Paths]) -> dict[str, FloatArray]:
    """Steady weather: the track and legs of every front route (one row each) as :func:`_route_maker`'s route has
    them, each distinct leg costed once (:meth:`RoutingProblem.costs`,
    :func:`~pyroute_rel.reliability.exposure.arc_exposure`: the functions :func:`~pyroute_rel.routing.route.build_route`
    calls, on the same end points; with steady weather they do not depend on the time). Joined legs of a course are
    timed as :func:`~pyroute_rel.routing.route.join_routes`
    does."""
    parts = [_steady_leg(grid, problem, p) for (grid, problem), p in zip(legs, paths, strict=True)]
    elapsed = [parts[0]["elapsed_h"]]
    offset = np.zeros(paths[0].start.size)
    for before, part in zip(parts[:-1], parts[1:], strict=True):
        offset = offset + before["elapsed_h"][:, -1]  # join_routes: each leg from the previous one's arrival
        elapsed.append(offset[:, None] + part["elapsed_h"][:, 1:])
    out = {k: np.concatenate([p[k] for p in parts], axis=1) for k in ("p_f", "p_fail_leg", "distance_nm")}
    for k in ("lon_deg", "lat_deg"):
        out[k] = np.concatenate([parts[0][k], *(p[k][:, 1:] for p in parts[1:])], axis=1)
    out["elapsed_h"] = np.concatenate(elapsed, axis=1)
    return out


def _steady_leg(grid: Grid, problem: RoutingProblem, paths: _Paths) -> dict[str, FloatArray]:
    """One leg's track points, elapsed time, and per leg ``p_f``, failure probability and distance of each path."""
    s_lon, s_lat = grid.start_points
    lon = np.concatenate([s_lon, grid.lon_deg.ravel(), [grid.finish[0]]])
    lat = np.concatenate([s_lat, grid.lat_deg.ravel(), [grid.finish[1]]])
    n_pts, n_ranks = lon.size, paths.nodes.shape[1]
    point = np.empty((paths.start.size, n_ranks + 2), dtype=np.int64)
    point[:, 0] = paths.start
    point[:, 1:-1] = s_lon.size + np.arange(n_ranks) * grid.n_nodes + paths.nodes
    point[:, -1] = n_pts - 1
    code = point[:, :-1] * n_pts + point[:, 1:]
    arc, inverse = np.unique(code, return_inverse=True)
    inverse = inverse.reshape(code.shape)
    a, b = arc // n_pts, arc % n_pts
    costs = problem.costs(lon[a], lat[a], lon[b], lat[b], np.zeros(arc.size))
    time_h, p_f = np.asarray(costs.time_h, dtype=float), np.asarray(costs.p_f, dtype=float)
    exposure = arc_exposure(problem, lon[a], lat[a], lon[b], lat[b], np.zeros(arc.size), time_h, p_f)
    elapsed = np.zeros((code.shape[0], n_ranks + 2))
    elapsed[:, 1:] = np.cumsum(time_h[inverse], axis=1)
    return {
        "lon_deg": lon[point],
        "lat_deg": lat[point],
        "elapsed_h": elapsed,
        "p_f": p_f[inverse],
        "p_fail_leg": exposure.p_fail_leg[inverse],
        "distance_nm": geodesy.distance_nm(lon[a], lat[a], lon[b], lat[b])[inverse],
    }


def _route_maker(legs: list[tuple[Grid, RoutingProblem]], paths: list[_Paths], i: int) -> Callable[[], Route]:
    """What builds front point ``i``'s route: each leg's path as a DP result, its legs recomputed
    (:func:`~pyroute_rel.routing.route.build_route`), the legs joined, each departing when the previous one arrives."""

    def make() -> Route:
        routes: list[Route] = []
        for (grid, problem), p in zip(legs, paths, strict=True):
            n_ranks = grid.n_ranks
            arrival = np.full((n_ranks, grid.n_nodes), np.inf)
            back = np.full((n_ranks, grid.n_nodes), -1, dtype=np.intp)
            nodes = p.nodes[i]
            arrival[np.arange(n_ranks), nodes] = p.times[i]
            back[np.arange(n_ranks), nodes] = np.concatenate([[p.start[i]], nodes[:-1]])
            result = DPResult(
                arrival_h=arrival,
                back=back,
                finish_h=float(p.finish_h[i]),
                finish_back=int(nodes[-1]),
                arcs_evaluated=0,
                arcs_forbidden=0,
                forbidden_by_reason={},
                dead_rank=None,
            )
            leg_problem = problem if not routes else replace(problem, departure=routes[-1].arrival)
            routes.append(build_route(grid, leg_problem, result))
        return routes[0] if len(routes) == 1 else join_routes(routes)

    return make


def route_on_grid_reason(grid: Grid, problem: RoutingProblem) -> str:
    """Why no route exists (the DP's explanation); an empty string if the DP finds one."""
    try:
        route_on_grid(grid, problem)
    except NoFeasibleRouteError as exc:
        return str(exc)
    return ""


def _check_grid_problem(grid: Any, problem: Any, progress: Any) -> bool:
    """The arguments every front takes, checked at the public boundary: ScenarioError naming the argument."""
    check_instance(grid, Grid, "grid", ScenarioError, expected="a Grid (pyroute_rel.make_grid)")
    check_instance(problem, RoutingProblem, "problem", ScenarioError, expected="a RoutingProblem")
    return check_flag(progress, "progress", ScenarioError)


def _check_legs(legs: Any, progress: Any) -> list[tuple[Grid, RoutingProblem]]:
    """A course's legs, checked at the public boundary: a non-empty sequence of (Grid, RoutingProblem) pairs."""
    if not isinstance(legs, Sequence) or not legs or not all(isinstance(x, tuple) and len(x) == 2 for x in legs):
        raise ScenarioError("legs must be a non-empty sequence of (grid, problem) pairs, one per leg of the course")
    for grid, problem in legs:
        _check_grid_problem(grid, problem, progress)
    return list(legs)


def _check_voyage_problem(grid: Grid, problem: RoutingProblem, max_labels: int) -> None:
    if isinstance(max_labels, bool) or not isinstance(max_labels, int) or max_labels < 1:
        raise ScenarioError(f"max_labels (--max-labels) must be a whole number >= 1 (got {max_labels!r})")
    if problem.time_step_h is not None:
        raise ScenarioError(
            "the voyage front is computed in continuous time: remove [route].time_step_h / --time-step "
            "(waiting is not modelled by the label setting)"
        )
    if problem.sides:
        raise ScenarioError(
            "the voyage front does not model tack and gybe penalties (the side of the wind is not in its labels): "
            "remove [boat].tack_penalty_s / gybe_penalty_s, or use the bottleneck front (--front bottleneck)"
        )
    if grid.finish_line is not None:
        raise ScenarioError(
            "the voyage front needs a finish point: a finish line is not supported (--front bottleneck)"
        )
    if problem.blocked is not None and problem.blocked.timed:
        raise ScenarioError("the voyage front does not model exclusion zones with time windows (--front bottleneck)")


def _extend(grid: Grid, problem: RoutingProblem, k: int, labels: _Labels) -> _Candidates | _Labels:
    """Every label of the previous rank extended along every sailable arc into rank ``k``: with steady weather each
    arc is costed once and the non-dominated labels are kept as they are made
    (:func:`~pyroute_rel._kernels.front.extend_steady`); otherwise each (label, arc) pair is costed at the label's
    arrival time and the candidates are returned (:func:`_reduce` keeps the non-dominated ones)."""
    src, valid = grid.pattern(k)
    width = src.shape[1]
    n_src = grid.start_points[0].size if k == 0 else grid.n_nodes
    count = np.bincount(labels.node, minlength=n_src)
    offset = np.concatenate([[0], np.cumsum(count)[:-1]])
    live = valid & (count[src] > 0)
    if problem.blocked is not None:
        live &= ~problem.blocked(k, None)  # zones with time windows are refused before
    geom = grid_geometry(grid, k, problem.samples)
    ends = _Ends(*(np.broadcast_to(a, src.shape).ravel() for a in grid.arcs(k)[:4]))
    steady = bool(problem.weather.steady)
    if steady:  # cost each live arc once (p_f judged on every piece: the hazard screen's), keep the sailable ones
        costs = problem.geometry_costs(geom, np.zeros(src.shape)) if problem.failure is None else _exact(problem, geom)
        time_all = np.where(live, costs.time_h, np.inf).ravel()
        arc = np.flatnonzero(np.isfinite(time_all))
        time_arc = time_all[arc]
        hz = _steady_hazards(problem, geom, src.shape, arc, ends.take(arc), time_arc, costs)
        from pyroute_rel._kernels.front import extend_steady  # numba: imported by the voyage front only

        node, t, h, parent = extend_steady(
            labels.t,
            labels.h,
            np.concatenate([offset, [labels.node.size]]),
            np.searchsorted(arc // width, np.arange(src.shape[0] + 1)),
            src.ravel()[arc],
            time_arc,
            hz,
        )
        return _Labels(node=node, t=t, h=h, parent=parent)
    arc = np.flatnonzero(live.ravel())
    n_per = count[src.ravel()[arc]]
    pair = np.repeat(np.arange(arc.size), n_per)  # (label, arc) pairs: the arc of each
    parent = offset[src.ravel()[arc]][pair] + _ramp(n_per)
    c_arc, t0 = arc[pair], labels.t[parent]
    sub = ArcGeometry(
        *(
            np.broadcast_to(a, src.shape + (a.shape[-1],)).reshape(-1, a.shape[-1])[c_arc]
            for a in (geom.lon_deg, geom.lat_deg, geom.course_deg, geom.seg_nm)
        )
    )
    costs = problem.geometry_costs(sub, t0)
    time_h = np.asarray(costs.time_h, dtype=float)
    ok = np.isfinite(time_h)
    p_pair = np.broadcast_to(costs.p_f, c_arc.shape)[ok]
    marks = None if costs.marks_h is None else costs.marks_h[ok]  # the times the arcs were sailed at
    hz = arc_exposure(problem, *ends.take(c_arc[ok]), t0[ok], time_h[ok], p_pair, marks_h=marks).hazard
    return _Candidates(
        node=c_arc[ok] // width,
        t=t0[ok] + time_h[ok],
        h=labels.h[parent[ok]] + hz,
        parent=parent[ok],
    )


def _exact(problem: RoutingProblem, geom: ArcGeometry, *, exact_p_f: bool = True) -> Any:
    """Steady weather: the costs of a rank's arcs leaving at the departure, each arc's ``p_f`` judged on every piece
    it crosses (``exact_p_f``; the DP's costs judge them only where they can forbid the arc: the same times and
    forbidden arcs, :func:`~pyroute_rel.routing.cost.geometry_costs`)."""
    return geometry_costs(
        geom,
        np.zeros(geom.shape),
        departure=problem.departure,
        weather=problem.weather,
        polar=problem.polar,
        failure=problem.failure,
        apf=float(problem.apf),
        beyond=problem.beyond,
        wave_loss=problem.wave_loss,
        exact_p_f=exact_p_f,
    )


def _columns(geom: ArcGeometry) -> tuple[FloatArray, ...]:
    """The geometry's sample points, courses and sub-segment lengths (without the arcs' end vectors)."""
    return (geom.lon_deg, geom.lat_deg, geom.course_deg, geom.seg_nm)


def _steady_hazards(
    problem: RoutingProblem,
    geom: ArcGeometry,
    shape: tuple[int, ...],
    arc: IntArray,
    ends: _Ends,
    time_h: FloatArray,
    costs: Any,
) -> FloatArray:
    """Steady weather: the hazard of each sailable arc ``arc`` (flat indices into a rank's arcs of shape ``shape``;
    ``ends`` their end points [deg], ``time_h`` their times [h], ``costs`` the rank's costs from :func:`_exact`), as
    :func:`~pyroute_rel.reliability.exposure.arc_exposure` gives it, resolving on 1 km sub-arcs only the arcs that need
    it.

    An arc whose largest ``p_f`` (every piece it crosses judged, :mod:`pyroute_rel.reliability.crossings`: a bound that
    may count a state the arc does not meet, never miss one) is 0 adds no hazard: every sub-arc's is 0. Among the
    others, an arc that lies in one patch's conditions with every criterion in one bin all along (patches only; not
    :func:`~pyroute_rel.reliability.crossings.needs_pieces`) meets the same ``p_f`` at every sub-arc's midpoint, so its
    hazard is that ``p_f`` over its whole time: the sum of its sub-arcs' hazards but for rounding (their times add up to
    the arc's). The rest are resolved on sub-arcs, given the ``p_f`` the router costs them with (the DP's, as a routed
    voyage's legs have it: used where a sub-arc's weather is missing)."""
    hz = np.zeros(arc.size)
    model = problem.failure
    if model is None:
        return hz
    p_max = np.broadcast_to(costs.p_f, shape).ravel()[arc]
    some = p_max > 0.0  # the others: no hazard
    bounds = problem.weather.boundaries
    near = None
    if bounds is not None and not bounds.continuous:  # patches: no missing weather, conditions constant per piece
        time_all = np.broadcast_to(costs.time_h, shape)
        near = needs_pieces(
            geom.lon_deg,
            geom.lat_deg,
            geom.course_deg,
            geom.seg_nm,
            np.zeros(shape),
            time_all,
            weather=problem.weather,
            failure=model,
            departure=problem.departure,
        )
    whole = np.zeros(arc.size, dtype=bool) if near is None else some & ~np.broadcast_to(near, shape).ravel()[arc]
    hz[whole] = hazard(p_max[whole], time_h[whole], model.exposure_h)
    rest = np.flatnonzero(some & ~whole)
    if rest.size:
        p_f = p_max[rest]  # the DP's p_f: the same where it can forbid an arc, else its samples' largest
        if float(problem.apf) >= float(np.max(model.p_flat)):
            cols = [
                np.broadcast_to(a, shape + (a.shape[-1],)).reshape(-1, a.shape[-1])[arc[rest]] for a in _columns(geom)
            ]
            p_f = np.asarray(_exact(problem, ArcGeometry(*cols), exact_p_f=False).p_f, dtype=float)
        hz[rest] = arc_exposure(problem, *ends.take(rest), np.zeros(rest.size), time_h[rest], p_f).hazard
    return hz


def _ramp(n_per: IntArray) -> IntArray:
    """0, 1, ..., n - 1 for each n of ``n_per``, concatenated."""
    total = int(n_per.sum())
    starts = np.repeat(np.cumsum(n_per) - n_per, n_per)
    return np.asarray(np.arange(total) - starts, dtype=np.intp)


def _reduce(c: _Candidates) -> _Labels:
    """The non-dominated candidates at each node (of equal ones the first), sorted by node then time: those whose
    hazard is below every hazard before them at their node, sorted by (node, time, hazard, position)
    (:func:`~pyroute_rel._kernels.front.nondominated`, one compiled pass)."""
    from pyroute_rel._kernels.front import nondominated  # numba: imported by the voyage front only

    pick = nondominated(c.node, c.t, c.h, int(c.node.max()) + 1 if c.node.size else 0)
    return _Labels(node=c.node[pick], t=c.t[pick], h=c.h[pick], parent=c.parent[pick])


@dataclass(frozen=True)
class Sensitivity:
    """What one failure criterion costs the route at the user's ``apf``.

    Attributes
    ----------
    criterion : The criterion's description (e.g. ``"WH: hs_m >= 4 m"``).
    node : Its evidence node (e.g. ``"WH"``).
    hours_cost : Voyage time with the criterion minus without it [h] (two separate routes).
    exposure_h : Hours the route spends where the criterion fires [h].
    bound_h : Hours of the route's legs that the criterion bends (they leave or reach another node than the route
        without it) [h].
    exposed_legs, bound_legs : Which legs of the route are exposed to it (it fires somewhere along them) and which
        it bends.
    route_without : The route with the criterion removed.
    """

    criterion: str
    node: str
    hours_cost: float
    exposure_h: float
    bound_h: float
    exposed_legs: npt.NDArray[np.bool_]
    bound_legs: npt.NDArray[np.bool_]
    route_without: Route

    def as_dict(self, route: Route) -> dict[str, Any]:
        """The JSON of a row of the sensitivity table: the stretches of ``route`` (the route at the user's apf)
        exposed to and bent by the criterion, each as its first and last point and hours."""
        return {
            "criterion": self.criterion,
            "node": self.node,
            "hours_cost": self.hours_cost,
            "exposure_h": self.exposure_h,
            "bound_h": self.bound_h,
            "exposed_at": _stretches(route, self.exposed_legs),
            "bound_at": _stretches(route, self.bound_legs),
        }


def _stretches(route: Route, legs: npt.NDArray[np.bool_]) -> list[dict[str, Any]]:
    """Runs of consecutive selected legs: their first and last point [deg], start [h] and duration [h]."""
    out = []
    edges = np.diff(np.concatenate([[0], legs.astype(np.int8), [0]]))
    for a, b in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True):
        out.append(
            {
                "from": [float(route.lon_deg[a]), float(route.lat_deg[a])],
                "to": [float(route.lon_deg[b]), float(route.lat_deg[b])],
                "start_h": float(route.elapsed_h[a]),
                "hours": float(route.elapsed_h[b] - route.elapsed_h[a]),
            }
        )
    return out


def sensitivity(grid: Grid, problem: RoutingProblem, route: Route | None = None) -> list[Sensitivity]:
    """For each criterion of the failure model, what it costs the route at ``problem.apf`` (module notes).

    ``route`` is that route when already computed (e.g. the bottleneck front's first point); an empty list without
    a failure model.
    """
    return course_sensitivity([(grid, problem)], route)


def course_sensitivity(legs: Sequence[tuple[Grid, RoutingProblem]], route: Route | None = None) -> list[Sensitivity]:
    """:func:`sensitivity` of a course through waypoints: the routes with and without each criterion are
    :func:`course_route`'s (``route``: the course's route at the first leg's ``apf``, when already computed)."""
    legs = _check_legs(legs, False)
    problem = legs[0][1]
    if route is not None:
        check_instance(route, Route, "route", ScenarioError, expected="a Route (of this grid and problem) or None")
    model = problem.failure
    if model is None:
        return []
    if route is None:
        route = _course_route(legs)
    exposure = leg_exposure(
        problem,
        route.lon_deg,
        route.lat_deg,
        route.elapsed_h[:-1] + route.legs.wait_h,
        route.legs.time_h,
        route.legs.p_f,
        marks_h=route.leg_marks_h,
    )
    out = []
    for c in model.criteria:
        other = _course_route(legs, failure=model.without(c.node))
        bound = _bound_legs(route, other)
        exposed = exposure.criterion_h[c.describe()] > 0.0
        out.append(
            Sensitivity(
                criterion=c.describe(),
                node=c.node,
                hours_cost=route.voyage_time_h - other.voyage_time_h,
                exposure_h=float(exposure.criterion_h[c.describe()].sum()),
                bound_h=float(route.legs.time_h[bound].sum()),
                exposed_legs=exposed,
                bound_legs=bound,
                route_without=other,
            )
        )
    return out


def _bound_legs(route: Route, other: Route) -> npt.NDArray[np.bool_]:
    """The legs of ``route`` into or out of a node where ``other`` (the same course routed otherwise) is elsewhere,
    leg of the course by leg (a mark between two legs is not a node)."""
    out = []
    for r, o in zip(route.course_legs or (route,), other.course_legs or (other,), strict=True):
        moved = r.nodes != o.nodes
        out.append(np.concatenate([moved, [False]]) | np.concatenate([[False], moved]))
    return np.concatenate(out)


def bounding_criterion(rows: list[Sensitivity], n_legs: int) -> IntArray:
    """Per leg of the route, the index in ``rows`` of the criterion that bends it (the one costing most hours when
    several do), -1 where none does."""
    which = np.full(n_legs, -1, dtype=np.intp)
    cost = np.full(n_legs, -math.inf)
    for i, row in enumerate(rows):
        better = row.bound_legs & (row.hours_cost > cost)
        which[better], cost[better] = i, row.hours_cost
    return which
