"""The Route result: track, per-leg conditions and failure probabilities, and its exports.

Voyage failure probability
--------------------------
Each leg's ``p_f`` is the failure model's probability for the worst conditions met along that leg. The
voyage failure probability is ``1 - prod(1 - p_f_leg)``: it assumes that failures on different legs are
independent events, which overstates the risk when the same weather system is met over many consecutive
legs (the legs are then strongly correlated) and depends on the grid's leg length. Treat it as an
indicator for comparing routes on the same grid, not as a calibrated probability; the maximum leg
``p_f`` (which the ``apf`` constraint bounds) does not depend on the grid.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields, replace
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from . import geodesy
from .cost import arc_quantities
from .errors import NoFeasibleRouteError
from .solve import DPResult, RoutingProblem, explain_infeasible, forward_dp, leg_costs
from .times import hours_after, iso_utc

if TYPE_CHECKING:
    from .grid import Grid
    from .weather import Conditions

__all__ = ["Route", "build_route", "join_routes", "route_on_grid", "LEG_FIELDS"]

FloatArray = npt.NDArray[np.float64]

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
)


@dataclass(frozen=True, eq=False)
class Route:
    """A routed voyage.

    Attributes
    ----------
    lon_deg, lat_deg : Track points [deg]: start, one node per rank, finish.
    elapsed_h : Time at each track point since departure [h].
    departure : Departure time (UTC).
    legs : Per-leg arrays (one fewer than points): ``distance_nm`` [nm], ``time_h`` [h], ``sog_kn`` mean speed
        over ground [kn], ``course_deg`` [deg], and at the leg's midpoint and mid-time ``tws_kn``, ``twd_deg``,
        ``twa_deg``, ``hs_m``, ``wave_dir_deg``, ``awd_deg`` (where the data have a hole at the midpoint that the
        leg's cost samples straddle, at the sample nearest it); ``p_f`` the leg's largest failure probability.
    nodes : Node index on each rank.
    grid : The grid routed on.
    dp : The raw DP result.
    meta : Scenario details for reports (polar, failure model, apf, ...).
    """

    lon_deg: FloatArray
    lat_deg: FloatArray
    elapsed_h: FloatArray
    departure: np.datetime64
    legs: dict[str, FloatArray]
    nodes: npt.NDArray[np.intp]
    grid: Grid
    dp: DPResult
    meta: dict[str, Any] = field(default_factory=dict)

    @property
    def voyage_time_h(self) -> float:
        """Voyage time [h]."""
        return float(self.elapsed_h[-1])

    @property
    def distance_nm(self) -> float:
        """Sailed great-circle distance along the track [nm]."""
        return float(self.legs["distance_nm"].sum())

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
        return float(np.max(self.legs["p_f"]))

    @property
    def voyage_failure_probability(self) -> float:
        """``1 - prod(1 - p_f)`` over legs (legs assumed independent; see the module notes)."""
        return float(1.0 - np.prod(1.0 - self.legs["p_f"]))

    @property
    def touches_edge(self) -> bool:
        """True when the track uses an outermost node of a rank (the grid may be too narrow)."""
        n = self.grid.n_nodes
        return n > 2 and bool(np.any((self.nodes == 0) | (self.nodes == n - 1)))

    def _legs_grids(self) -> dict[str, Any]:
        """For a course through waypoints: the ranks of all legs and each leg's grid (the other keys are the first
        leg's)."""
        grids = self.meta.get("grids_object")
        if not grids:
            return {}
        return {"n_ranks": sum(g.n_ranks for g in grids), "legs": [g.describe() for g in grids]}

    def summary(self) -> dict[str, Any]:
        """The JSON contract of ``pyroute-rel route --json`` (see the README)."""
        times = self.time
        p_point = np.concatenate([[0.0], self.legs["p_f"]])
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
            **{k: v for k, v in self.meta.items() if not k.endswith("_object")},
            "track": [
                {"lon": float(lo), "lat": float(la), "time": iso_utc(t), "p_f": float(p)}
                for lo, la, t, p in zip(self.lon_deg, self.lat_deg, times, p_point, strict=True)
            ],
        }


