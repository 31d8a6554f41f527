"""What a route map shades: the failure model's probability, fired criteria and class against apf over an area,
for the heading and time of the route where it passes nearest (:func:`route_risk_field`).

The maps of :mod:`pyroute_rel.viz.maps` only draw; the physics they show (weather sampled on a mesh, the quantities the
failure model reads, its probability) is computed here, from the same functions the router costs arcs with
(:func:`~pyroute_rel.reliability.failure.arc_quantities`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from pyroute_rel import geodesy
from pyroute_rel.boat.crab import steer
from pyroute_rel.boat.march import time_along
from pyroute_rel.reliability.failure import arc_quantities

if TYPE_CHECKING:
    from pyroute_rel.reliability.failure import FailureModel
    from pyroute_rel.routing.grid import Grid
    from pyroute_rel.routing.route import Route
    from pyroute_rel.weather import Conditions, WeatherSource

__all__ = [
    "failure_field",
    "continuous_lon_deg",
    "RISK_CLASSES",
    "risk_class",
    "format_probability",
    "RiskField",
    "track_samples",
    "nearest_sample",
    "route_risk_field",
]

FloatArray = npt.NDArray[np.float64]


def continuous_lon_deg(lon_deg: npt.ArrayLike, ref_deg: float) -> FloatArray:
    """Longitudes [deg] moved by whole turns to within 180 deg of ``ref_deg`` [deg], so a course across the
    antimeridian is continuous (values may run past +-180; whole turns only, so longitudes in view stay exact).

    Examples
    --------
    >>> continuous_lon_deg([179.0, -179.0], 179.0).tolist()
    [179.0, 181.0]
    """
    x = np.asarray(lon_deg, dtype=float)
    return x + 360.0 * np.round((ref_deg - x) / 360.0)


def failure_field(
    grid: Grid, weather: WeatherSource, failure: FailureModel, *, time: Any = None, n: int = 200
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Failure probability and fired-criteria count on a lon/lat mesh covering the grid, for a craft heading
    towards the finish.

    The maps use :func:`route_risk_field` instead: criteria that depend on the heading fire here for a heading no
    route may sail (south of the finish, heading north), and time-varying weather is read at one time.

    Parameters
    ----------
    grid : The grid whose extent the mesh covers.
    weather : The weather sampled at the mesh points.
    failure : The failure model.
    time : When the weather is sampled (UTC); default 2000-01-01 (any time, for steady weather).
    n : Mesh points along each axis.

    Returns
    -------
    ``(lon [deg], lat [deg], p_f, n_fired)`` 2-D arrays of shape (n, n); the heading at each point is the
    great-circle course towards the finish. Longitudes are continuous across the antimeridian
    (:func:`continuous_lon_deg` around the start).
    """
    view = continuous_lon_deg(grid.lon_deg, grid.start[0])
    lon = np.linspace(view.min(), view.max(), n)
    lat = np.linspace(grid.lat_deg.min(), grid.lat_deg.max(), n)
    glon, glat = np.meshgrid(lon, lat)  # longitudes may run past +-180 (a course across the antimeridian)
    heading = geodesy.initial_bearing_deg(glon, glat, grid.finish[0], grid.finish[1])
    t = np.datetime64("2000-01-01") if time is None else time
    cond = weather.sample((glon + 180.0) % 360.0 - 180.0, glat, t)
    q = arc_quantities(cond, heading)
    need = {k: q[k] for k in failure.quantities}
    p = np.asarray(failure.p_fail(need), dtype=float)
    fired = np.asarray(failure.fired(need)).sum(axis=0)
    return glon, glat, p, fired


#: Classes of :attr:`RiskField.risk_class`: the failure model's verdict on a point, against the route's apf.
RISK_CLASSES: dict[int, str] = {
    -1: "unknown (weather missing)",
    0: "allowed (no criterion fires)",
    1: "criteria fire, allowed (p_f <= apf)",
    2: "forbidden (p_f > apf)",
}


