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
with ``H`` the hazard accumulated along the track (:mod:`pyroute_rel.exposure`): a sum over arcs, so the front is
that of a bi-objective shortest-path problem. It is found by label setting in rank order (Martins 1984): every node
keeps the labels (arrival time, accumulated hazard) no other label at that node dominates; a label is extended along
every arc out of its node, and the labels arriving at a node are reduced to the non-dominated ones. An arc's hazard
is :func:`~pyroute_rel.exposure.arc_exposure`'s, the figure a routed voyage reports, so a front point's
voyage failure probability is that of its route (tested). Arcs with ``p_f > apf`` stay forbidden. With steady
weather only the arcs that need it are resolved on 1 km sub-arcs: an arc that meets no ``p_f > 0`` anywhere adds 0,
and one inside a single patch's conditions with every criterion in one bin adds its ``p_f`` over its whole time (the
same to rounding; ``_steady_hazards``), and each rank's labels are extended and reduced in one compiled pass
(:mod:`pyroute_rel.front_compiled`).

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
<pyroute_rel.failure.FailureModel.without>`, two separate DP runs), the hours the route spends where the criterion
fires, and the legs it bends (where the two routes leave different nodes): the route "bounded" by that criterion.

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
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import numpy.typing as npt

from .cost import ArcGeometry, geometry_costs
from .crossings import needs_pieces
from .errors import LabelLimitError, NoFeasibleRouteError, ScenarioError, check_flag, check_instance
from .exposure import arc_exposure, hazard, leg_exposure
from .grid import Grid
from .progress import progress_bar
from .route import Route, build_route, route_on_grid
from .solve import DPResult, RoutingProblem, grid_geometry

__all__ = [
    "MAX_LABELS",
    "FrontPoint",
    "Front",
    "Sensitivity",
    "pareto_indices",
    "bottleneck_front",
    "voyage_front",
    "sensitivity",
    "bounding_criterion",
]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.intp]

#: Default cap on the non-dominated labels one node may hold in :func:`voyage_front` (``--max-labels``). Commercial
#: routers cap at 512 per state; the control course (``examples/microtransat_control.toml``) on its default grid needs
#: 711 at one node (105 on average), so 512 would refuse the documented example: 1024 lets it run with room, and
#: still bounds a rank's labels (nodes x 1024) to a few hundred thousand on default grids.
MAX_LABELS = 1024


@dataclass(frozen=True)
class FrontPoint:
    """One route of a front.

    Attributes
    ----------
    voyage_time_h : Voyage time [h].
    max_failure_probability : Largest leg ``p_f`` of the route [-].
    voyage_failure_probability : ``1 - exp(-hazard)`` [-].
    hazard : Hazard accumulated along the route [-] (:mod:`pyroute_rel.exposure`).
    distance_nm : Sailed distance [nm].
    route : The route.
    apf : The threshold it was routed at (bottleneck front), else None.
    """

    voyage_time_h: float
    max_failure_probability: float
    voyage_failure_probability: float
    hazard: float
    distance_nm: float
    route: Route
    apf: float | None = None

    def as_dict(self) -> dict[str, Any]:
        """The JSON of a front point (``pyroute-rel tradeoff --json``); its track as ``pyroute-rel route --json``'s."""
        return {
            "voyage_time_h": self.voyage_time_h,
            "max_failure_probability": self.max_failure_probability,
            "voyage_failure_probability": self.voyage_failure_probability,
            "hazard": self.hazard,
            "distance_nm": self.distance_nm,
            "apf": self.apf,
            "track": self.route.summary()["track"],  # as `pyroute-rel route --json`: lon, lat, time, p_f per point
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
        route=route,
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
    progress = _check_grid_problem(grid, problem, progress)
    levels = failure_levels(problem)
    points: list[FrontPoint] = []
    apf = float(problem.apf)
    bar = progress_bar(len(levels), enabled=progress, desc="thresholds", unit="route")
    try:
        while True:
            try:
                route = route_on_grid(grid, replace(problem, apf=apf))
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


def voyage_front(grid: Grid, problem: RoutingProblem, *, max_labels: int = MAX_LABELS, progress: bool = False) -> Front:
    """The front of (voyage time, voyage failure probability) on the grid by label setting (module notes).

    Parameters
    ----------
    grid : The rank digraph (no finish line).
    problem : The routing problem (continuous time: no ``time_step_h``); arcs with ``p_f > apf`` are forbidden.
    max_labels : Most non-dominated labels a node may hold (>= 1).
    progress : Show a progress bar.

    Raises
    ------
    LabelLimitError
        When a node would hold more than ``max_labels`` labels (names the rank, the count and ``--max-labels``).
    NoFeasibleRouteError
        When no route reaches the finish.
    ScenarioError
        For a finish line or a time lattice, which the label setting does not model.
    """
    progress = _check_grid_problem(grid, problem, progress)
    _check_voyage_problem(grid, problem, max_labels)
    labels = _Labels(
        node=np.arange(grid.start_points[0].size),
        t=np.zeros(grid.start_points[0].size),
        h=np.zeros(grid.start_points[0].size),
        parent=np.full(grid.start_points[0].size, -1),
    )
    history: list[_Labels] = []
    counts_sum, counts_n, counts_max = 0, 0, 0
    bar = progress_bar(grid.n_ranks + 1, enabled=progress, desc="ranks", unit="rank")
    try:
        for k in range(grid.n_ranks + 1):
            cand = _extend(grid, problem, k, labels)
            labels = cand if isinstance(cand, _Labels) else _reduce(cand)
            per_node = np.bincount(labels.node) if labels.node.size else np.zeros(0, dtype=np.intp)
            per_node = per_node[per_node > 0]
            if per_node.size and per_node.max() > max_labels:
                where = "the finish" if k == grid.n_ranks else f"rank {k + 1} of {grid.n_ranks}"
                raise LabelLimitError(
                    f"the voyage front needs {int(per_node.max())} non-dominated labels at a node of {where}, more "
                    f"than the cap of {max_labels} per node: raise --max-labels (max_labels), or use fewer nodes "
                    "(--n-ranks, --half-width-km, --aspect), or the bottleneck front (--front bottleneck)"
                )
            counts_sum, counts_n = counts_sum + int(per_node.sum()), counts_n + per_node.size
            counts_max = max(counts_max, int(per_node.max()) if per_node.size else 0)
            history.append(labels)
            bar.update(1)
            if labels.node.size == 0:  # no path: the DP says where its front died and why
                raise NoFeasibleRouteError(route_on_grid_reason(grid, problem) or f"no path reaches rank {k}")
    finally:
        bar.close()
    points = []
    for i in range(labels.node.size):  # the finish's labels: the front, fastest first
        route = _label_route(grid, problem, history, i)
        points.append(replace(_point(route), hazard=float(labels.h[i]) + 0.0))
    return Front(
        kind="voyage",
        points=tuple(points),
        runs=1,
        labels_mean=counts_sum / max(counts_n, 1),
        labels_max=counts_max,
    )


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


def _check_voyage_problem(grid: Grid, problem: RoutingProblem, max_labels: int) -> None:
    if isinstance(max_labels, bool) or not isinstance(max_labels, int) or max_labels < 1:
        raise ScenarioError(f"max_labels (--max-labels) must be a whole number >= 1 (got {max_labels!r})")
    if problem.time_step_h is not None:
        raise ScenarioError(
            "the voyage front is computed in continuous time: remove [route].time_step_h / --time-step "
            "(waiting is not modelled by the label setting)"
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
    (:func:`~pyroute_rel.front_compiled.extend_steady`); otherwise each (label, arc) pair is costed at the label's
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
    ends = [np.broadcast_to(a, src.shape).ravel() for a in grid.arcs(k)[:4]]
    steady = bool(problem.weather.steady)
    if steady:  # cost each live arc once, then keep the sailable ones
        costs = problem.geometry_costs(geom, np.zeros(src.shape))
        time_all = np.where(live, costs.time_h, np.inf).ravel()
        arc = np.flatnonzero(np.isfinite(time_all))
        p_arc = np.broadcast_to(costs.p_f, src.shape).ravel()[arc]
        time_arc = time_all[arc]
        hz = _steady_hazards(problem, geom, src.shape, arc, [e[arc] for e in ends], time_arc, p_arc)
        from .front_compiled import extend_steady  # numba: imported by the voyage front only

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
    hz = arc_exposure(problem, *(e[c_arc[ok]] for e in ends), t0[ok], time_h[ok], p_pair).hazard
    return _Candidates(
        node=c_arc[ok] // width,
        t=t0[ok] + time_h[ok],
        h=labels.h[parent[ok]] + hz,
        parent=parent[ok],
    )


def _steady_hazards(
    problem: RoutingProblem,
    geom: ArcGeometry,
    shape: tuple[int, ...],
    arc: IntArray,
    ends: list[FloatArray],
    time_h: FloatArray,
    p_f: FloatArray,
) -> FloatArray:
    """Steady weather: the hazard of each sailable arc ``arc`` (flat indices into a rank's arcs of shape ``shape``;
    ``ends`` their end points [deg], ``time_h`` their times [h], ``p_f`` their costed ``p_f``), as
    :func:`~pyroute_rel.exposure.arc_exposure` gives it, resolving on 1 km sub-arcs only the arcs that need it.

    An arc whose largest ``p_f`` (every piece it crosses judged, :mod:`pyroute_rel.crossings`: a bound that may count
    a state the arc does not meet, never miss one) is 0 adds no hazard: every sub-arc's is 0. Among the others, an arc
    that lies in one patch's conditions with every criterion in one bin all along (patches only; not
    :func:`~pyroute_rel.crossings.needs_pieces`) meets the same ``p_f`` at every sub-arc's midpoint, so its hazard is
    that ``p_f`` over its whole time: the sum of its sub-arcs' hazards but for rounding (their times add up to the
    arc's). The rest are resolved on sub-arcs."""
    hz = np.zeros(arc.size)
    model = problem.failure
    if model is None:
        return hz
    t0 = np.zeros(shape)
    costs = geometry_costs(
        geom,
        t0,
        departure=problem.departure,
        weather=problem.weather,
        polar=problem.polar,
        failure=model,
        apf=float(problem.apf),
        beyond=problem.beyond,
        wave_loss=problem.wave_loss,
        exact_p_f=True,
    )
    p_max = np.broadcast_to(costs.p_f, shape).ravel()[arc]
    some = p_max > 0.0  # the others: no hazard
    bounds = getattr(problem.weather, "boundaries", None)
    near = None
    if bounds is not None and not bounds.continuous:  # patches: no missing weather, conditions constant per piece
        time_all = np.broadcast_to(costs.time_h, shape)
        near = needs_pieces(
            geom.lon_deg,
            geom.lat_deg,
            geom.course_deg,
            geom.seg_nm,
            t0,
            time_all,
            weather=problem.weather,
            failure=model,
            departure=problem.departure,
        )
    whole = np.zeros(arc.size, dtype=bool) if near is None else some & ~np.broadcast_to(near, shape).ravel()[arc]
    hz[whole] = hazard(p_max[whole], time_h[whole], model.exposure_h)
    rest = np.flatnonzero(some & ~whole)
    if rest.size:
        hz[rest] = arc_exposure(problem, *(e[rest] for e in ends), np.zeros(rest.size), time_h[rest], p_f[rest]).hazard
    return hz


def _ramp(n_per: IntArray) -> IntArray:
    """0, 1, ..., n - 1 for each n of ``n_per``, concatenated."""
    total = int(n_per.sum())
    starts = np.repeat(np.cumsum(n_per) - n_per, n_per)
    return np.asarray(np.arange(total) - starts, dtype=np.intp)


def _reduce(c: _Candidates) -> _Labels:
    """The non-dominated candidates at each node (of equal ones the first), sorted by node then time: those whose
    hazard is below every hazard before them at their node, sorted by (node, time, hazard, position)
    (:func:`~pyroute_rel.front_compiled.nondominated`, one compiled pass)."""
    from .front_compiled import nondominated  # numba: imported by the voyage front only

    pick = nondominated(c.node, c.t, c.h, int(c.node.max()) + 1 if c.node.size else 0)
    return _Labels(node=c.node[pick], t=c.t[pick], h=c.h[pick], parent=c.parent[pick])


def _label_route(grid: Grid, problem: RoutingProblem, history: list[_Labels], i: int) -> Route:
    """The route of label ``i`` at the finish: its nodes traced back rank by rank, legs recomputed
    (:func:`~pyroute_rel.route.build_route`)."""
    n_ranks = grid.n_ranks
    nodes = np.empty(n_ranks, dtype=np.intp)
    times = np.empty(n_ranks)
    label = int(history[n_ranks].parent[i])
    for k in range(n_ranks - 1, -1, -1):
        nodes[k], times[k] = history[k].node[label], history[k].t[label]
        label = int(history[k].parent[label])
    start = label
    arrival = np.full((n_ranks, grid.n_nodes), np.inf)
    back = np.full((n_ranks, grid.n_nodes), -1, dtype=np.intp)
    arrival[np.arange(n_ranks), nodes] = times
    back[np.arange(n_ranks), nodes] = np.concatenate([[start], nodes[:-1]])
    result = DPResult(
        arrival_h=arrival,
        back=back,
        finish_h=float(history[n_ranks].t[i]),
        finish_back=int(nodes[-1]),
        arcs_evaluated=0,
        arcs_forbidden=0,
        forbidden_by_reason={},
        dead_rank=None,
    )
    return build_route(grid, problem, result)


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
    _check_grid_problem(grid, problem, False)
    if route is not None:
        check_instance(route, Route, "route", ScenarioError, expected="a Route (of this grid and problem) or None")
    model = problem.failure
    if model is None:
        return []
    if route is None:
        route = route_on_grid(grid, problem)
    exposure = leg_exposure(
        problem,
        route.lon_deg,
        route.lat_deg,
        route.elapsed_h[:-1] + route.legs.wait_h,
        route.legs.time_h,
        route.legs.p_f,
    )
    out = []
    for c in model.criteria:
        other = route_on_grid(grid, replace(problem, failure=model.without(c.node)))
        moved = route.nodes != other.nodes
        bound = np.concatenate([moved, [False]]) | np.concatenate([[False], moved])  # legs into/out of a moved node
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


def bounding_criterion(rows: list[Sensitivity], n_legs: int) -> IntArray:
    """Per leg of the route, the index in ``rows`` of the criterion that bends it (the one costing most hours when
    several do), -1 where none does."""
    which = np.full(n_legs, -1, dtype=np.intp)
    cost = np.full(n_legs, -math.inf)
    for i, row in enumerate(rows):
        better = row.bound_legs & (row.hours_cost > cost)
        which[better], cost[better] = i, row.hours_cost
    return which