def _sample(problem: RoutingProblem, lon: FloatArray, lat: FloatArray, t_h: FloatArray) -> Conditions:
    """The problem's weather at points and times [h after departure] (at the departure when it is steady)."""
    if getattr(problem.weather, "steady", False):
        return problem.weather.sample(lon, lat, problem.departure)
    return problem.weather.sample(lon, lat, hours_after(problem.departure, np.asarray(t_h, dtype=float)))


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
    """
    result = forward_dp(grid, problem, progress=progress)
    if result.dead_rank is not None or not np.isfinite(result.finish_h):
        raise NoFeasibleRouteError(explain_infeasible(grid, problem, result))
    return build_route(grid, problem, result)


def build_route(grid: Grid, problem: RoutingProblem, result: DPResult) -> Route:
    """Turn a DP result into a Route, recomputing every leg from its end points."""
    nodes = result.path()
    waits = result.waits()
    lon, lat = result.points(grid)
    elapsed, costs = leg_costs(problem, lon, lat, waits)
    dist = geodesy.distance_nm(lon[:-1], lat[:-1], lon[1:], lat[1:])
    mlon, mlat = geodesy.intermediate_point(lon[:-1], lat[:-1], lon[1:], lat[1:], 0.5)
    course = geodesy.initial_bearing_deg(mlon, mlat, lon[1:], lat[1:])
    mid_h = elapsed[:-1] + waits + 0.5 * costs.time_h
    cond = _sample(problem, mlon, mlat, mid_h)
    hole = ~(np.isfinite(cond.tws_kn) & np.isfinite(cond.twd_deg)) & np.isfinite(costs.time_h)
    if hole.any() and problem.samples > 1:
        # a sailable leg whose midpoint falls in a hole of the data (a NaN cell its samples straddle): report the
        # conditions at its cost sample nearest the midpoint instead, which the cost found valid
        frac = (problem.samples // 2 - 0.5) / problem.samples
        i = np.flatnonzero(hole)
        slon, slat = geodesy.intermediate_point(lon[i], lat[i], lon[i + 1], lat[i + 1], frac)
        at = _sample(problem, slon, slat, (elapsed[:-1] + waits)[i] + frac * costs.time_h[i])
        cond = replace(cond, **{f.name: _put(getattr(cond, f.name), i, getattr(at, f.name)) for f in fields(cond)})
        course = course.copy()
        course[i] = geodesy.initial_bearing_deg(slon, slat, lon[i + 1], lat[i + 1])
    q = arc_quantities(cond, course)
    legs = {
        "distance_nm": dist,
        "time_h": costs.time_h,
        "sog_kn": dist / costs.time_h,  # while sailing (waits excluded)
        "course_deg": course,
        "tws_kn": np.asarray(cond.tws_kn, dtype=float),
        "twd_deg": np.asarray(cond.twd_deg, dtype=float),
        "twa_deg": q["twa_deg"],
        "hs_m": np.asarray(cond.hs_m, dtype=float),
        "wave_dir_deg": np.asarray(cond.wave_dir_deg, dtype=float),
        "awd_deg": q["awd_deg"],
        "p_f": np.asarray(costs.p_f, dtype=float),
        "wait_h": waits,
    }
    meta: dict[str, Any] = {
        "apf": float(problem.apf),
        "failure_model": None if problem.failure is None else problem.failure.name,
        "polar": problem.polar.name,
        "samples_per_arc": problem.samples,
        "weather_object": problem.weather,
        "failure_object": problem.failure,
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
        meta=meta,
    )


def join_routes(routes: list[Route]) -> Route:
    """One Route from legs sailed one after the other (each starting where and when the previous ended)."""
    from dataclasses import replace as _replace

    first = routes[0]
    lon = _chain([r.lon_deg for r in routes])
    lat = _chain([r.lat_deg for r in routes])
    offsets = [0.0]
    for r in routes[:-1]:
        offsets.append(offsets[-1] + r.voyage_time_h)
    elapsed = np.concatenate(
        [first.elapsed_h, *(o + r.elapsed_h[1:] for o, r in zip(offsets[1:], routes[1:], strict=True))]
    )
    legs = {k: np.concatenate([r.legs[k] for r in routes]) for k in first.legs}
    dp = _replace(
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
    meta.update(_joined_refinement(routes))
    meta["legs_of_course"] = len(routes)
    meta["grids_object"] = [r.grid for r in routes]
    return Route(
        lon_deg=lon,
        lat_deg=lat,
        elapsed_h=elapsed,
        departure=first.departure,
        legs=legs,
        nodes=np.concatenate([r.nodes for r in routes]),
        grid=first.grid,
        dp=dp,
        meta=meta,
    )


def _chain(tracks: list[FloatArray]) -> FloatArray:
    """Legs' point arrays joined into one track: each leg after the first starts where the previous one ended."""
    return np.concatenate([tracks[0], *(t[1:] for t in tracks[1:])])


def _joined_refinement(routes: list[Route]) -> dict[str, Any]:
    """``meta["refine"]`` and the grid track of a course whose legs were refined (:mod:`pyroute_rel.refine`): level
    i's voyage time sums every leg's time after its level i (a leg that stopped earlier counts its best), its arcs
    the arcs the legs costed at that level, its half-width and spacing are the widest legs'."""
    infos = [r.meta.get("refine") for r in routes]
    if not any(infos):
        return {}
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
    tracks = [r.meta.get("grid_track_object") or (r.lon_deg, r.lat_deg, r.voyage_time_h) for r in routes]
    lon = _chain([t[0] for t in tracks])
    lat = _chain([t[1] for t in tracks])
    grid_h = sum(i["grid_voyage_time_h"] if i else r.voyage_time_h for i, r in zip(infos, routes, strict=True))
    return {"refine": {"levels": levels, "grid_voyage_time_h": grid_h}, "grid_track_object": (lon, lat, grid_h)}
