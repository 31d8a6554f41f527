"""No clipping: the largest failure probability met anywhere along great-circle arcs.

The cost function samples the weather at a few points of each arc (:func:`~pyroute_rel.routing.cost.geometry_costs`),
which times the arc well but can miss a corner of an area where the failure criteria fire. This module judges each arc
on everything it crosses:

1. **Pieces.** A weather source may say where its conditions can change (:class:`Boundaries`): the meridians and
   parallels of its patch edges or grid lines, within boxes. Each arc is cut where it crosses them (exactly, on the
   sphere: a meridian's plane meets the arc once at most; a parallel, ``z = sin(lat)``, at most twice), and at the
   equator (where the course along a great circle stops turning one way: elsewhere the course is monotonic along
   the arc, ``sin(course) cos(lat)`` being constant).
2. **Ranges.** On each piece the conditions are sampled at both ends, nudged inside the piece by
   :data:`NUDGE` of its length (a patch edge belongs to one side only), and at its middle; a crossing within
   :data:`NUDGE` of the arc's end (a node or waypoint on a patch edge, found there to rounding) does not cut the arc,
   so an arc that touches a patch only at an end is judged by its interior, as the cost function's samples judge it
   (the box is closed, but a point of contact is not a stretch sailed in it); with continuous fields
   (grids, smooth sources) also where the parabola through those three values of each quantity has its extremum.
   Each quantity's range over the piece is taken from those values; an angle relative to the heading (apparent
   wave direction, TWA) is unwrapped before it is folded into [0, 180], so a piece whose relative angle passes 0 or
   180 reaches it.
3. **Largest p_f.** Every state combination of the failure table whose bins the ranges reach is a candidate; the
   piece's p_f is the largest such entry (and the criteria that fire in any entry above ``apf`` are reported).

What this guarantees:

- *Patches* (:class:`~pyroute_rel.weather.UniformWeather`): conditions are constant on each piece but for the
  heading, which is monotonic on it, so the ranges are exact and an arc is judged on every patch it enters by more
  than the nudge (``NUDGE`` times the piece, under 0.1 m on arcs under 100 km; the crossings themselves are exact to
  rounding). With two heading-dependent quantities in one model (TWA and the apparent wave direction) the box of
  their ranges is a bound: it may count a combination the arc does not meet, never miss one (conservative).
- *Gridded fields* (:class:`~pyroute_rel.weather.GriddedWeather`, bilinear in space): the arc is cut at every grid
  line; within a cell a bilinear field along the piece is a product of two nearly linear functions, a parabola,
  whose extremum is sampled. The residual is the curvature of the great circle in lon/lat within one cell, far
  below 100 m on cells of a degree or less. In time, the arc is also cut wherever the craft crosses one of the
  file's time steps, at the times the march of :mod:`pyroute_rel.boat.march` gives (linear between the ends of its
  sub-segments): within a piece every field is then linear in time as well, and the piece is judged along its path
  in space and time.
- *Smooth sources without boundaries*: the arc is one piece: its ends, middle and the extremum of each quantity's
  parabola are sampled, exact for quantities monotonic or quadratic along the arc.

Missing weather (NaN) is still judged at the cost function's samples only; the pieces add failure criteria.

Cost: only the arcs that may need it are cut (:func:`needs_pieces`): with patches, those near a patch edge or whose
heading may cross a criterion's bin edge; with a gridded source, those whose sampled quantities are closer to a bin
edge than the field can change along the arc (:meth:`~pyroute_rel.weather.GriddedWeather.variation`). The others
keep their samples' p_f, which is then exact (no bin changes along them).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, replace
from typing import Any, Literal

import numpy as np
import numpy.typing as npt

from pyroute_rel import geodesy
from pyroute_rel.boat.crab import steer
from pyroute_rel.boat.march import step_hours, time_along
from pyroute_rel.boat.polar import Polar
from pyroute_rel.reliability.failure import QUANTITY_FIELDS, FailureModel
from pyroute_rel.times import hours_after
from pyroute_rel.units import KM_PER_NM
from pyroute_rel.weather.base import Boundaries, Conditions, WeatherSource

__all__ = [
    "Boundaries",
    "NUDGE",
    "ArcExtremes",
    "ArcPieces",
    "arc_extremes",
    "arc_pieces",
    "needs_pieces",
    "split_fractions",
    "time_fractions",
    "cut_in_time",
]

FloatArray = npt.NDArray[np.float64]

#: How far inside a piece [fraction of its length] its end points are sampled.
NUDGE = 1e-6


@dataclass(frozen=True)
class ArcExtremes:
    """The largest p_f along each arc and the criteria that fire where it exceeds ``apf``.

    Attributes
    ----------
    p_f : Largest failure probability met along each arc [-] (0 where no piece gave a state).
    fired_bits : Bit ``c`` set where criterion ``c`` fires in some state above ``apf`` along the arc.
    pieces : Pieces judged in all.
    """

    p_f: FloatArray
    fired_bits: npt.NDArray[np.uint32]
    pieces: int


def _lonlat(xyz: FloatArray) -> tuple[FloatArray, FloatArray]:
    x, y, z = xyz[..., 0], xyz[..., 1], xyz[..., 2]
    return np.degrees(np.arctan2(y, x)), np.degrees(np.arcsin(np.clip(z, -1.0, 1.0)))


def _frame(a: FloatArray, b: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Central angle ``omega`` [rad] of each arc and the unit tangent ``u`` at ``a`` towards ``b``: the arc is
    ``a cos(t) + u sin(t)`` for ``t`` in ``[0, omega]``."""
    d = a - b
    omega = 2.0 * np.arcsin(np.clip(np.sqrt(np.sum(d * d, axis=-1)) / 2.0, 0.0, 1.0))
    u = b - a * np.cos(omega)[:, None]
    norm = np.sqrt(np.sum(u * u, axis=-1))
    u = np.where(norm[:, None] > 0.0, u / np.where(norm > 0.0, norm, 1.0)[:, None], 0.0)
    return omega, u