def risk_class(p_f: npt.ArrayLike, n_fired: npt.ArrayLike, apf: float) -> npt.NDArray[np.int8]:
    """The class of each point (:data:`RISK_CLASSES`): 2 where ``p_f > apf`` (the router forbids arcs there),
    1 where a criterion fires but ``p_f <= apf``, 0 where none fires and ``p_f <= apf``, -1 where p_f is NaN.

    Parameters
    ----------
    p_f : Failure probabilities [-].
    n_fired : Number of criteria fired at each point.
    apf : Acceptable probability of failure [-].

    Examples
    --------
    >>> risk_class([0.0, 0.9, 1.0, float("nan")], [0, 1, 2, 0], 0.95).tolist()
    [0, 1, 2, -1]
    """
    p = np.asarray(p_f, dtype=float)
    fired = np.asarray(n_fired) > 0
    out = np.where(p > apf, 2, np.where(fired, 1, 0)).astype(np.int8)
    out[np.isnan(p)] = -1
    return out


def format_probability(p: float, digits: int = 2) -> str:
    """A probability with ``digits`` significant digits of itself, or of its distance to 1 when close to 1, so that
    small and near-certain values stay distinct (0.001 is not 0.00, 0.9996 is not 1).

    Examples
    --------
    >>> [format_probability(p) for p in (0.0, 0.001, 0.00123, 0.5, 0.9, 0.95, 0.9996, 1.0)]
    ['0', '0.001', '0.0012', '0.5', '0.9', '0.95', '0.9996', '1']
    >>> format_probability(float("nan")), format_probability(2.5e-7), format_probability(-0.0)
    ('nan', '2.5e-07', '0')
    """
    if not math.isfinite(p):
        return str(p)
    if p == 0.0:
        return "0"  # -0.0 too
    if p == 1.0 or p < 0.0 or p > 1.0:
        return f"{p:g}"
    if p < 1e-4:
        return f"{p:.{digits}g}"
    small = min(p, 1.0 - p)  # the digits that tell it apart from 0 or from 1
    decimals = max(digits - 1 - math.floor(math.log10(small)), 1)
    text = f"{p:.{decimals}f}".rstrip("0").rstrip(".")
    return text if text not in ("0", "1") else f"{p:.{decimals + 1}f}"


@dataclass(frozen=True)
class RiskField:
    """The failure model over an area, for the heading and time of the route nearest each point (what a route's map
    shades).

    Each point is evaluated as the route would meet it: with the course the route sails at its nearest point
    (the great-circle course of the leg there, or with a current the heading that holds it), and with the weather
    at the time the route passes that point. On the track this is what the router costs; off it, it answers "what
    if the route had passed here, sailing as it does nearby".

    Attributes
    ----------
    lon_deg, lat_deg : Mesh [deg], 2-D; longitudes continuous across the antimeridian (:func:`continuous_lon_deg`
        around the route's start).
    heading_deg : Heading evaluated at each point [deg].
    course_deg : Course over ground of the route at its nearest point [deg] (the heading, without a current).
    elapsed_h : When the weather is sampled at each point [h after the route's departure].
    conditions : The weather there and then.
    p_f : Failure probability [-] (0 without a failure model; NaN where the evidence is unknown).
    n_fired : Criteria fired at each point.
    risk_class : :func:`risk_class` against :attr:`apf`.
    apf : The route's acceptable probability of failure [-].
    """

    lon_deg: FloatArray
    lat_deg: FloatArray
    heading_deg: FloatArray
    course_deg: FloatArray
    elapsed_h: FloatArray
    conditions: Conditions
    p_f: FloatArray
    n_fired: npt.NDArray[np.intp]
    risk_class: npt.NDArray[np.int8]
    apf: float


