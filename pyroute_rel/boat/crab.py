"""Holding a course in a current: the exact crab angle.

A craft that must make good a course ``course_deg`` through water moving with a current steers a heading
``course + delta`` off the course (the crab angle ``delta``) so that the current's push across the course is
cancelled by its own velocity through the water. With boat speed through the water ``V(heading)`` from the polar
(it depends on the heading through the true wind angle), the heading must satisfy

    g(delta) = V(course + delta) * sin(delta) + c_cross = 0,

where ``c_cross`` is the current's component to starboard of the course, and the speed made good along the course
is ``sog = V(course + delta) * cos(delta) + c_along``. Because ``V`` depends on ``delta``, this is a scalar root
problem per point, not the closed form ``asin(-c_cross / V)`` with a fixed ``V``.

Method and guarantee
--------------------
At a root, ``V = |c_cross| / |sin(delta)|``, so the speed made good there is ``|c_cross| cot|delta| + c_along``: it
falls as ``|delta|`` grows. Of all headings that hold the course, the best is therefore the smallest crab angle,
on the side facing the cross current, and it is the one chosen.

The polar is bilinear, so at a point's wind speed ``V`` is linear in the true wind angle between the polar's
angles, and the true wind angle is linear in ``delta`` between the headings where it meets a polar angle, 0 or
180 deg. Cut at those headings, ``[0, 90]`` deg of crab angle falls into pieces on which ``V = a + b x`` exactly
(``x = delta`` in radians; ``a + b x`` is read from the polar at two points inside the piece, so a jump of ``V``
at a piece's end, as with ``beyond="forbid"``, is kept). On a piece, ``f(x) = (a + b x) sin x`` either rises
(``b >= 0``) or is concave (``b < 0``: ``f'' = 2 b cos x - V sin x < 0``), so whether ``f`` reaches ``|c_cross|``
on the piece, and where first, follows from its ends and, when concave, its maximum (a root of ``f'``, found by
bisection). The first piece where it does brackets the smallest crab angle, which regula falsi (Illinois) narrows
to 1e-12 rad on the exact piecewise form. No root is missed, however close two roots lie. Where no heading holds
the course with a speed made good of at least :data:`~pyroute_rel.boat.polar.MIN_SPEED_KN`, the point cannot be
sailed (``ok`` is False: the arc is forbidden with reason "current").

Without a cross current (``c_cross == 0``) the craft steers the course itself, as without current.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from pyroute_rel import geodesy
from pyroute_rel.boat.polar import MIN_SPEED_KN, Polar, boat_speed_kn
from pyroute_rel.units import KN_PER_MS
from pyroute_rel.weather.base import Conditions

__all__ = ["CrabSolution", "hold_course", "steer"]

FloatArray = npt.NDArray[np.float64]

_TOL_RAD = 1e-12  # the crab angle is refined until its bracket is this narrow [rad]
_MAX_ITER = 200


@dataclass(frozen=True)
class CrabSolution:
    """Where a craft steers to hold its course, and how fast it then goes; arrays of the points' shape.

    Attributes
    ----------
    heading_deg : Heading steered, clockwise from true north [deg], in [0, 360).
    twa_deg : True wind angle on that heading [deg], in [0, 180].
    boat_speed_kn : Speed through the water on that heading [kn] (polar speed times ``speed_factor``).
    sog_kn : Speed made good along the course [kn].
    ok : True where some heading holds the course with ``sog_kn >= MIN_SPEED_KN``; elsewhere the other fields
        hold the no-current values (heading = course) and the point cannot be sailed.
    """

    heading_deg: FloatArray
    twa_deg: FloatArray
    boat_speed_kn: FloatArray
    sog_kn: FloatArray
    ok: npt.NDArray[np.bool_]


def hold_course(
    course_deg: npt.ArrayLike,
    twd_deg: npt.ArrayLike,
    tws_kn: npt.ArrayLike,
    current_u_ms: npt.ArrayLike,
    current_v_ms: npt.ArrayLike,
    polar: Polar,
    *,
    beyond: str = "clamp",
    speed_factor: npt.ArrayLike = 1.0,
) -> CrabSolution:
    """The heading that holds ``course_deg`` in a current, with the speed made good (exact crab angle).

    Parameters
    ----------
    course_deg : Course to make good, clockwise from true north [deg].
    twd_deg : True wind direction, from [deg].
    tws_kn : True wind speed [kn].
    current_u_ms, current_v_ms : Current, eastward and northward, "to" [m/s].
    polar : The craft's polar.
    beyond : What the polar does outside its table (:data:`~pyroute_rel.boat.polar.BEYOND_MODES`).
    speed_factor : Multiplies the polar speed (e.g. a wave speed loss) [-], >= 0.

    Returns
    -------
    CrabSolution
        Arrays with the broadcast shape of the inputs.

    Examples
    --------
    A polar of 5 kn at every angle in 0.5 m/s of current across the course: ``sin(delta) = -c / V``, and the speed
    made good is ``sqrt(V**2 - c**2)`` (c = 0.5 m/s = 0.971922 kn; closed form 348.791233 deg, 4.904627 kn):

    >>> flat = Polar(twa_deg=[0.0, 180.0], tws_kn=[0.0, 40.0], speed_kn=[[5.0, 5.0], [5.0, 5.0]], name="flat")
    >>> s = hold_course(0.0, 90.0, 10.0, 0.5, 0.0, flat)
    >>> round(float(s.heading_deg), 6), round(float(s.sog_kn), 6)
    (348.791233, 4.904627)
    """
    arrays = np.broadcast_arrays(
        *(np.asarray(x, dtype=np.float64) for x in (course_deg, twd_deg, tws_kn, current_u_ms, current_v_ms))
    )
    factor = np.broadcast_to(np.asarray(speed_factor, dtype=np.float64), arrays[0].shape).ravel()
    shape = arrays[0].shape
    course, twd, tws, cu, cv = (a.ravel() for a in arrays)
    crs = np.radians(course)
    cu_kn, cv_kn = cu * KN_PER_MS, cv * KN_PER_MS
    c_along = cu_kn * np.sin(crs) + cv_kn * np.cos(crs)
    c_cross = cu_kn * np.cos(crs) - cv_kn * np.sin(crs)  # to starboard of the course

    def speed(rows: npt.NDArray[np.intp], delta_deg: FloatArray) -> FloatArray:
        twa = geodesy.angle_diff_deg(twd[rows], course[rows] + delta_deg)
        return boat_speed_kn(polar, twa, tws[rows], beyond=beyond) * factor[rows]

    best_delta = np.where(c_cross == 0.0, 0.0, np.nan)  # NaN: no heading holds the course (yet)
    v0 = speed(np.arange(course.size), np.zeros(course.shape))
    best_sog = np.where(c_cross == 0.0, v0 + c_along, -np.inf)
    best_sog[np.isnan(v0) | np.isnan(c_cross)] = np.nan
    crossed = np.flatnonzero((c_cross != 0.0) & np.isfinite(c_cross))
    if crossed.size:
        knots = np.union1d(polar.twa_deg, [0.0, 180.0])
        with np.errstate(divide="ignore", invalid="ignore", over="ignore", under="ignore"):
            _solve(crossed, twd - course, c_cross, speed, knots, best_delta)
    delta = best_delta
    v = speed(np.arange(course.size), delta)
    with np.errstate(invalid="ignore"):
        sog = np.where(np.isfinite(delta), v * np.cos(np.radians(delta)) + c_along, np.nan)
    sog = np.where(c_cross == 0.0, best_sog, sog)
    ok = sog >= MIN_SPEED_KN
    delta = np.where(ok, delta, 0.0)
    heading = np.mod(course + delta, 360.0)
    v = np.where(ok, v, speed(np.arange(course.size), delta))
    sog = np.where(ok, sog, np.where(np.isnan(sog) & np.isnan(v), np.nan, 0.0))
    twa = geodesy.angle_diff_deg(twd, heading)
    return CrabSolution(
        heading_deg=heading.reshape(shape),
        twa_deg=twa.reshape(shape),
        boat_speed_kn=v.reshape(shape),
        sog_kn=sog.reshape(shape),
        ok=ok.reshape(shape),
    )


def steer(
    cond: Conditions,
    course_deg: npt.ArrayLike,
    polar: Polar,
    *,
    beyond: str = "clamp",
    speed_factor: npt.ArrayLike = 1.0,
) -> CrabSolution:
    """:func:`hold_course` in the wind and current of ``cond`` (one place for the cost function and the exposure
    integral, so both judge the heading the craft really steers)."""
    return hold_course(
        course_deg,
        cond.twd_deg,
        cond.tws_kn,
        cond.current_u_ms,
        cond.current_v_ms,
        polar,
        beyond=beyond,
        speed_factor=speed_factor,
    )


def _solve(
    rows: npt.NDArray[np.intp],
    wind_rel_deg: FloatArray,
    c_cross: FloatArray,
    speed: Callable[[npt.NDArray[np.intp], FloatArray], FloatArray],
    knots_deg: FloatArray,
    best_delta: FloatArray,
) -> None:
    """The smallest crab angle [deg] of the points ``rows`` (see the module notes), written into ``best_delta``.

    ``wind_rel_deg`` is the wind direction relative to the course (twd - course) [deg]; ``knots_deg`` the true wind
    angles where the polar's speed may bend [deg].
    """
    n = rows.size
    side = -np.sign(c_cross[rows])  # steer into the cross current: delta = side * x
    cross = np.abs(c_cross[rows])
    # crab angles x [deg] in (0, 90) where the true wind angle |wrap(w - side x)| meets a knot
    w = wind_rel_deg[rows][:, None]
    k = knots_deg[None, :]
    cuts = np.concatenate([side[:, None] * (w - k), side[:, None] * (w + k)], axis=1)
    cuts = np.mod(cuts, 360.0)
    cuts = np.where((cuts > 0.0) & (cuts < 90.0), cuts, 90.0)
    edges = np.sort(np.concatenate([np.zeros((n, 1)), cuts, np.full((n, 1), 90.0)], axis=1), axis=1)
    x0, x1 = np.radians(edges[:, :-1]), np.radians(edges[:, 1:])
    # V = a + b x on each piece, from two points inside it
    t1, t2 = x0 + (x1 - x0) / 3.0, x0 + 2.0 * (x1 - x0) / 3.0
    r = np.broadcast_to(rows[:, None], t1.shape).ravel()
    s_ = np.broadcast_to(side[:, None], t1.shape).ravel()
    v1 = speed(r, s_ * np.degrees(t1.ravel())).reshape(t1.shape)
    v2 = speed(r, s_ * np.degrees(t2.ravel())).reshape(t1.shape)
    b = (v2 - v1) / (t2 - t1)
    a = v1 - b * t1
    piece = x1 > x0
    c = cross[:, None]

    def h(x: FloatArray, aa: FloatArray, bb: FloatArray, cc: FloatArray) -> FloatArray:
        return (aa + bb * x) * np.sin(x) - cc

    h0, h1 = h(x0, a, b, c), h(x1, a, b, c)
    # concave pieces that end below the cross current may rise above it inside: where is their top?
    top = x1.copy()
    hump = piece & (b < 0) & (h0 < 0) & (h1 < 0)
    if hump.any():
        lo, hi, aa, bb = x0[hump], x1[hump], a[hump], b[hump]
        for _ in range(60):  # f' = b sin x + (a + b x) cos x falls on the piece: bisect its sign change
            mid = 0.5 * (lo + hi)
            rising = bb * np.sin(mid) + (aa + bb * mid) * np.cos(mid) > 0
            lo, hi = np.where(rising, mid, lo), np.where(rising, hi, mid)
        top[hump] = 0.5 * (lo + hi)
    h_top = np.where(hump, h(top, a, b, c), h1)
    reach = piece & ((h0 >= 0) | (h_top >= 0))
    has = reach.any(axis=1)
    j = np.argmax(reach, axis=1)  # the first piece that reaches
    at = np.flatnonzero(has)
    jj = j[at]
    lo, hi = x0[at, jj], np.where(h0[at, jj] >= 0, x0[at, jj], top[at, jj])
    aa, bb, cc = a[at, jj], b[at, jj], c[at, 0]
    root = _refine(lambda sub, x: h(x, aa[sub], bb[sub], cc[sub]), lo, hi)
    best_delta[rows[at]] = side[at] * np.degrees(root)


def _refine(h: Callable[[npt.NDArray[np.intp], FloatArray], FloatArray], a: FloatArray, b: FloatArray) -> FloatArray:
    """The upper end of a bracket [a, b] with ``h(a) < 0 <= h(b)`` narrowed below :data:`_TOL_RAD` around the root,
    by regula falsi with the Illinois modification (Dowell and Jarratt 1971, doi:10.1007/BF01934364); vectorised."""
    a, b = a.copy(), b.copy()
    idx = np.arange(a.size)
    fa, fb = h(idx, a), h(idx, b)
    side = np.zeros(a.size, dtype=np.int8)  # which end stayed last time: -1 a, +1 b
    active = np.flatnonzero(b - a > _TOL_RAD)
    for _ in range(_MAX_ITER):
        if not active.size:
            break
        aa, bb, ffa, ffb = a[active], b[active], fa[active], fb[active]
        x = bb - ffb * (bb - aa) / (ffb - ffa)
        bad = ~((x > aa) & (x < bb))
        x[bad] = 0.5 * (aa[bad] + bb[bad])
        fx = h(active, x)
        up = fx >= 0
        # the end that moves takes x; the end that stays twice in a row has its value halved (Illinois)
        fa_new = np.where(up & (side[active] == -1), 0.5 * ffa, ffa)
        fb_new = np.where(~up & (side[active] == 1), 0.5 * ffb, ffb)
        b[active] = np.where(up, x, bb)
        fb[active] = np.where(up, fx, fb_new)
        a[active] = np.where(up, aa, x)
        fa[active] = np.where(up, fa_new, fx)
        side[active] = np.where(up, -1, 1)
        active = active[b[active] - a[active] > _TOL_RAD]
    return b