def _candidates(
    lon0: FloatArray, lat0: FloatArray, lon1: FloatArray, lat1: FloatArray, omega: FloatArray, bounds: Boundaries
) -> tuple[npt.NDArray[np.bool_], FloatArray, FloatArray, FloatArray, FloatArray]:
    """Arcs that may meet a box, and each arc's longitude and (widened) latitude range [deg].

    Longitude is monotonic along a minor arc that does not pass a pole, so its range is its ends' (taken across
    the antimeridian when shorter); every point of an arc is within ``omega / 2`` of an end, which bounds its
    latitudes."""
    half = np.degrees(omega) / 2.0
    la_lo = np.minimum(lat0, lat1) - half
    la_hi = np.maximum(lat0, lat1) + half
    dl = (lon1 - lon0 + 180.0) % 360.0 - 180.0
    lo_lo = np.minimum(lon0, lon0 + dl)
    lo_hi = np.maximum(lon0, lon0 + dl)
    polar = (la_hi >= 89.0) | (la_lo <= -89.0)
    lo_lo = np.where(polar, -540.0, lo_lo)
    lo_hi = np.where(polar, 540.0, lo_hi)
    if bounds.boxes is None:
        return np.ones(lon0.shape, bool), lo_lo, lo_hi, la_lo, la_hi
    meet = np.zeros(lon0.shape, bool)
    for bx0, bx1, by0, by1 in bounds.boxes:
        lat_ok = (la_hi >= by0) & (la_lo <= by1)
        lon_ok = np.zeros(lon0.shape, bool)
        for shift in (-360.0, 0.0, 360.0):
            lon_ok |= (lo_hi >= bx0 + shift) & (lo_lo <= bx1 + shift)
        meet |= lat_ok & lon_ok
    return meet, lo_lo, lo_hi, la_lo, la_hi


def _lines_in(values: FloatArray, lo: FloatArray, hi: FloatArray, period: float | None) -> FloatArray:
    """Per arc, the lines of sorted ``values`` within ``[lo, hi]`` (NaN-padded to the widest arc)."""
    if period is not None:  # meridians: the lines one period either side too
        values = np.concatenate([values - period, values, values + period])
    i0 = np.searchsorted(values, lo, side="left")
    i1 = np.searchsorted(values, hi, side="right")
    count = i1 - i0
    width = int(count.max()) if count.size else 0
    if width == 0:
        return np.empty((lo.size, 0))
    j = i0[:, None] + np.arange(width)
    ok = j < i1[:, None]
    return np.where(ok, values[np.minimum(j, values.size - 1)], np.nan)


def split_fractions(a_xyz: FloatArray, b_xyz: FloatArray, bounds: Boundaries | None) -> FloatArray:
    """Fractions along each arc (shape ``(n, k)``, sorted, NaN-padded) where it crosses a boundary line or the
    equator, more than :data:`NUDGE` from its ends (a line through an end cuts nothing off).

    Parameters
    ----------
    a_xyz, b_xyz : Unit vectors of the arcs' ends, shape (n, 3).
    bounds : Where conditions change (None: nowhere but the equator).

    >>> a, b = geodesy.to_xyz([-46.0], [33.0]), geodesy.to_xyz([-44.0], [33.0])
    >>> bounds = Boundaries(np.array([-45.0]), np.array([]), None, False)
    >>> split_fractions(a, b, bounds).round(6).tolist()
    [[0.5]]
    """
    return _split_fractions(a_xyz, b_xyz, bounds, *_frame(a_xyz, b_xyz))


def _split_fractions(
    a_xyz: FloatArray, b_xyz: FloatArray, bounds: Boundaries | None, omega: FloatArray, u: FloatArray
) -> FloatArray:
    """:func:`split_fractions` with the arcs' :func:`_frame` known."""
    lon0, lat0 = _lonlat(a_xyz)
    lon1, lat1 = _lonlat(b_xyz)
    parts = []
    if bounds is not None:
        meet, lo_lo, lo_hi, la_lo, la_hi = _candidates(lon0, lat0, lon1, lat1, omega, bounds)
        lo_lo, lo_hi = np.where(meet, lo_lo, np.nan), np.where(meet, lo_hi, np.nan)
        la_lo, la_hi = np.where(meet, la_lo, np.nan), np.where(meet, la_hi, np.nan)
        merid = _lines_in(np.asarray(bounds.lon_deg, float), lo_lo, lo_hi, 360.0)
        paral = _lines_in(np.asarray(bounds.lat_deg, float), la_lo, la_hi, None)
        parts += [_meridian_crossings(a_xyz, u, omega, merid), _parallel_crossings(a_xyz, u, omega, paral)]
    parts.append(_parallel_crossings(a_xyz, u, omega, np.zeros((omega.size, 1))))
    s = np.concatenate(parts, axis=1)
    # a line through an arc's end is met there, but rounding puts the crossing a hair inside the arc (1e-14, or
    # 1e-7 where the arc grazes the line): a sliver piece sampled on the line itself, inside a closed patch box or
    # not by chance. Crossings within NUDGE of an end cut nothing off: the end piece is judged by its interior.
    with np.errstate(invalid="ignore"):
        s = np.sort(np.where((s > NUDGE) & (s < 1.0 - NUDGE), s, np.nan), axis=1)  # NaN last
    width = int(np.isfinite(s).sum(axis=1).max()) if s.size else 0
    return s[:, :width]