def track_samples(route: Route, *, spacing_km: float = 10.0) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Points along a route's legs at most ``spacing_km`` [km] apart (mid-points of equal sub-segments, as the
    cost samples an arc), with the great-circle course there [deg] and the time the route passes [h after
    departure: in time-varying weather the times its legs were sailed at
    (:attr:`~pyroute_rel.routing.route.Route.leg_marks_h`), else linear in distance along each leg].

    Returns
    -------
    ``(lon [deg], lat [deg], course [deg], elapsed [h])``, 1-D.
    """
    lon, lat = np.asarray(route.lon_deg, dtype=float), np.asarray(route.lat_deg, dtype=float)
    km = geodesy.distance_km(lon[:-1], lat[:-1], lon[1:], lat[1:])
    n = np.maximum(np.ceil(km / spacing_km).astype(int), 1)
    leg = np.repeat(np.arange(km.size), n)
    k = np.arange(leg.size) - np.repeat(np.cumsum(n) - n, n)
    frac = (k + 0.5) / n[leg]
    s_lon, s_lat = geodesy.intermediate_point(lon[leg], lat[leg], lon[leg + 1], lat[leg + 1], frac)
    course = geodesy.initial_bearing_deg(s_lon, s_lat, lon[leg + 1], lat[leg + 1])
    if route.leg_marks_h is not None:  # the times the legs were sailed at (time-varying weather)
        return s_lon, s_lat, course, time_along(route.leg_marks_h[leg], frac)
    sail_from = route.elapsed_h[:-1] + route.legs.wait_h
    elapsed = sail_from[leg] + frac * route.legs.time_h[leg]
    return s_lon, s_lat, course, elapsed


def nearest_sample(
    lon_deg: FloatArray, lat_deg: FloatArray, s_lon: FloatArray, s_lat: FloatArray
) -> npt.NDArray[np.intp]:
    """Index of the sample nearest (great circle) each point, in the points' shape."""
    pts = geodesy.to_xyz(lon_deg, lat_deg).reshape(-1, 3)
    samples = geodesy.to_xyz(s_lon, s_lat)
    out = np.empty(pts.shape[0], dtype=np.intp)
    rows = max(1, 2_000_000 // max(samples.shape[0], 1))  # bounded memory: about 16 MB of dot products a chunk
    for i in range(0, pts.shape[0], rows):
        out[i : i + rows] = np.argmax(pts[i : i + rows] @ samples.T, axis=1)
    return out.reshape(np.shape(lon_deg))


def route_risk_field(
    route: Route,
    lon_deg: npt.ArrayLike,
    lat_deg: npt.ArrayLike,
    *,
    spacing_km: float = 10.0,
) -> RiskField:
    """The failure model on a mesh, for the heading and time of the route where it passes nearest each point.

    Parameters
    ----------
    route : The route (a course through waypoints: all its legs).
    lon_deg, lat_deg : Mesh points [deg] (any shape; longitudes may run past +-180).
    spacing_km : Spacing of the route's samples the points are matched to [km].

    Returns
    -------
    RiskField
        In the mesh's shape.
    """
    glon, glat = np.broadcast_arrays(np.asarray(lon_deg, dtype=float), np.asarray(lat_deg, dtype=float))
    s_lon, s_lat, s_course, s_h = track_samples(route, spacing_km=spacing_km)
    near = nearest_sample(glon, glat, s_lon, s_lat)
    course, elapsed = s_course[near], s_h[near]
    problem = route.problem
    cond = problem.weather_at(geodesy.wrap_lon(glon), glat, elapsed)
    heading, twa = course, None
    if cond.has_current:  # the heading that holds the course in the current, as the cost steers
        factor = 1.0 if problem.wave_loss is None else problem.wave_loss.factor(cond.hs_m)
        crab = steer(cond, course, problem.polar, beyond=problem.beyond, speed_factor=factor)
        heading, twa = crab.heading_deg, crab.twa_deg
    failure = route.failure
    if failure is None:
        p = np.zeros(glon.shape)
        n_fired = np.zeros(glon.shape, dtype=np.intp)
    else:
        q = arc_quantities(cond, heading, failure.quantities)
        if twa is not None and "twa_deg" in q:
            q["twa_deg"] = twa
        p = np.asarray(failure.p_fail(q), dtype=float)
        n_fired = np.asarray(failure.fired(q)).sum(axis=0)
    return RiskField(
        lon_deg=glon,
        lat_deg=glat,
        heading_deg=np.asarray(heading, dtype=float),
        course_deg=course,
        elapsed_h=elapsed,
        conditions=cond,
        p_f=p,
        n_fired=n_fired,
        risk_class=risk_class(p, n_fired, problem.apf),
        apf=float(problem.apf),
    )
