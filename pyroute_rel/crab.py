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
on the side facing the cross current, and it is the one chosen. No root lies below ``asin(|c_cross| / V_max)``,
``V_max`` being the polar's fastest speed at the point's wind speed; from there the crab angle is stepped outward
by ``step_deg`` (1 deg by default) until ``g`` changes sign, and that step is narrowed to below 1e-9 deg (regula
falsi, Illinois variant, which keeps the bracket). ``g`` is continuous (the polar is interpolated bilinearly), so
the root found is the smallest one except where ``g`` touches zero and turns back within one step, which costs at
most a grazing heading. Where no heading holds the course with a speed made good of at least
:data:`~pyroute_rel.polar.MIN_SPEED_KN`, the point cannot be sailed (``ok`` is False: the arc is forbidden with
reason "current").

Without a cross current (``c_cross == 0``) the craft steers the course itself, as without current.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from . import geodesy
from .polar import MIN_SPEED_KN, Polar, boat_speed_kn
from .units import KN_PER_MS

__all__ = ["CrabSolution", "hold_course"]

FloatArray = npt.NDArray[np.float64]

_TOL_DEG = 1e-9  # the crab angle is refined until its bracket is this narrow [deg]
_MAX_ITER = 100


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
    step_deg: float = 1.0,
) -> CrabSolution:
    """The heading that holds ``course_deg`` in a current, with the speed made good (exact crab angle).

    Parameters
    ----------
    course_deg : Course to make good, clockwise from true north [deg].
    twd_deg : True wind direction, from [deg].
    tws_kn : True wind speed [kn].
    current_u_ms, current_v_ms : Current, eastward and northward, "to" [m/s].
    polar : The craft's polar.
    beyond : What the polar does outside its table (:data:`~pyroute_rel.polar.BEYOND_MODES`).
    speed_factor : Multiplies the polar speed (e.g. a wave speed loss) [-], >= 0.
    step_deg : Scan step of the crab angle [deg] (see the module notes), in (0, 10].

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
    if not 0.0 < step_deg <= 10.0:
        raise ValueError(f"'step_deg' must be in (0, 10] [deg] (got {step_deg!r})")
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

    best_delta = np.zeros(course.shape)
    v0 = speed(np.arange(course.size), np.zeros(course.shape))
    best_sog = np.where(c_cross == 0.0, v0 + c_along, -np.inf)
    best_sog[np.isnan(v0) | np.isnan(c_cross)] = np.nan
    crossed = np.flatnonzero((c_cross != 0.0) & np.isfinite(c_cross))
    if crossed.size:
        # the fastest the craft can sail at each point's wind speed: the polar's maximum over its angles
        v_max = np.max(boat_speed_kn(polar, polar.twa_deg[None, :], tws[:, None], beyond=beyond), axis=1) * factor
        _solve(crossed, c_cross, c_along, speed, v_max, step_deg, best_delta, best_sog)
    ok = best_sog >= MIN_SPEED_KN
    delta = np.where(ok, best_delta, 0.0)
    heading = np.mod(course + delta, 360.0)
    v = speed(np.arange(course.size), delta)
    sog = np.where(ok, best_sog, np.where(np.isnan(best_sog), np.nan, 0.0))
    twa = geodesy.angle_diff_deg(twd, heading)
    return CrabSolution(
        heading_deg=heading.reshape(shape),
        twa_deg=twa.reshape(shape),
        boat_speed_kn=v.reshape(shape),
        sog_kn=sog.reshape(shape),
        ok=ok.reshape(shape),
    )


def _solve(
    rows: npt.NDArray[np.intp],
    c_cross: FloatArray,
    c_along: FloatArray,
    speed: Callable[[npt.NDArray[np.intp], FloatArray], FloatArray],
    v_max: FloatArray,
    step_deg: float,
    best_delta: FloatArray,
    best_sog: FloatArray,
) -> None:
    """The smallest crab angle of the points ``rows`` (see the module notes), written into ``best_*``."""
    cross = np.abs(c_cross[rows])
    side = -np.sign(c_cross[rows])  # steer into the cross current
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = cross / v_max[rows]
    rows, cross, side = rows[ratio < 1.0], cross[ratio < 1.0], side[ratio < 1.0]
    lo = np.degrees(np.arcsin(ratio[ratio < 1.0]))  # no root below this

    def h(at: npt.NDArray[np.intp], d: FloatArray) -> FloatArray:  # >= 0 once the craft stems the cross current
        return speed(rows[at], side[at] * d) * np.sin(np.radians(d)) - cross[at]

    active = np.arange(rows.size)
    hi = lo.copy()
    found = np.zeros(rows.size, dtype=bool)
    h_hi = h(active, hi)
    found[active[h_hi >= 0]] = True
    active = active[h_hi < 0]
    while active.size:
        lo[active] = hi[active]
        hi[active] = np.minimum(hi[active] + step_deg, 90.0)
        h_hi = h(active, hi[active])
        found[active[h_hi >= 0]] = True
        active = active[(h_hi < 0) & (lo[active] < 90.0)]
    at = np.flatnonzero(found)
    b = _refine(lambda sub, d: h(at[sub], d), lo[at], hi[at])
    delta = side[at] * b
    r = rows[at]
    best_delta[r] = delta
    best_sog[r] = speed(r, delta) * np.cos(np.radians(delta)) + c_along[r]


def _refine(h: Callable[[npt.NDArray[np.intp], FloatArray], FloatArray], a: FloatArray, b: FloatArray) -> FloatArray:
    """The upper end of a bracket [a, b] with ``h(a) < 0 <= h(b)`` narrowed below :data:`_TOL_DEG` around the root,
    by regula falsi with the Illinois modification (Dowell and Jarratt 1971, doi:10.1007/BF01934364); vectorised."""
    a, b = a.copy(), b.copy()
    idx = np.arange(a.size)
    fa, fb = h(idx, a), h(idx, b)
    side = np.zeros(a.size, dtype=np.int8)  # which end stayed last time: -1 a, +1 b
    active = np.flatnonzero(b - a > _TOL_DEG)
    for _ in range(_MAX_ITER):
        if not active.size:
            break
        aa, bb, ffa, ffb = a[active], b[active], fa[active], fb[active]
        with np.errstate(divide="ignore", invalid="ignore"):
            x = bb - ffb * (bb - aa) / (ffb - ffa)
        bad = ~((x > aa) & (x < bb))
        x[bad] = 0.5 * (aa[bad] + bb[bad])
        fx = h(active, x)
        up = fx >= 0
        # the end that moves takes x; the end that stays twice in a row has its value halved (Illinois)
        stay_a, stay_b = up, ~up
        fa_new = np.where(stay_a & (side[active] == -1), 0.5 * ffa, ffa)
        fb_new = np.where(stay_b & (side[active] == 1), 0.5 * ffb, ffb)
        b[active] = np.where(up, x, bb)
        fb[active] = np.where(up, fx, fb_new)
        a[active] = np.where(up, aa, x)
        fa[active] = np.where(up, fa_new, fx)
        side[active] = np.where(up, -1, 1)
        active = active[b[active] - a[active] > _TOL_DEG]
    return b