def _meridian_crossings(a: FloatArray, u: FloatArray, omega: FloatArray, lon_deg: FloatArray) -> FloatArray:
    """Fractions where arcs cross the meridians ``lon_deg`` (n, k) [deg] (NaN: none): the arc meets the meridian's
    plane, normal ``(-sin L, cos L, 0)``, at ``tan t = -(a.n) / (u.n)``, once in ``[0, pi)``."""
    lon = np.radians(lon_deg)
    sin_lon, cos_lon = np.sin(lon), np.cos(lon)
    nx, ny = -sin_lon, cos_lon
    an = a[:, 0:1] * nx + a[:, 1:2] * ny
    un = u[:, 0:1] * nx + u[:, 1:2] * ny
    t = np.arctan2(-an, un) % np.pi
    om = omega[:, None]
    # the crossing must be on the meridian's half, not its antimeridian
    cos_t, sin_t = np.cos(t), np.sin(t)
    px = a[:, 0:1] * cos_t + u[:, 0:1] * sin_t
    py = a[:, 1:2] * cos_t + u[:, 1:2] * sin_t
    same = px * cos_lon + py * sin_lon > 0.0
    with np.errstate(invalid="ignore", divide="ignore"):
        f = t / om
    return np.where((t > 0.0) & (t < om) & same & np.isfinite(lon_deg), f, np.nan)


def _parallel_crossings(a: FloatArray, u: FloatArray, omega: FloatArray, lat_deg: FloatArray) -> FloatArray:
    """Fractions where arcs cross the parallels ``lat_deg`` (n, k) [deg]: ``z(t) = r cos(t - phi) = sin(lat)``,
    two solutions at most (shape (n, 2k), NaN: none)."""
    r = np.hypot(a[:, 2], u[:, 2])[:, None]
    phi = np.arctan2(u[:, 2], a[:, 2])[:, None]
    s = np.sin(np.radians(lat_deg))
    with np.errstate(invalid="ignore", divide="ignore"):
        d = np.arccos(np.clip(s / r, -1.0, 1.0))
        ok = np.abs(s) <= r
        om = omega[:, None]
        out = []
        for t in ((phi - d) % (2.0 * np.pi), (phi + d) % (2.0 * np.pi)):
            out.append(np.where(ok & (t > 0.0) & (t < om), t / om, np.nan))
    return np.concatenate(out, axis=1)


def _pieces(fractions: FloatArray) -> tuple[npt.NDArray[np.intp], FloatArray, FloatArray]:
    """Arc index, start and end fraction of each piece (arc-major order) from sorted split fractions."""
    n = fractions.shape[0]
    s = np.concatenate([np.zeros((n, 1)), fractions, np.ones((n, 1))], axis=1)
    s = np.sort(s, axis=1)  # NaN last
    s0, s1 = s[:, :-1], s[:, 1:]
    with np.errstate(invalid="ignore"):
        ok = s1 > s0
    arc = np.broadcast_to(np.arange(n)[:, None], s0.shape)[ok]
    return arc, s0[ok], s1[ok]


