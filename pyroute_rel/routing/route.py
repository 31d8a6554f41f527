"""The Route result: track, per-leg conditions and failure probabilities, and its exports.

Failure probabilities
---------------------
Each leg's ``p_f`` is the failure model's probability for the worst conditions met along that leg: what the
``apf`` constraint bounds (``p_f > apf`` forbids an arc), which does not depend on the grid. It is the probability of
failure over the model's reference exposure ``exposure_h`` [h] in those conditions. The voyage's failure probability
adds up exposure (:mod:`pyroute_rel.reliability.exposure`): each leg contributes the hazard of the time it spends in
each condition, ``-ln(1 - p_f) * dt / exposure_h`` summed along it (``p_fail_leg = 1 - exp(-hazard)``), and the voyage
``1 - exp(-sum of hazards)``. Unlike a product over legs ``1 - prod(1 - p_f_leg)`` (each leg one trial, so the figure
grows with the number of legs), it converges as the grid is refined.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field, fields, replace
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from pyroute_rel import geodesy
from pyroute_rel.boat.manoeuvre import TrackManoeuvres
from pyroute_rel.boat.march import time_along
from pyroute_rel.errors import NoFeasibleRouteError, ScenarioError, check_flag, check_instance
from pyroute_rel.reliability.exposure import LegExposure, combined_failure_probability, leg_exposure
from pyroute_rel.reliability.failure import arc_quantities
from pyroute_rel.routing.cost import REASONS, ArcCosts
from pyroute_rel.routing.solve import (
    DPResult,
    RoutingProblem,
    explain_cause,
    forward_dp,
    grid_geometry,
    leg_manoeuvres,
)
from pyroute_rel.times import hours_after, iso_utc

if TYPE_CHECKING:
    from pyroute_rel.obstacles.zones import Zone
    from pyroute_rel.reliability.failure import FailureModel
    from pyroute_rel.routing.grid import Grid
    from pyroute_rel.weather import WeatherSource

__all__ = [
    "Route",
    "Legs",
    "GridTrack",
    "ForbiddenArcs",
    "build_route",
    "join_routes",
    "route_on_grid",
    "forbidden_on_grid",
    "LEG_FIELDS",
    "track_legs",
]

FloatArray = npt.NDArray[np.float64]
#: An array of text (numpy's fixed-width unicode strings).
StrArray = npt.NDArray[np.str_]

LEG_FIELDS = (
    "wait_h",
    "distance_nm",
    "time_h",
    "sog_kn",
    "course_deg",
    "tws_kn",
    "twd_deg",
    "twa_deg",
    "hs_m",
    "wave_dir_deg",
    "awd_deg",
    "p_f",
    "p_fail_leg",
)


@dataclass(frozen=True, eq=False)
class Legs(Mapping[str, FloatArray]):
    """Per-leg conditions of a route: one value per leg, a leg joining two consecutive track points.

    Each attribute is a float array with one fewer value than the track has points. The conditions are those at
    the leg's midpoint and mid-time (where the data have a hole at the midpoint that the leg's cost samples
    straddle, at the sample nearest it). A ``Legs`` is also a read-only mapping, ``legs["time_h"]``, in the order
    below.

    Attributes
    ----------
    distance_nm : Great-circle length of the leg [nm].
    time_h : Sailing time [h] (waits excluded).
    sog_kn : Mean speed over ground while sailing [kn].
    course_deg : Course over ground, clockwise from true north [deg].
    tws_kn : True wind speed [kn].
    twd_deg : True wind direction, where it blows from [deg].
    twa_deg : True wind angle, in [0, 180] [deg].
    hs_m : Significant wave height [m].
    wave_dir_deg : Mean wave direction, where the waves come from [deg].
    awd_deg : Apparent wave direction (0 = head seas) [deg].
    p_f : The leg's largest failure probability (0 without a failure model): the probability of failure over the
        model's ``exposure_h`` in the worst conditions along the leg, what ``apf`` bounds.
    wait_h : Wait at the leg's start before sailing it [h].
    p_fail_leg : Probability of failure over the leg's sailing time, from the time it spends in each condition
        (:mod:`pyroute_rel.reliability.exposure`) [-].
    """

    distance_nm: FloatArray
    time_h: FloatArray
    sog_kn: FloatArray
    course_deg: FloatArray
    tws_kn: FloatArray
    twd_deg: FloatArray
    twa_deg: FloatArray
    hs_m: FloatArray
    wave_dir_deg: FloatArray
    awd_deg: FloatArray
    p_f: FloatArray
    wait_h: FloatArray
    p_fail_leg: FloatArray

    def __post_init__(self) -> None:
        n = None
        for name in self:
            values = np.asarray(vars(self)[name], dtype=float)
            if values.ndim != 1 or (n is not None and values.size != n):
                raise ValueError(f"Legs.{name} must be a 1-D array of {n} values, one per leg (got {values.shape})")
            n = values.size
            object.__setattr__(self, name, values)
        if np.any((self.p_fail_leg < 0.0) | (self.p_fail_leg > 1.0)):
            raise ValueError(f"Legs.p_fail_leg must be probabilities in [0, 1] (got {self.p_fail_leg.tolist()})")

    def __getitem__(self, key: str) -> FloatArray:
        if key not in LEG_FIELDS:
            raise KeyError(key)
        return vars(self)[key]  # type: ignore[no-any-return]

    def __iter__(self) -> Iterator[str]:
        return iter(_LEG_ORDER)

    def __len__(self) -> int:
        return len(_LEG_ORDER)

    __eq__ = object.__eq__  # identity, as for Route (a mapping's == would compare arrays)
    __hash__ = object.__hash__

    @property
    def n_legs(self) -> int:
        """Number of legs."""
        return int(self.time_h.size)


#: The order of :class:`Legs`' fields (``LEG_FIELDS`` is the CSV's, with the wait first).
_LEG_ORDER = tuple(f.name for f in fields(Legs))


@dataclass(frozen=True)
class GridTrack:
    """The track on the grid routed on, before refinement (:mod:`pyroute_rel.refine`): points [deg] and voyage
    time [h]."""

    lon_deg: FloatArray
    lat_deg: FloatArray
    voyage_time_h: float


@dataclass(frozen=True)
class ForbiddenArcs:
    """Arcs of a route's grid that the failure model, the weather, the polar, currents or obstacles forbade.

    Every attribute is an array with one value per arc (see :meth:`Route.forbidden_arcs`).

    Attributes
    ----------
    leg : Which leg of a course through waypoints the arc belongs to (0 without waypoints).
    rank : Rank the arc goes into (0 = from the start, ``grid.n_ranks`` = into the finish).
    src, dst : Node index the arc leaves on the previous rank (a start point at rank 0) and reaches on ``rank``
        (0 for the finish).
    from_lon_deg, from_lat_deg, to_lon_deg, to_lat_deg : The arc's end points [deg].
    departure_h : When the arc is sailed [h after the route's departure]: the DP's arrival time at its source.
    departure : The same time (UTC), to the second.
    p_f : The arc's largest failure probability at that time (NaN where the weather is missing).
    reason : Why it is forbidden: names of :data:`~pyroute_rel.routing.cost.REASONS` joined by ``+`` (e.g.
        ``"failure"``, ``"failure+obstacle"``).
    criteria : For arcs the failure model forbids, the criteria that fired along them (their descriptions joined
        by ``"; "``, e.g. ``"WH: hs_m >= 4 m"``); ``""`` otherwise.
    """

    leg: npt.NDArray[np.intp]
    rank: npt.NDArray[np.intp]
    src: npt.NDArray[np.intp]
    dst: npt.NDArray[np.intp]
    from_lon_deg: FloatArray
    from_lat_deg: FloatArray
    to_lon_deg: FloatArray
    to_lat_deg: FloatArray
    departure_h: FloatArray
    departure: npt.NDArray[np.datetime64]
    p_f: FloatArray
    reason: StrArray
    criteria: StrArray

    def __len__(self) -> int:
        return int(self.rank.size)

    def as_dict(self) -> dict[str, np.ndarray]:
        """The columns by name (e.g. for ``pandas.DataFrame(route.forbidden_arcs().as_dict())``)."""
        return {f.name: vars(self)[f.name] for f in fields(self)}


@dataclass(frozen=True, eq=False)
class Route:
    """A routed voyage: what :meth:`pyroute_rel.scenario.Scenario.route` returns.

    Attributes
    ----------
    lon_deg, lat_deg : Track points [deg]: start, one node per rank, finish.
    elapsed_h : Time at each track point since departure [h].
    departure : Departure time (UTC).
    legs : Per-leg conditions (one fewer than points), :class:`Legs`: typed arrays with units, also readable as
        ``legs["time_h"]``.
    nodes : Node index on each rank.
    grid : The grid routed on (the first leg's for a course through waypoints: see :attr:`grids`).
    dp : The raw DP result on :attr:`grid`.
    problem : The routing problem solved on :attr:`grid` (weather, polar, failure model, apf, obstacles).
    meta : Scenario details for the JSON summary (polar, failure model name, apf, refinement levels, ...): plain
        JSON values only; the objects a route knows are attributes.
    zones : The exclusion zones avoided (for maps).
    course_legs : For a course through waypoints, the route of each leg between consecutive marks (empty
        otherwise).
    grid_track : For a refined route, the track on the grid routed on before refinement (None otherwise).
    exposure_by_criterion_h : Hours sailed where each criterion of the failure model fires, by the criterion's
        description (e.g. ``"WH: hs_m >= 4 m"``) [h]; empty without a failure model.
    manoeuvres : Side of the wind of each leg, the tack or gybe at its start and the time it cost
        (:class:`~pyroute_rel.boat.manoeuvre.TrackManoeuvres`; penalties zero unless the boat has them).
    leg_marks_h : In time-varying weather, when the craft reaches the end of each of a leg's sub-segments [h after
        departure], shape (legs, samples + 1): the times the legs were sailed at (:mod:`pyroute_rel.boat.march`; the
        time along a sub-segment is linear between its marks, :func:`~pyroute_rel.boat.march.time_along`); None with
        steady weather (a leg's time is then shared along it by distance).
    arrived : False for a track that stops short of the finish (a planner's that did not reach it): the outputs
        never name its last point the finish (:mod:`pyroute_rel.outputs` names it ``end``), and the map marks the
        finish and where the track ends (:func:`~pyroute_rel.viz.maps.plot_route`). A DP route always arrives.
    """

    lon_deg: FloatArray
    lat_deg: FloatArray
    elapsed_h: FloatArray
    departure: np.datetime64
    legs: Legs
    nodes: npt.NDArray[np.intp]
    grid: Grid
    dp: DPResult
    problem: RoutingProblem
    meta: dict[str, Any] = field(default_factory=dict)
    zones: tuple[Zone, ...] = ()
    course_legs: tuple[Route, ...] = ()
    grid_track: GridTrack | None = None
    exposure_by_criterion_h: dict[str, float] = field(default_factory=dict)
    manoeuvres: TrackManoeuvres | None = None
    leg_marks_h: FloatArray | None = None
    arrived: bool = True

    @property
    def weather(self) -> WeatherSource:
        """The weather routed in."""
        return self.problem.weather

    @property
    def failure(self) -> FailureModel | None:
        """The failure model (None without one)."""
        return self.problem.failure

    @property
    def grids(self) -> tuple[Grid, ...]:
        """The grid of each leg of the course (one grid without waypoints)."""
        return tuple(r.grid for r in self.course_legs) if self.course_legs else (self.grid,)

    @property
    def voyage_time_h(self) -> float:
        """Voyage time [h]."""
        return float(self.elapsed_h[-1])

    @property
    def distance_nm(self) -> float:
        """Sailed great-circle distance along the track [nm]."""
        return float(self.legs.distance_nm.sum())

    @property
    def time(self) -> npt.NDArray[np.datetime64]:
        """UTC time at each track point."""
        start = np.asarray(self.departure).astype("datetime64[s]")
        return start + np.round(self.elapsed_h * 3600.0).astype("timedelta64[s]")

    @property
    def arrival(self) -> np.datetime64:
        """Arrival time (UTC)."""
        return self.time[-1]

    @property
    def max_failure_probability(self) -> float:
        """Largest leg failure probability."""
        return float(np.max(self.legs.p_f))

    @property
    def voyage_failure_probability(self) -> float:
        """Probability of failure over the voyage, ``1 - exp(-sum of the legs' hazards)`` [-] (see the module
        notes): ``1 - prod(1 - p_fail_leg)``."""
        return combined_failure_probability(self.legs.p_fail_leg)

    @property
    def touches_edge(self) -> bool:
        """True when the track uses an outermost node of a rank (the grid may be too narrow)."""
        n = self.grid.n_nodes
        return n > 2 and bool(np.any((self.nodes == 0) | (self.nodes == n - 1)))

    def forbidden_arcs(self) -> ForbiddenArcs:
        """The arcs the DP found forbidden, each at the time the DP sails it: from every node it reached.

        Each arc of the grid leaving a node the DP reached is costed again at the DP's arrival time there (and
        after each wait the problem allows: an arc is listed when it is forbidden at every departure time tried),
        with the problem's weather, polar, failure model, apf and obstacles. Arcs the DP skipped by pruning are
        costed too, so the table may hold more arcs than ``dp.arcs_forbidden`` counts (``prune = false`` makes
        them agree). With a finish line, ranks whose every node is reached after the voyage ends are left out. A
        course through waypoints lists every leg's grid (column ``leg``); a refined route, the grid routed on.

        Returns
        -------
        ForbiddenArcs
            One row per forbidden arc, in the order leg, rank, destination node, source node.

        Examples
        --------
        >>> from pyroute_rel import scenario_from_mapping
        >>> sc = scenario_from_mapping({
        ...     "route": {"start": [-12.0, 45.0], "finish": [-20.0, 40.0]}, "grid": {"n_ranks": 20},
        ...     "weather": {"kind": "uniform", "tws_kn": 15.0, "twd_deg": 0.0, "hs_m": 1.0,
        ...                 "patch": [{"lon": [-17.0, -15.0], "lat": [41.0, 44.0], "hs_m": 4.5}]},
        ...     "avoid": {"land": False}, "failure": {"model": "dickson2018", "apf": 0.5}})
        >>> route = sc.route()
        >>> arcs = route.forbidden_arcs()
        >>> len(arcs), int(arcs.rank[0]), str(arcs.reason[0]), str(arcs.criteria[0]), str(arcs.departure[0])
        (694, 6, 'failure', 'WH: hs_m >= 4 m', '2018-06-02T09:14:22')
        """
        parts = self.course_legs or (self,)
        offsets = [float((r.departure - self.departure) / np.timedelta64(1, "s")) / 3600.0 for r in parts]
        tables = [
            forbidden_on_grid(r.grid, r.problem, r.dp, leg=i, offset_h=o)
            for i, (r, o) in enumerate(zip(parts, offsets, strict=True))
        ]
        return ForbiddenArcs(
            **{f.name: np.concatenate([vars(t)[f.name] for t in tables]) for f in fields(ForbiddenArcs)}
        )

    def _legs_grids(self) -> dict[str, Any]:
        """For a course through waypoints: the ranks of all legs and each leg's grid (the other keys are the first
        leg's)."""
        if not self.course_legs:
            return {}
        return {"n_ranks": sum(g.n_ranks for g in self.grids), "legs": [g.describe() for g in self.grids]}

    def summary(self) -> dict[str, Any]:
        """The JSON contract of ``pyroute-rel route --json`` (see the README)."""
        times = self.time
        p_point = np.concatenate([[0.0], self.legs.p_f])
        return {
            "voyage_time_h": self.voyage_time_h,
            "distance_nm": self.distance_nm,
            "departure": iso_utc(times[0]),
            "arrival": iso_utc(times[-1]),
            "grid": {
                "n_ranks": self.grid.n_ranks,
                "n_nodes": self.grid.n_nodes,
                "spacing_km": self.grid.spacing_km,
                "rank_spacing_km": self.grid.rank_spacing_km,
                "max_deviation_deg": self.grid.max_deviation_deg,
                "aspect": self.grid.aspect,
                "half_width_km": self.grid.half_width_km,
                "band": self.grid.band,
                "touches_edge": self.touches_edge,
                **self._legs_grids(),
            },
            "arcs": {
                "evaluated": self.dp.arcs_evaluated,
                "pruned": self.dp.arcs_pruned,
                "forbidden": self.dp.arcs_forbidden,
                "forbidden_by_reason": self.dp.forbidden_by_reason,
                "forbidden_by_criterion": self.dp.forbidden_by_criterion,
            },
            "max_failure_probability": self.max_failure_probability,
            "voyage_failure_probability": self.voyage_failure_probability,
            "exposure_by_criterion_h": dict(self.exposure_by_criterion_h),
            "manoeuvres": {"tacks": 0, "gybes": 0, "penalty_h": 0.0}
            if self.manoeuvres is None
            else self.manoeuvres.summary(),
            **self.meta,
            "track": [
                {"lon": float(lo), "lat": float(la), "time": iso_utc(t), "p_f": float(p)}
                for lo, la, t, p in zip(self.lon_deg, self.lat_deg, times, p_point, strict=True)
            ],
        }


def _put(values: FloatArray, i: npt.NDArray[np.intp], new: FloatArray) -> FloatArray:
    out = np.array(values, dtype=float)  # a copy
    out[i] = new
    return out


def route_on_grid(
    grid: Grid,
    problem: RoutingProblem,
    *,
    progress: bool = False,
) -> Route:
    """Find the minimum-time route on the grid that respects the failure model (forward DP).

    Raises
    ------
    NoFeasibleRouteError
        When every path has a forbidden arc; the message says at which rank the front of reachable nodes
        died and which criteria forbade the arcs there.
    ScenarioError
        ``grid`` is not a Grid, ``problem`` not a RoutingProblem or ``progress`` not True or False.
    """
    from pyroute_rel.routing.grid import Grid

    check_instance(grid, Grid, "grid", ScenarioError)
    check_instance(problem, RoutingProblem, "problem", ScenarioError)
    progress = check_flag(progress, "progress", ScenarioError)
    result = forward_dp(grid, problem, progress=progress)
    if result.dead_rank is not None or not np.isfinite(result.finish_h):
        cause, hint = explain_cause(grid, problem, result)
        error = NoFeasibleRouteError(cause + hint)
        error.result, error.cause, error.hint = result, cause, hint  # for pyroute_rel.routing.relax
        raise error
    return build_route(grid, problem, result)


def _dp_elapsed(result: DPResult) -> FloatArray:
    """The DP's time at each point of its path but the last [h after departure] (0 at the start), where each leg
    leaves after its wait: the departure times :func:`~pyroute_rel.routing.solve.leg_manoeuvres` costs the legs from."""
    nodes = result.path()
    ranks = np.arange(len(nodes))
    if result.labels is not None:
        sides = result.path_sides()
        assert sides is not None  # (a DP with side labels gives the path's sides)
        arrival = result.labels.arrival_h[ranks, nodes, sides[:-1]]
    else:
        arrival = result.arrival_h[ranks, nodes]
    return np.concatenate([[0.0], arrival])


def build_route(grid: Grid, problem: RoutingProblem, result: DPResult) -> Route:
    """Turn a DP result into a Route, recomputing every leg from its end points: all legs in one vectorised call
    from the DP's arrival times, checked against the legs' own chain of arrivals
    (:func:`~pyroute_rel.routing.solve.leg_manoeuvres`)."""
    nodes = result.path()
    waits = result.waits()
    lon, lat = result.points(grid)
    elapsed, costs, manoeuvres = leg_manoeuvres(problem, lon, lat, waits, elapsed_guess_h=_dp_elapsed(result))
    legs, exposure = track_legs(problem, lon, lat, elapsed, waits, costs)
    meta: dict[str, Any] = {
        "apf": float(problem.apf),
        "failure_model": None if problem.failure is None else problem.failure.name,
        "failure_exposure_h": None if problem.failure is None else problem.failure.exposure_h,
        "polar": problem.polar.name,
        "samples_per_arc": problem.samples,
    }
    return Route(
        lon_deg=lon,
        lat_deg=lat,
        elapsed_h=elapsed,
        departure=np.datetime64(problem.departure).astype("datetime64[s]"),  # type: ignore[arg-type]
        legs=legs,
        nodes=nodes,
        grid=grid,
        dp=result,
        problem=problem,
        meta=meta,
        exposure_by_criterion_h={k: float(v.sum()) for k, v in exposure.criterion_h.items()},
        manoeuvres=manoeuvres,
        leg_marks_h=costs.marks_h,
    )


def track_legs(
    problem: RoutingProblem,
    lon_deg: FloatArray,
    lat_deg: FloatArray,
    elapsed_h: FloatArray,
    waits_h: FloatArray,
    costs: ArcCosts,
) -> tuple[Legs, LegExposure]:
    """Per-leg conditions and exposure of a timed track, every leg sailable (finite time).

    Parameters
    ----------
    problem : The routing problem the legs were costed in.
    lon_deg, lat_deg : Track points [deg] (one more than legs).
    elapsed_h : Time at each point [h after ``problem.departure``] (:func:`~pyroute_rel.routing.solve.leg_costs`).
    waits_h : Wait before each leg [h].
    costs : The legs' costs (:func:`~pyroute_rel.routing.solve.leg_costs`).

    Returns
    -------
    The legs (conditions at each leg's midpoint and mid-time, see :class:`Legs`) and their exposure
    (:func:`~pyroute_rel.reliability.exposure.leg_exposure`).
    """
    lon, lat, elapsed = (np.asarray(a, dtype=float) for a in (lon_deg, lat_deg, elapsed_h))
    waits = np.asarray(waits_h, dtype=float)
    dist = geodesy.distance_nm(lon[:-1], lat[:-1], lon[1:], lat[1:])
    mlon, mlat = geodesy.intermediate_point(lon[:-1], lat[:-1], lon[1:], lat[1:], 0.5)
    course = geodesy.initial_bearing_deg(mlon, mlat, lon[1:], lat[1:])
    marks = costs.marks_h  # when the craft reaches each sub-segment end (time-varying weather), else None
    mid_h = elapsed[:-1] + waits + 0.5 * costs.time_h if marks is None else time_along(marks, np.full(len(dist), 0.5))
    cond = problem.weather_at(mlon, mlat, mid_h)
    hole = ~(np.isfinite(cond.tws_kn) & np.isfinite(cond.twd_deg)) & np.isfinite(costs.time_h)
    if hole.any() and problem.samples > 1:
        # a sailable leg whose midpoint falls in a hole of the data (a NaN cell its samples straddle): report the
        # conditions at its cost sample nearest the midpoint instead, which the cost found valid
        frac = (problem.samples // 2 - 0.5) / problem.samples
        i = np.flatnonzero(hole)
        slon, slat = geodesy.intermediate_point(lon[i], lat[i], lon[i + 1], lat[i + 1], frac)
        at_h = (
            (elapsed[:-1] + waits)[i] + frac * costs.time_h[i]
            if marks is None
            else time_along(marks[i], np.full(i.size, frac))
        )
        at = problem.weather_at(slon, slat, at_h)
        cond = replace(cond, **{f.name: _put(vars(cond)[f.name], i, vars(at)[f.name]) for f in fields(cond)})
        course = course.copy()
        course[i] = geodesy.initial_bearing_deg(slon, slat, lon[i + 1], lat[i + 1])
    q = arc_quantities(cond, course)
    exposure = leg_exposure(problem, lon, lat, elapsed[:-1] + waits, costs.time_h, costs.p_f, marks_h=marks)
    legs = Legs(
        distance_nm=dist,
        time_h=costs.time_h,
        sog_kn=dist / costs.time_h,  # while sailing (waits excluded)
        course_deg=course,
        tws_kn=np.asarray(cond.tws_kn, dtype=float),
        twd_deg=np.asarray(cond.twd_deg, dtype=float),
        twa_deg=q["twa_deg"],
        hs_m=np.asarray(cond.hs_m, dtype=float),
        wave_dir_deg=np.asarray(cond.wave_dir_deg, dtype=float),
        awd_deg=q["awd_deg"],
        # the largest p_f judged along the leg, and at least that of every condition its exposure counts
        p_f=np.asarray(costs.p_f if exposure.p_max is None else np.fmax(costs.p_f, exposure.p_max), dtype=float),
        wait_h=waits,
        p_fail_leg=exposure.p_fail_leg,
    )
    return legs, exposure


def join_routes(routes: list[Route]) -> Route:
    """One Route from legs sailed one after the other (each starting where and when the previous ended).

    The legs' routes are kept in :attr:`Route.course_legs`; the grid, problem and obstacles are the first leg's.
    """
    first = routes[0]
    lon = _chain([r.lon_deg for r in routes])
    lat = _chain([r.lat_deg for r in routes])
    offsets = [0.0]
    for r in routes[:-1]:
        offsets.append(offsets[-1] + r.voyage_time_h)
    elapsed = np.concatenate(
        [first.elapsed_h, *(o + r.elapsed_h[1:] for o, r in zip(offsets[1:], routes[1:], strict=True))]
    )
    legs = Legs(**{k: np.concatenate([r.legs[k] for r in routes]) for k in first.legs})
    dp = replace(
        first.dp,
        arcs_evaluated=sum(r.dp.arcs_evaluated for r in routes),
        arcs_pruned=sum(r.dp.arcs_pruned for r in routes),
        arcs_forbidden=sum(r.dp.arcs_forbidden for r in routes),
        forbidden_by_reason={k: sum(r.dp.forbidden_by_reason[k] for r in routes) for k in first.dp.forbidden_by_reason},
        forbidden_by_criterion={
            k: sum(r.dp.forbidden_by_criterion.get(k, 0) for r in routes)
            for r0 in routes
            for k in r0.dp.forbidden_by_criterion
        },
    )
    meta = dict(first.meta)
    refined, grid_track = _joined_refinement(routes)
    meta.update(refined)
    meta["legs_of_course"] = len(routes)
    return Route(
        lon_deg=lon,
        lat_deg=lat,
        elapsed_h=elapsed,
        departure=first.departure,
        legs=legs,
        nodes=np.concatenate([r.nodes for r in routes]),
        grid=first.grid,
        dp=dp,
        problem=first.problem,
        meta=meta,
        zones=first.zones,
        course_legs=tuple(routes),
        grid_track=grid_track,
        exposure_by_criterion_h={
            k: sum(r.exposure_by_criterion_h.get(k, 0.0) for r in routes)
            for r0 in routes
            for k in r0.exposure_by_criterion_h
        },
        manoeuvres=_joined_manoeuvres(routes),
        leg_marks_h=_joined_marks(routes, offsets),
    )


def _joined_marks(routes: list[Route], offsets: list[float]) -> FloatArray | None:
    """The legs' marks of a course's legs one after the other, each shifted by the time its leg of the course starts
    [h] (None unless every leg has them, on as many samples)."""
    marks = [r.leg_marks_h for r in routes]
    if any(m is None for m in marks) or len({m.shape[1] for m in marks if m is not None}) != 1:
        return None
    return np.concatenate([o + m for o, m in zip(offsets, marks, strict=True) if m is not None])


def _joined_manoeuvres(routes: list[Route]) -> TrackManoeuvres | None:
    """The manoeuvres of a course's legs one after the other (each leg started on the side the last ended on)."""
    parts = [r.manoeuvres for r in routes]
    if any(m is None for m in parts):
        return None
    return TrackManoeuvres(
        side=np.concatenate([m.side for m in parts if m is not None]),
        kind=np.concatenate([m.kind for m in parts if m is not None]),
        penalty_h=np.concatenate([m.penalty_h for m in parts if m is not None]),
    )


def _chain(tracks: list[FloatArray]) -> FloatArray:
    """Legs' point arrays joined into one track: each leg after the first starts where the previous one ended."""
    return np.concatenate([tracks[0], *(t[1:] for t in tracks[1:])])


def _joined_refinement(routes: list[Route]) -> tuple[dict[str, Any], GridTrack | None]:
    """``meta["refine"]`` and the grid track of a course whose legs were refined (:mod:`pyroute_rel.refine`): level
    i's voyage time sums every leg's time after its level i (a leg that stopped earlier counts its best), its arcs
    the arcs the legs costed at that level, its half-width and spacing are the widest legs'."""
    infos = [r.meta.get("refine") for r in routes]
    if not any(infos):
        return {}, None
    n = max(len(i["levels"]) for i in infos if i)
    levels = []
    for k in range(n):
        at = [i["levels"][min(k, len(i["levels"]) - 1)] if i and i["levels"] else None for i in infos]
        levels.append(
            {
                "half_width_km": max(lv["half_width_km"] for lv in at if lv),
                "spacing_km": max(lv["spacing_km"] for lv in at if lv),
                "voyage_time_h": sum(
                    lv["voyage_time_h"] if lv else r.voyage_time_h for lv, r in zip(at, routes, strict=True)
                ),
                "arcs_evaluated": sum(i["levels"][k]["arcs_evaluated"] for i in infos if i and k < len(i["levels"])),
            }
        )
    tracks = [r.grid_track or GridTrack(r.lon_deg, r.lat_deg, r.voyage_time_h) for r in routes]
    lon = _chain([t.lon_deg for t in tracks])
    lat = _chain([t.lat_deg for t in tracks])
    grid_h = sum(i["grid_voyage_time_h"] if i else r.voyage_time_h for i, r in zip(infos, routes, strict=True))
    return {"refine": {"levels": levels, "grid_voyage_time_h": grid_h}}, GridTrack(lon, lat, grid_h)


def forbidden_on_grid(
    grid: Grid, problem: RoutingProblem, result: DPResult, *, leg: int = 0, offset_h: float = 0.0
) -> ForbiddenArcs:
    """The forbidden arcs of one grid's DP (see :meth:`Route.forbidden_arcs`).

    Parameters
    ----------
    grid, problem, result : The grid, the routing problem solved on it and its DP result.
    leg : Value of the ``leg`` column [-].
    offset_h : Added to ``departure_h``: the problem's departure after the voyage's [h].
    """
    blocks = []
    for k in range(grid.n_ranks + 1):
        t_prev = np.zeros(grid.start_points[0].size) if k == 0 else result.arrival_h[k - 1]
        if not np.isfinite(t_prev).any():
            break  # the front died
        if grid.finish_line is not None and k > 0 and np.all(t_prev >= result.finish_h):
            break  # every node reached after the voyage ended: the DP stopped
        blocks.append(_forbidden_into(grid, problem, k, t_prev))
    keys = ("rank", "src", "dst", "from_lon_deg", "from_lat_deg", "to_lon_deg", "to_lat_deg", "departure_h", "p_f")
    cols = {key: np.concatenate([np.zeros(0), *(b[key] for b in blocks)]) for key in (*keys, "reason", "fired")}
    names = [] if problem.failure is None else [c.describe() for c in problem.failure.criteria]
    reasons = cols["reason"].astype(np.int64)
    fired = cols["fired"].astype(np.int64)
    return ForbiddenArcs(
        leg=np.full(reasons.size, leg, dtype=np.intp),
        rank=cols["rank"].astype(np.intp),
        src=cols["src"].astype(np.intp),
        dst=cols["dst"].astype(np.intp),
        from_lon_deg=cols["from_lon_deg"],
        from_lat_deg=cols["from_lat_deg"],
        to_lon_deg=cols["to_lon_deg"],
        to_lat_deg=cols["to_lat_deg"],
        departure_h=offset_h + cols["departure_h"],
        departure=np.datetime64(problem.departure, "s")  # type: ignore[call-overload]  # numpy's stubs have no datetime64(datetime64, unit) overload
        + np.round(cols["departure_h"] * 3600.0).astype("timedelta64[s]"),
        p_f=cols["p_f"],
        reason=np.array(["+".join(n for n, bit in REASONS.items() if r & bit) for r in reasons], dtype=str),
        criteria=np.array(
            [
                "; ".join(c for i, c in enumerate(names) if (f >> i) & 1) if r & REASONS["failure"] else ""
                for f, r in zip(fired, reasons, strict=True)
            ],
            dtype=str,
        ),
    )


def _forbidden_into(grid: Grid, problem: RoutingProblem, k: int, t_prev: FloatArray) -> dict[str, np.ndarray]:
    """The forbidden arcs into rank k as columns (``reason`` and ``fired`` as bit codes), costed like the DP."""
    src, valid = grid.pattern(k)
    t_src = t_prev[src]
    live = valid & np.isfinite(t_src)
    t_src = np.where(live, t_src, 0.0)
    geom = grid_geometry(grid, k, problem.samples)
    step = problem.time_step_h or 0.0
    reason = np.zeros(live.shape, dtype=np.uint8)
    allowed = np.zeros(live.shape, dtype=bool)
    for w in range(problem.n_wait + 1):
        t0 = t_src + w * step
        costs = problem.geometry_costs(geom, t0)
        r_w = np.where(live, costs.reason, 0).astype(np.uint8)
        if problem.blocked is not None:
            hit = problem.blocked(k, hours_after(problem.departure, t0)) & live
            r_w = r_w | np.where(hit, REASONS["obstacle"], 0).astype(np.uint8)
        if w == 0:
            p_f, fired = np.broadcast_to(costs.p_f, live.shape), costs.bits()
        reason = reason | r_w  # forbidden when forbidden at every departure time tried
        allowed |= live & (r_w == 0)
    bad = live & ~allowed
    dst, col = np.nonzero(bad)
    lon0, lat0, lon1, lat1, _, _ = grid.arcs(k)
    return {
        "rank": np.full(dst.size, k),
        "src": src[dst, col],
        "dst": dst,
        "from_lon_deg": np.broadcast_to(lon0, live.shape)[bad],
        "from_lat_deg": np.broadcast_to(lat0, live.shape)[bad],
        "to_lon_deg": np.broadcast_to(lon1, live.shape)[bad],
        "to_lat_deg": np.broadcast_to(lat1, live.shape)[bad],
        "departure_h": t_src[bad],
        "p_f": p_f[bad],
        "reason": reason[bad],
        "fired": fired[bad],
    }