def _points(
    a: FloatArray, u: FloatArray, omega: FloatArray, arc: npt.NDArray[np.intp], f: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Lon, lat [deg] and course [deg] at fractions ``f`` (shape (m, r)) of arcs ``arc`` (m,).

    Component by component (numpy's arithmetic over a last axis of 3 costs more than the numbers), each the same
    operations on the same values as the vector form ``p = a cos(t) + u sin(t)``, ``v = u cos(t) - a sin(t)``."""
    t = f * omega[arc][:, None]
    c, s = np.cos(t), np.sin(t)
    aa, uu = a[arc], u[arc]
    ax, ay, az = (aa[:, i, None] for i in range(3))
    ux, uy, uz = (uu[:, i, None] for i in range(3))
    x, y, z = ax * c + ux * s, ay * c + uy * s, az * c + uz * s
    vx, vy, vz = ux * c - ax * s, uy * c - ay * s, uz * c - az * s  # direction of travel
    lon, lat = np.degrees(np.arctan2(y, x)), np.degrees(np.arcsin(np.clip(z, -1.0, 1.0)))
    lr = np.radians(lon)
    sin_lr, cos_lr = np.sin(lr), np.cos(lr)
    east = -sin_lr * vx + cos_lr * vy
    north = vz * np.sqrt(x * x + y * y) - z * (cos_lr * vx + sin_lr * vy)
    return lon, lat, geodesy.bearing_deg(east, north)


@dataclass(frozen=True)
class _Judge:
    """What the pieces are judged with (the cost function's settings)."""

    departure: np.datetime64
    weather: WeatherSource
    polar: Polar
    failure: FailureModel
    apf: float
    beyond: str
    speed_factor: Any  # a callable of Hs giving the wave speed loss factor, or None


def _quantities(judge: _Judge, lon: FloatArray, lat: FloatArray, course: FloatArray, t_h: FloatArray | None):  # type: ignore[no-untyped-def]
    """The failure model's quantities at points; relative angles unfolded (``field - heading`` in (-180, 180])."""
    w = judge.weather
    if w.steady or t_h is None:
        cond: Conditions = w.sample(lon, lat, judge.departure)
    else:
        cond = _sample_fields(w, lon, lat, hours_after(judge.departure, t_h), judge.failure)
    heading = course
    if cond.has_current:
        factor = 1.0 if judge.speed_factor is None else judge.speed_factor(cond.hs_m)
        crab = steer(cond, course, judge.polar, beyond=judge.beyond, speed_factor=factor)
        heading = np.where(np.isfinite(crab.heading_deg), crab.heading_deg, course)
    out: dict[str, tuple[FloatArray, bool]] = {}
    for name in judge.failure.quantities:
        field, relative = QUANTITY_FIELDS[name]
        value = np.asarray(getattr(cond, field), dtype=float)
        if relative:
            value = (value - heading + 180.0) % 360.0 - 180.0
        out[name] = (value, bool(relative))
    return out


def _sample_fields(
    weather: WeatherSource, lon: FloatArray, lat: FloatArray, time: npt.NDArray[np.datetime64], failure: FailureModel
) -> Conditions:
    """``weather.sample(lon, lat, time)``, with only the fields the failure model judges (and the current) where
    the source can sample some fields alone (``sample_at``: the same numbers, fewer fields interpolated); every
    field where there is a current (the crab heading needs the wind)."""
    fields = {QUANTITY_FIELDS[name][0] for name in failure.quantities} | {"current_u_ms", "current_v_ms"}
    cond = weather.sample_at(weather.prepare(lon, lat), time, fields=fields)
    return weather.sample(lon, lat, time) if cond.has_current else cond


def _ranges(values: FloatArray, relative: bool) -> tuple[FloatArray, FloatArray]:
    """Range of a quantity over each piece from its values at the piece's points (last axis; NaN ignored, NaN where
    all are): a relative angle is unwrapped about the middle point, then folded into [0, 180]."""
    if not relative:
        return _last_axis(np.fmin, values), _last_axis(np.fmax, values)
    ref = values[..., 1:2]
    unwrapped = ref + (values - ref + 180.0) % 360.0 - 180.0
    return _fold_range(_last_axis(np.fmin, unwrapped), _last_axis(np.fmax, unwrapped))


def _fold_range(lo: FloatArray, hi: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Range in [0, 180] of an angle folded (:func:`~pyroute_rel.geodesy.fold_angle_deg`) as it sweeps
    ``[lo, hi]`` [deg] (``hi - lo < 360``)."""
    m = lo % 360.0  # in [0, 360)
    h = m + (hi - lo)
    fm, fh = geodesy.fold_angle_deg(m), geodesy.fold_angle_deg(h)
    fmin, fmax = np.minimum(fm, fh), np.maximum(fm, fh)
    fmax = np.where(((m <= 180.0) & (h >= 180.0)) | ((m <= 540.0) & (h >= 540.0)), 180.0, fmax)
    fmin = np.where((m == 0.0) | ((m <= 360.0) & (h >= 360.0)), 0.0, fmin)
    return fmin, fmax


def _vertex(values: FloatArray, r: FloatArray) -> FloatArray:
    """Where the parabola through three values at positions ``r`` (3,) has its extremum (clipped into the
    positions' span; the middle where it is flat or NaN)."""
    y0, y1, y2 = values[..., 0], values[..., 1], values[..., 2]
    r0, r1, r2 = r
    d = (r0 - r1) * (r0 - r2) * (r1 - r2)
    with np.errstate(invalid="ignore", divide="ignore"):
        A = (r2 * (y1 - y0) + r1 * (y0 - y2) + r0 * (y2 - y1)) / d
        B = (r2 * r2 * (y0 - y1) + r1 * r1 * (y2 - y0) + r0 * r0 * (y1 - y2)) / d
        v = -B / (2.0 * A)
    return np.where(np.isfinite(v), np.clip(v, r0, r2), r1)


def _box_max(
    model: FailureModel, ranges: dict[str, tuple[FloatArray, FloatArray]], apf: float
) -> tuple[FloatArray, npt.NDArray[np.uint32]]:
    """Largest table entry whose states the quantity ranges reach, per piece, and the criteria fired in reached
    entries above ``apf`` (see the module notes)."""
    reach = []
    for c in model.criteria:
        lo, hi = ranges[c.quantity]
        side: Literal["left", "right"] = "right" if c.closed == "left" else "left"
        edges = np.asarray(c.edges, dtype=float)
        b_lo, b_hi = np.searchsorted(edges, lo, side=side), np.searchsorted(edges, hi, side=side)
        known = ~np.isnan(lo)
        r = np.zeros(lo.shape + (len(c.states) + 1,), dtype=bool)
        for b, state in enumerate(c.bin_states):
            r[..., c.states.index(state)] |= known & (b_lo <= b) & (b <= b_hi)
        if c.if_missing != "nan":
            fill = len(c.states) if c.if_missing == "prior" else c.states.index(c.if_missing)
            r[..., fill] |= ~known
        reach.append(r)
    shape = tuple(len(c.states) + 1 for c in model.criteria)
    p_flat, bits_flat = model.p_flat, model.fired_bits_flat
    best = np.full(reach[0].shape[:-1], -np.inf)
    bits = np.zeros(best.shape, dtype=np.uint32)
    for flat, idx in enumerate(itertools.product(*(range(n) for n in shape))):
        ok = reach[0][..., idx[0]]
        for r, i in zip(reach[1:], idx[1:], strict=True):  # pairwise: no stacked copy of the masks
            ok = ok & r[..., i]
        p = float(p_flat[flat])
        np.maximum(best, np.where(ok, p, -np.inf), out=best)
        if p > apf:
            bits |= np.where(ok, bits_flat[flat], 0).astype(np.uint32)
    return best, bits


def _last_axis(op: Any, a: FloatArray) -> FloatArray:
    """``op`` (``np.minimum``, ``np.maximum``) reduced over a short last axis one slice at a time (numpy reduces a
    short last axis slowly)."""
    out = np.array(a[..., 0], dtype=float)
    for k in range(1, a.shape[-1]):
        op(out, a[..., k], out=out)
    return out


def needs_pieces(
    lon_deg: FloatArray,
    lat_deg: FloatArray,
    course_deg: FloatArray,
    seg_nm: FloatArray,
    t0_h: FloatArray,
    time_h: FloatArray,
    *,
    weather: WeatherSource,
    failure: FailureModel,
    departure: np.datetime64,
    cond: Conditions | None = None,
) -> npt.NDArray[np.bool_] | None:
    """Which arcs the cost function's samples cannot judge alone (None: any of them may need it), from the samples.

    Every point of an arc is within half a sub-segment of a sample, and the course along a great circle turns by at most
    ``|tan(lat)| / R`` per unit length (an arc that may come within a degree of a pole is always judged). With patches
    (steady, no current) an arc needs its pieces judged when it may reach a patch edge (a turn either way too: the
    samples' longitudes and the patch's may be on either side of the antimeridian), or when its course may carry a
    heading-dependent quantity across a bin edge of its criterion; elsewhere the samples' conditions hold all along it
    and every criterion stays in one bin. With a gridded source, when some quantity at some sample is closer to a bin
    edge than the field can change within that distance and time (:meth:`~pyroute_rel.weather.GriddedWeather.variation`;
    the arc's whole sailing time bounds the time), plus the course's turn for a heading-dependent one. Other sources,
    and currents (the heading is then not the course): None.

    Parameters
    ----------
    lon_deg, lat_deg, course_deg : The samples (shape (..., samples)) [deg].
    seg_nm : Sub-segment lengths [nm], broadcast to (..., 1).
    t0_h, time_h : Departure [h after ``departure``] and sailing time [h] of each arc (shape (...)).
    weather, failure, departure : As for :func:`arc_extremes`.
    cond : The weather at the samples, if known (else sampled again).
    """
    bounds = weather.boundaries
    if bounds is None:
        return None
    half_deg = np.degrees(seg_nm[..., 0] * 0.5 * KM_PER_NM / geodesy.EARTH_RADIUS_KM) * 1.001 + 1e-9
    la_lo = _last_axis(np.minimum, lat_deg) - half_deg
    la_hi = _last_axis(np.maximum, lat_deg) + half_deg
    # the block's highest latitude [deg] (a bound for every arc: the course's turn, degrees of longitude per km)
    big = min(max(float(np.max(np.abs(la_lo), initial=0.0)), float(np.max(np.abs(la_hi), initial=0.0))), 89.0)
    # every relative angle along the arc is within `margin` of its value at the first sample plus its field's
    # change (the fold is 1-Lipschitz; the course is monotonic along the arc)
    turn = half_deg * (math.tan(math.radians(big)) * 1.01) + 1e-9
    c0 = course_deg[..., 0]
    margin = 2.0 * turn
    for k in range(1, course_deg.shape[-1]):
        margin = np.maximum(margin, np.abs((course_deg[..., k] - c0 + 180.0) % 360.0 - 180.0) + 2.0 * turn)
    if bounds.continuous:
        variation = weather.variation
        if _unbounded(weather, failure, variation):
            return None
        dt = np.zeros(()) if weather.steady else np.where(np.isfinite(time_h), time_h, 0.0)  # forbidden: no time
        span = (half_deg / math.cos(math.radians(big)), half_deg, dt)
        if cond is None or cond.tws_kn.shape != lon_deg.shape:
            cond = _sample_cond(weather, lon_deg, lat_deg, t0_h, time_h, departure)
        if cond is None or cond.has_current:
            return None
        near = _near_bin_edges(cond, course_deg, margin, failure, variation, span)
        return None if near is None else near | (la_hi > 89.0) | (la_lo < -89.0)  # (near a pole: judged whole)
    if bounds.boxes is None or not weather.steady:
        return None
    near = _near_edges(lon_deg, la_lo, la_hi, half_deg / math.cos(math.radians(big)), bounds.boxes)
    relative = [c for c in failure.criteria if QUANTITY_FIELDS[c.quantity][1]]
    if not relative:
        return near
    if cond is None or cond.tws_kn.shape != lon_deg.shape:
        cond = weather.sample(lon_deg[..., :1], lat_deg[..., :1], departure)  # uniform away from the edges
    if cond.has_current:
        return None
    for c in relative:
        q0 = geodesy.fold_angle_deg(np.asarray(getattr(cond, QUANTITY_FIELDS[c.quantity][0]), float)[..., 0] - c0)
        for e in c.edges:
            near |= np.abs(q0 - e) <= margin
    return near


def _unbounded(weather: WeatherSource, failure: FailureModel, variation: Any) -> bool:
    """True when a criterion's field has no variation bound (:func:`needs_pieces` would find that after sampling
    the weather; known before it when the weather has no current, which returns None first), the heading-dependent
    ones asked first (a direction's bound is the one that tends to be missing, and says so fast)."""
    if "current_u_ms" in weather.fields:
        return False
    names = sorted({QUANTITY_FIELDS[c.quantity] for c in failure.criteria}, key=lambda f: (not f[1], f[0]))
    return any(variation(name) is None for name, _ in names)


def _near_edges(
    lon_deg: FloatArray, la_lo: FloatArray, la_hi: FloatArray, lon_margin: FloatArray, boxes: FloatArray
) -> npt.NDArray[np.bool_]:
    """Arcs whose bounding box (latitudes ``[la_lo, la_hi]``, the samples' longitudes widened by ``lon_margin``)
    meets an edge of a box (rows ``lon_min, lon_max, lat_min, lat_max`` [deg]); only the arcs within the boxes'
    union are tested edge by edge."""
    lo_lo = _last_axis(np.minimum, lon_deg) - lon_margin
    lo_hi = _last_axis(np.maximum, lon_deg) + lon_margin
    near = (lo_hi - lo_lo) > 180.0  # across the antimeridian: judge it whole
    near |= (la_hi > 89.0) | (la_lo < -89.0)  # near a pole (the course turns without bound there): judge it whole
    union = (la_hi >= boxes[:, 2].min()) & (la_lo <= boxes[:, 3].max())
    pick = np.flatnonzero(union.reshape(-1))
    if not pick.size:
        return near
    x0, x1 = lo_lo.reshape(-1)[pick], lo_hi.reshape(-1)[pick]
    y0, y1 = la_lo.reshape(-1)[pick], la_hi.reshape(-1)[pick]
    hit = np.zeros(pick.size, dtype=bool)
    for bx0_, bx1_, by0, by1 in boxes:
        lat_in = (y1 >= by0) & (y0 <= by1)
        for shift in (-360.0, 0.0, 360.0):  # a patch's edges a turn either way (the samples' longitudes may be)
            bx0, bx1 = bx0_ + shift, bx1_ + shift
            lon_in = (x1 >= bx0) & (x0 <= bx1)
            for x in (bx0, bx1):
                hit |= lat_in & (x0 <= x) & (x1 >= x)
            for y in (by0, by1):
                hit |= lon_in & (y0 <= y) & (y1 >= y)
    flat = near.reshape(-1).copy()
    flat[pick] |= hit
    return flat.reshape(near.shape)


def _sample_cond(
    weather: WeatherSource,
    lon_deg: FloatArray,
    lat_deg: FloatArray,
    t0_h: FloatArray,
    time_h: FloatArray,
    departure: np.datetime64,
) -> Conditions | None:
    """The weather at the samples (at the arc's departure plus their share of its time; None with a current)."""
    if weather.steady:
        cond = weather.sample(lon_deg, lat_deg, departure)
    else:
        n = lon_deg.shape[-1]
        frac = (np.arange(n) + 0.5) / n
        dt = np.where(np.isfinite(time_h), time_h, 0.0)
        cond = weather.sample(lon_deg, lat_deg, hours_after(departure, t0_h[..., None] + frac * dt[..., None]))
    return None if cond.has_current else cond


def _near_bin_edges(
    cond: Conditions,
    course_deg: FloatArray,
    margin: FloatArray,
    failure: FailureModel,
    variation: Any,
    span: tuple[Any, Any, Any],
) -> npt.NDArray[np.bool_] | None:
    """Arcs with a quantity at a sample within its possible change (``variation(field)`` over ``span``: longitude,
    latitude [deg] and time [h] differences; plus ``margin`` [deg] for a heading-dependent one) of a bin edge."""
    near = np.zeros(course_deg.shape[:-1], dtype=bool)
    for c in failure.criteria:
        field, relative = QUANTITY_FIELDS[c.quantity]
        v = variation(field)
        if v is None:
            return None
        change = v.fixed + v.per_lon * span[0] + v.per_lat * span[1] + v.per_h * span[2]
        value = np.asarray(getattr(cond, field), dtype=float)
        if relative:
            value = geodesy.fold_angle_deg(value - course_deg)
            change = change + margin
        for e in c.edges:
            for k in range(course_deg.shape[-1]):
                near |= np.abs(value[..., k] - e) <= change
    return near


@dataclass(frozen=True)
class ArcPieces:
    """Arcs cut into pieces where conditions can change (:func:`arc_pieces`), and each piece's ends (nudged inside)
    and middle: everything :func:`arc_extremes` needs that does not depend on the weather's values or the times, so
    that arcs judged in many weathers on one grid (ensemble members) are cut once.

    Attributes
    ----------
    a_xyz, u_xyz : Unit vector of each arc's start and unit tangent there towards its end, shape (n, 3).
    omega : Central angle of each arc [rad] (n,).
    arc, s0, s1 : Each piece's arc, start and end fraction along it (arc-major order).
    lon_deg, lat_deg, course_deg : Position and course [deg] at the piece's ends (nudged inside by
        :data:`NUDGE`) and middle, shape (pieces, 3).
    continuous : Whether the fields are continuous (no patches): the quantities' parabolas are sampled too.
    """

    a_xyz: FloatArray
    u_xyz: FloatArray
    omega: FloatArray
    arc: npt.NDArray[np.intp]
    s0: FloatArray
    s1: FloatArray
    lon_deg: FloatArray
    lat_deg: FloatArray
    course_deg: FloatArray
    continuous: bool

    def take(self, arcs: npt.ArrayLike) -> ArcPieces:
        """The pieces of arcs ``arcs`` (indices, in that order, repeats allowed), as if those arcs were cut alone."""
        idx = np.asarray(arcs, dtype=np.intp).reshape(-1)
        counts = np.bincount(self.arc, minlength=self.omega.size)
        starts = np.cumsum(counts) - counts
        c = counts[idx]
        first = np.cumsum(c) - c
        pick = np.repeat(starts[idx] - first, c) + np.arange(int(c.sum()), dtype=np.intp)
        return ArcPieces(
            a_xyz=self.a_xyz[idx],
            u_xyz=self.u_xyz[idx],
            omega=self.omega[idx],
            arc=np.repeat(np.arange(idx.size, dtype=np.intp), c),
            s0=self.s0[pick],
            s1=self.s1[pick],
            lon_deg=self.lon_deg[pick],
            lat_deg=self.lat_deg[pick],
            course_deg=self.course_deg[pick],
            continuous=self.continuous,
        )


#: Fractions of a piece where :func:`arc_extremes` samples it: both ends nudged inside, and the middle.
_FRACTIONS = np.array([NUDGE, 0.5, 1.0 - NUDGE])


def arc_pieces(a_xyz: FloatArray, b_xyz: FloatArray, bounds: Boundaries | None) -> ArcPieces:
    """Great-circle arcs cut where they cross ``bounds`` (a weather's :class:`Boundaries`; None: the equator only)
    and the points at which :func:`arc_extremes` samples each piece first (see the module notes).

    Parameters
    ----------
    a_xyz, b_xyz : Unit vectors of the arcs' ends, shape (n, 3).
    bounds : Where conditions can change.
    """
    omega, u = _frame(a_xyz, b_xyz)
    arc, s0, s1 = _pieces(_split_fractions(a_xyz, b_xyz, bounds, omega, u))
    f = s0[:, None] + (s1 - s0)[:, None] * _FRACTIONS
    lon, lat, course = _points(a_xyz, u, omega, arc, f)
    continuous = bounds is None or bounds.continuous
    return ArcPieces(a_xyz, u, omega, arc, s0, s1, lon, lat, course, continuous)


def arc_extremes(
    a_xyz: FloatArray,
    b_xyz: FloatArray,
    t0_h: FloatArray,
    time_h: FloatArray,
    *,
    departure: np.datetime64,
    weather: WeatherSource,
    polar: Polar,
    failure: FailureModel,
    apf: float = 1.0,
    beyond: str = "clamp",
    speed_factor: Any = None,
    pieces: ArcPieces | None = None,
    marks_h: FloatArray | None = None,
) -> ArcExtremes:
    """The largest failure probability met anywhere along great-circle arcs (see the module notes).

    Parameters
    ----------
    a_xyz, b_xyz : Unit vectors of the arcs' ends, shape (n, 3).
    t0_h : Departure of each arc [h after ``departure``] (n,).
    time_h : Each arc's sailing time [h] (n,): with time-varying weather a point at fraction ``f`` is judged at
        ``t0_h + f * time_h`` (at ``t0_h`` where the time is not finite).
    departure, weather, polar, failure, apf, beyond : As for :func:`~pyroute_rel.routing.cost.geometry_costs`.
    speed_factor : Wave speed loss factor as a function of Hs (for the crab heading in a current), or None.
    pieces : The arcs' pieces (:func:`arc_pieces` with the weather's boundaries, e.g. cut once for many weathers
        on one grid, then :meth:`ArcPieces.take`, then :func:`cut_in_time` with ``marks_h``), or None: cut here.
        The numbers are the same either way. A weather whose answers depend on the query's row (first axis), such as
        one answering each piece in its own ensemble member, is queried with one row per piece, and gives
        ``take_rows(rows)``: the same weather for queries whose rows are those pieces.
    marks_h : The time the craft reaches each of the arc's ``S`` equal sub-segments' ends [h after ``departure``],
        shape (n, S + 1) (:attr:`~pyroute_rel.routing.cost.ArcCosts.marks_h`, the march of
        :mod:`pyroute_rel.boat.march`), or None: ``t0_h + f * time_h``. With marks the time along the arc is linear
        between them, and every piece is also cut where the craft crosses one of the weather's
        :attr:`~pyroute_rel.weather.WeatherSource.time_steps`, so that a piece lies within one step of the file in time
        as in one cell in space.
    """
    judge = _Judge(departure, weather, polar, failure, float(apf), beyond, speed_factor)
    timing = None if weather.steady else _Timing(np.asarray(t0_h, float), np.asarray(time_h, float), marks_h)
    if pieces is None:
        pieces = arc_pieces(a_xyz, b_xyz, weather.boundaries)
        if timing is not None and marks_h is not None:
            pieces = cut_in_time(pieces, marks_h, weather.time_steps, departure)
    arc, s0, s1 = pieces.arc, pieces.s0, pieces.s1
    r = _FRACTIONS
    t = None if timing is None else timing.at(arc, s0[:, None] + (s1 - s0)[:, None] * r)
    q = _quantities(judge, pieces.lon_deg, pieces.lat_deg, pieces.course_deg, t)
    if pieces.continuous:  # the extremum of each quantity's parabola through the three points
        rv = np.stack([_vertex(v, r) for v, _ in q.values()], axis=-1)
        qv = _at_vertices(judge, pieces, timing, rv, q)
        q = {k: (np.concatenate([v, qv[k]], axis=-1), rel) for k, (v, rel) in q.items()}
    ranges = {k: _ranges(v, rel) for k, (v, rel) in q.items()}
    best, bits = _box_max(failure, ranges, judge.apf)
    n = pieces.omega.size
    p_arc = np.zeros(n)
    bits_arc = np.zeros(n, dtype=np.uint32)
    if arc.size:
        starts = np.flatnonzero(np.r_[True, arc[1:] != arc[:-1]])
        p_arc[arc[starts]] = np.maximum(np.maximum.reduceat(best, starts), 0.0)
        bits_arc[arc[starts]] = np.bitwise_or.reduceat(bits, starts)
    return ArcExtremes(p_f=p_arc, fired_bits=bits_arc, pieces=int(arc.size))


def _at_vertices(
    judge: _Judge,
    pieces: ArcPieces,
    timing: _Timing | None,
    rv: FloatArray,
    q: dict[str, tuple[FloatArray, bool]],
) -> dict[str, FloatArray]:
    """Every quantity at each quantity's vertex ``rv`` (pieces, quantities) [fraction of the piece]: sampled where
    the vertex is a new point, copied from ``q`` (the quantities at :data:`_FRACTIONS`) where it is one of those
    (a parabola's extremum clipped to an end, or the middle where it is flat): the same point, the same numbers."""
    s0, s1, arc = pieces.s0[:, None], pieces.s1[:, None], pieces.arc
    col = np.full(rv.shape, -1, dtype=np.intp)
    for c, x in enumerate(_FRACTIONS):
        col[rv == x] = c
    new = col < 0
    out = {k: np.take_along_axis(v, np.maximum(col, 0), axis=-1) for k, (v, _) in q.items()}
    if new.any():
        at = np.broadcast_to(arc[:, None], rv.shape)[new]
        fv = (s0 + (s1 - s0) * rv)[new][:, None]
        tv = None if timing is None else timing.at(at, fv)
        lon_v, lat_v, course_v = _points(pieces.a_xyz, pieces.u_xyz, pieces.omega, at, fv)
        take_rows = judge.weather.take_rows  # a weather answering each piece from its own source
        if take_rows is not None:
            judge = replace(judge, weather=take_rows(np.broadcast_to(np.arange(rv.shape[0])[:, None], rv.shape)[new]))
        qv = _quantities(judge, lon_v, lat_v, course_v, tv)
        for k, v in out.items():
            v[new] = qv[k][0][:, 0]
    return out


@dataclass(frozen=True)
class _Timing:
    """When the craft is at each fraction of each arc: its departure ``t0_h`` plus that share of its time ``time_h``
    [h], or, with ``marks_h`` (n, S + 1), linear between the times it reaches the ends of its S equal sub-segments."""

    t0_h: FloatArray
    time_h: FloatArray
    marks_h: FloatArray | None

    def at(self, arc: npt.NDArray[np.intp], f: FloatArray) -> FloatArray:
        """Time [h after departure] at fractions ``f`` (m, r) of arcs ``arc`` (m,)."""
        if self.marks_h is not None:
            return time_along(self.marks_h[arc], f)
        t0 = self.t0_h[arc][:, None]
        dt = self.time_h[arc][:, None]
        return np.where(np.isfinite(dt), t0 + f * dt, t0)


def time_fractions(
    marks_h: FloatArray, steps: npt.NDArray[np.datetime64] | None, departure: np.datetime64
) -> tuple[npt.NDArray[np.intp], FloatArray]:
    """Where the craft crosses the weather's time steps along each arc: the arcs (increasing) and fractions along
    them (strictly inside, by more than :data:`NUDGE`), from the times ``marks_h`` (n, S + 1) [h after
    ``departure``] it reaches its S equal sub-segments' ends (time linear between them)."""
    n, samples = marks_h.shape[0], marks_h.shape[1] - 1
    if steps is None or not len(steps) or not n:
        return np.zeros(0, dtype=np.intp), np.zeros(0)
    steps_h = step_hours(steps, departure)
    assert steps_h is not None  # (steps are given)
    marks = np.where(np.isfinite(marks_h), marks_h, -np.inf)
    j = np.searchsorted(steps_h, marks, side="right")  # the first step after each mark
    counts = np.maximum(j[:, 1:] - j[:, :-1], 0)  # steps in (mark k, mark k + 1], per sub-segment
    total = int(counts.sum())
    if not total:
        return np.zeros(0, dtype=np.intp), np.zeros(0)
    flat = counts.reshape(-1)
    owner = np.repeat(np.arange(flat.size), flat)
    first = np.cumsum(flat) - flat
    step = j[:, :-1].reshape(-1)[owner] + (np.arange(total) - first[owner])
    arc, k = np.divmod(owner, samples)
    t_lo, t_hi = marks[arc, k], marks[arc, k + 1]
    f = (k + (steps_h[step] - t_lo) / (t_hi - t_lo)) / samples
    keep = (f > NUDGE) & (f < 1.0 - NUDGE)
    return arc[keep], f[keep]


def cut_in_time(
    pieces: ArcPieces, marks_h: FloatArray, steps: npt.NDArray[np.datetime64] | None, departure: np.datetime64
) -> ArcPieces:
    """``pieces`` cut again where the craft crosses a time step of the weather (:func:`time_fractions`), from the
    times ``marks_h`` (n, S + 1) [h after ``departure``] the craft reaches the arcs' sub-segment ends."""
    arc_t, f_t = time_fractions(marks_h, steps, departure)
    if not arc_t.size:
        return pieces
    n = pieces.omega.size
    ends = np.unique(pieces.arc)
    arc_all = np.concatenate([pieces.arc, arc_t, ends])
    f_all = np.concatenate([pieces.s0, f_t, np.ones(ends.size)])
    order = np.lexsort((f_all, arc_all))
    arc_all, f_all = arc_all[order], f_all[order]
    same = (arc_all[1:] == arc_all[:-1]) & (f_all[1:] > f_all[:-1])
    arc, s0, s1 = arc_all[:-1][same], f_all[:-1][same], f_all[1:][same]
    f = s0[:, None] + (s1 - s0)[:, None] * _FRACTIONS
    lon, lat, course = _points(pieces.a_xyz, pieces.u_xyz, pieces.omega, arc, f)
    assert arc.size >= pieces.arc.size and (n == 0 or arc.max() < n)
    return replace(pieces, arc=arc, s0=s0, s1=s1, lon_deg=lon, lat_deg=lat, course_deg=course)
