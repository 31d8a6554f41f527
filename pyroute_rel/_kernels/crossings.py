"""Compiled twin of :mod:`pyroute_rel.reliability.crossings` for patches: the largest p_f along one great-circle arc in
uniform weather with boxes (:class:`~pyroute_rel.weather.UniformWeather`), and the cost function's failure judgement at
an arc's samples, for the DP's compiled rank step (:mod:`pyroute_rel._kernels.dp`).

:func:`arc_p_f` does for one arc what :func:`~pyroute_rel.reliability.crossings.arc_extremes` does for many in steady
weather without a current, step for step and in the same arithmetic: the arc cut where it crosses the patches' meridians
and parallels (only when its bounding box meets a patch, the lines within its ranges) and the equator, crossings within
:data:`~pyroute_rel.reliability.crossings.NUDGE` of an end dropped; each piece sampled at its ends nudged inside and its
middle; each quantity's range over the piece (a heading-dependent one unwrapped about the middle, then folded into [0,
180]); every table entry whose states those ranges reach a candidate, the largest its p_f. :func:`needs_judging` is
:func:`~pyroute_rel.reliability.crossings.needs_pieces`' test for patches for one arc, with the arc's own latitude bound
where the numpy code takes its block's (a tighter bound: both are sound, so an arc it passes over keeps its samples'
verdict, which is then exact).

The weather's fields are given per criterion (:class:`BoxFields`): the value outside the patches and, per patch,
the value it sets (NaN: it leaves that field as it is), later patches winning where they overlap, a patch closed, as
:meth:`~pyroute_rel.weather.UniformWeather.sample` gives them. numba is imported only by problems this path serves.

Numpy twin: :func:`pyroute_rel.reliability.crossings.arc_extremes` and
:func:`~pyroute_rel.reliability.crossings.needs_pieces`; pinned by
``tests/test_dp_compiled_failure.py::test_arc_p_f_equals_arc_extremes`` and
``::test_arcs_passed_over_are_judged_by_their_samples``.
"""

from __future__ import annotations

import hashlib
import math
from typing import Any, NamedTuple

import numba
import numpy as np
import numpy.typing as npt

from pyroute_rel._kernels.cost import evidence_point
from pyroute_rel._kernels.polar import fmax, fmin
from pyroute_rel.reliability.crossings import NUDGE
from pyroute_rel.reliability.failure import QUANTITY_FIELDS, FailureModel
from pyroute_rel.units import EARTH_RADIUS_KM, KM_PER_NM

__all__ = ["BoxFields", "box_fields", "arc_p_f", "needs_judging", "sample_evidence"]

FloatArray = npt.NDArray[np.float64]


class BoxFields(NamedTuple):
    """What the compiled judgement needs of a failure model and of uniform weather with patches (:func:`box_fields`).

    One row per criterion of the model, in order: its field's value outside the patches and per patch, whether it is
    taken relative to the heading, its classifier (bin edges, the state of each bin, the state a NaN puts it in) and
    its stride in the flat table."""

    #: Field of each criterion outside the patches, shape (criteria,).
    base: FloatArray
    #: Every patch as ``(lon_min, lon_max, lat_min, lat_max)`` [deg], shape (patches, 4).
    boxes: FloatArray
    #: The value each patch sets for each criterion's field (NaN: none), shape (patches, criteria).
    values: FloatArray
    #: The patches' meridians and parallels [deg], sorted (the weather's :class:`~pyroute_rel.weather.Boundaries`).
    lon_lines: FloatArray
    lat_lines: FloatArray
    #: Whether each criterion's quantity is an angle to the heading.
    relative: npt.NDArray[np.bool_]
    #: Bin edges per criterion (NaN-padded), their number, whether a value on an edge goes to the upper bin.
    edges: FloatArray
    n_edges: npt.NDArray[np.intp]
    right: npt.NDArray[np.bool_]
    #: State of each bin (padded with -1), the state a NaN is put in (-1: none, the evidence is unknown), the number
    #: of slots of each axis (states + "unobserved") and each axis's stride in the flat table.
    bin_state: npt.NDArray[np.intp]
    fill_state: npt.NDArray[np.intp]
    n_slots: npt.NDArray[np.intp]
    stride: npt.NDArray[np.intp]
    #: The model's flat table, its entries above apf and the criteria each fires
    # : (:attr:`~pyroute_rel.reliability.failure.FailureModel.p_flat`,
    # :attr:`~pyroute_rel.reliability.failure.FailureModel.fired_bits_flat`).
    p_flat: FloatArray
    over: npt.NDArray[np.bool_]
    bits: npt.NDArray[np.uint32]
    #: The acceptable probability and the table's largest entry (an arc whose samples met it cannot meet more).
    apf: float
    p_max: float
    # : The flat-index classifier of :meth:`~pyroute_rel.reliability.failure.FailureModel.evidence_rules` (contributions
    # per
    #: bin, the contribution of a NaN), for the samples (:func:`sample_evidence`).
    contrib: npt.NDArray[np.intp]
    fill: npt.NDArray[np.intp]

    def key(self) -> str:
        """A digest of every field (name, dtype, shape and bytes, in order): equal for fields that judge every arc
        alike, bit for bit (the key of what is kept of a judgement, :class:`~pyroute_rel._kernels.dp.Judged`)."""
        digest = hashlib.blake2b(digest_size=16)
        for name, value in zip(self._fields, self, strict=True):
            a = np.ascontiguousarray(value)
            digest.update(f"{name}:{a.dtype.str}:{a.shape}:".encode())
            digest.update(a.tobytes())
        return digest.hexdigest()


def box_fields(weather: Any, model: FailureModel, apf: float) -> BoxFields | None:
    """:class:`BoxFields` of uniform weather with patches and a failure model at ``apf`` (None where the weather has
    no :meth:`~pyroute_rel.weather.UniformWeather.boundaries` or a patch sets a NaN)."""
    bounds = weather.boundaries
    fields = [QUANTITY_FIELDS[c.quantity][0] for c in model.criteria]
    patches = list(weather.patches)
    base = np.array([float(getattr(weather, f)) for f in fields])
    values = np.array([[p.values.get(f, np.nan) for f in fields] for p in patches], dtype=float).reshape(
        -1, len(fields)
    )
    if any(np.isnan(v) for p in patches for v in p.values.values()):
        return None  # a patch that sets a missing value: NaN here means "not set"
    if bounds is None:
        boxes, lons, lats = np.zeros((0, 4)), np.zeros(0), np.zeros(0)
    else:
        boxes, lons, lats = bounds.boxes, bounds.lon_deg, bounds.lat_deg
    edges, n_edges, contrib, right, fill = model.evidence_rules()
    n_slots = np.array([len(c.states) + 1 for c in model.criteria], dtype=np.intp)
    stride = np.ones(len(n_slots), dtype=np.intp)
    for i in range(len(n_slots) - 2, -1, -1):
        stride[i] = stride[i + 1] * n_slots[i + 1]
    bin_state = np.full(edges.shape[:1] + (edges.shape[1] + 1,), -1, dtype=np.intp)
    fill_state = np.full(len(n_slots), -1, dtype=np.intp)
    for i, c in enumerate(model.criteria):
        for b, state in enumerate(c.bin_states):
            bin_state[i, b] = c.states.index(state)
        if c.if_missing != "nan":
            fill_state[i] = len(c.states) if c.if_missing == "prior" else c.states.index(c.if_missing)
    p_flat = np.array(model.p_flat, dtype=np.float64)
    c_ = np.ascontiguousarray
    return BoxFields(
        base=base,
        boxes=c_(boxes, dtype=np.float64).reshape(-1, 4),
        values=c_(values),
        lon_lines=c_(lons, dtype=np.float64),
        lat_lines=c_(lats, dtype=np.float64),
        relative=np.array([QUANTITY_FIELDS[c.quantity][1] for c in model.criteria], dtype=np.bool_),
        edges=c_(edges),
        n_edges=c_(n_edges),
        right=c_(right),
        bin_state=bin_state,
        fill_state=fill_state,
        n_slots=n_slots,
        stride=stride,
        p_flat=p_flat,
        over=np.array(p_flat > apf, dtype=np.bool_),
        bits=np.array(model.fired_bits_flat, dtype=np.uint32),
        apf=float(apf),
        p_max=float(np.max(p_flat)),
        contrib=c_(contrib),
        fill=c_(fill),
    )


@numba.njit(nogil=True, cache=True, inline="always", error_model="numpy")
def _fields_at(lon, lat, base, boxes, values, out):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Each criterion's field at a point into ``out``: the base, overridden by each closed box holding the point
    that sets it (in order)."""
    for c in range(base.size):
        out[c] = base[c]
    for p in range(boxes.shape[0]):
        if lon >= boxes[p, 0] and lon <= boxes[p, 1] and lat >= boxes[p, 2] and lat <= boxes[p, 3]:
            for c in range(base.size):
                v = values[p, c]
                if v == v:
                    out[c] = v


@numba.njit(nogil=True, cache=True, inline="always", error_model="numpy")
def sample_evidence(lon, lat, course, base, boxes, values, relative, edges, n_edges, right, contrib, fill, p_flat, over,
                    bits, work):  # type: ignore[no-untyped-def]  # pragma: no cover  # fmt: skip
    """The cost function's judgement at one sample (lon, lat, course [deg]) with the fields and classifier of a
    :class:`BoxFields`: the table entry's p_f (NaN where the evidence is unknown), whether it exceeds apf, the
    criteria it fires then, and whether the evidence is unknown (:func:`~pyroute_rel._kernels.cost.evidence_point`'s
    classification). ``work``: scratch of one value per criterion."""
    _fields_at(lon, lat, base, boxes, values, work)
    e, lost = evidence_point(work, relative, course, edges, n_edges, contrib, right, fill)
    if lost:
        return np.nan, False, np.uint32(0), True
    return p_flat[e], over[e], bits[e] if over[e] else np.uint32(0), False


@numba.njit(nogil=True, cache=True, inline="always", error_model="numpy")
def _lonlat(x, y, z):  # type: ignore[no-untyped-def]  # pragma: no cover
    return np.degrees(np.arctan2(y, x)), np.degrees(np.arcsin(min(max(z, -1.0), 1.0)))


@numba.njit(nogil=True, cache=True, inline="always", error_model="numpy")
def _add_parallel(ax, ay, az, ux, uy, uz, omega, lat, out, n):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The fractions where the arc crosses parallel ``lat`` [deg] appended to ``out[n:]`` (crossings' arithmetic);
    returns the new count."""
    r = math.hypot(az, uz)
    phi = math.atan2(uz, az)
    s = math.sin(np.radians(lat))
    if not abs(s) <= r or r == 0.0:  # (an arc along the equator: numpy's 0 / 0 is NaN there, no crossing)
        return n
    d = math.acos(min(max(s / r, -1.0), 1.0))
    for t in ((phi - d) % (2.0 * np.pi), (phi + d) % (2.0 * np.pi)):
        if t > 0.0 and t < omega:
            out[n] = t / omega
            n += 1
    return n


@numba.njit(nogil=True, cache=True, error_model="numpy")
def arc_p_f(a, b, lon_lines, lat_lines, f, cuts, work, reach):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The largest p_f met along the great-circle arc from unit vector ``a`` to ``b`` (3,) and the criteria fired in
    the entries above apf it meets (:func:`~pyroute_rel.reliability.crossings.arc_extremes` for one arc of steady
    patches without a current; 0 where no piece reaches a state). ``f``: (base, boxes, values, relative, edges, n_edges,
    right, bin_state, fill_state, n_slots, stride, p_flat, p_over, bits); ``cuts``, ``work``, ``reach``: scratch (cuts
    for every crossing, (criteria, 4) values, and (criteria, slots))."""
    (
        base,
        boxes,
        values,
        relative,
        edges,
        n_edges,
        right,
        bin_state,
        fill_state,
        n_slots,
        stride,
        p_flat,
        p_over,
        bits,
    ) = f
    ax, ay, az = a[0], a[1], a[2]
    dx, dy, dz = ax - b[0], ay - b[1], az - b[2]
    omega = 2.0 * math.asin(min(max(math.sqrt(dx * dx + dy * dy + dz * dz) / 2.0, 0.0), 1.0))
    co = math.cos(omega)
    ux, uy, uz = b[0] - ax * co, b[1] - ay * co, b[2] - az * co
    norm = math.sqrt(ux * ux + uy * uy + uz * uz)
    if norm > 0.0:
        ux, uy, uz = ux / norm, uy / norm, uz / norm
    else:
        ux = uy = uz = 0.0
    frame = (ax, ay, az, ux, uy, uz, omega)
    m = _cuts(frame, b, boxes, lon_lines, lat_lines, cuts)
    best = -np.inf
    fired = np.uint32(0)
    s0 = 0.0
    for i in range(m + 1):
        s1 = cuts[i]
        if not s1 > s0:
            continue
        _piece_values(frame, s0, s1, base, boxes, values, relative, work)
        s0 = s1
        if _reach(work, relative, edges, n_edges, right, bin_state, fill_state, n_slots, reach):
            best, fired = _entries(reach, n_slots, stride, p_flat, p_over, bits, best, fired)
    return max(best, 0.0), fired


@numba.njit(nogil=True, cache=True, inline="always", error_model="numpy")
def _cuts(frame, b, boxes, lon_lines, lat_lines, cuts):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Where the arc (``frame``: its start, tangent and central angle) to ``b`` crosses the patches' lines (when its
    bounding box meets a patch, the lines within its ranges: :func:`~pyroute_rel.reliability.crossings._candidates`) and
    the equator, more than NUDGE from its ends, sorted into ``cuts[:m]`` and followed by 1; returns ``m``."""
    ax, ay, az, ux, uy, uz, omega = frame
    n = 0
    if boxes.shape[0]:
        lon0, lat0 = _lonlat(ax, ay, az)
        lon1, lat1 = _lonlat(b[0], b[1], b[2])
        half = np.degrees(omega) / 2.0
        la_lo = min(lat0, lat1) - half
        la_hi = max(lat0, lat1) + half
        dl = (lon1 - lon0 + 180.0) % 360.0 - 180.0
        lo_lo = min(lon0, lon0 + dl)
        lo_hi = max(lon0, lon0 + dl)
        if la_hi >= 89.0 or la_lo <= -89.0:
            lo_lo, lo_hi = -540.0, 540.0
        meet = False
        for p in range(boxes.shape[0]):
            if la_hi >= boxes[p, 2] and la_lo <= boxes[p, 3]:
                for shift in (-360.0, 0.0, 360.0):
                    meet |= lo_hi >= boxes[p, 0] + shift and lo_lo <= boxes[p, 1] + shift
        if meet:
            for shift in (-360.0, 0.0, 360.0):
                for L in lon_lines:
                    v = L + shift
                    if v >= lo_lo and v <= lo_hi:
                        n = _add_meridian(frame, v, cuts, n)
            for L in lat_lines:
                if L >= la_lo and L <= la_hi:
                    n = _add_parallel(ax, ay, az, ux, uy, uz, omega, L, cuts, n)
    n = _add_parallel(ax, ay, az, ux, uy, uz, omega, 0.0, cuts, n)
    m = 0
    for i in range(n):  # crossings within NUDGE of an end cut nothing off
        if cuts[i] > NUDGE and cuts[i] < 1.0 - NUDGE:
            cuts[m] = cuts[i]
            m += 1
    cuts[:m].sort()
    cuts[m] = 1.0
    return m


@numba.njit(nogil=True, cache=True, inline="always", error_model="numpy")
def _add_meridian(frame, lon, cuts, n):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The fraction where the arc crosses meridian ``lon`` [deg] (its plane, normal (-sin L, cos L, 0), on the
    meridian's half) appended to ``cuts[n:]``; returns the new count."""
    ax, ay, az, ux, uy, uz, omega = frame
    lr = np.radians(lon)
    sl, cl = math.sin(lr), math.cos(lr)
    an = ax * -sl + ay * cl
    un = ux * -sl + uy * cl
    t = math.atan2(-an, un) % np.pi
    ct, st = math.cos(t), math.sin(t)
    px, py = ax * ct + ux * st, ay * ct + uy * st
    if t > 0.0 and t < omega and px * cl + py * sl > 0.0:
        cuts[n] = t / omega
        n += 1
    return n


@numba.njit(nogil=True, cache=True, inline="always", error_model="numpy")
def _piece_values(frame, s0, s1, base, boxes, values, relative, work):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Each criterion's quantity at the piece ``[s0, s1]``'s ends (nudged inside) and middle into ``work[:, 0:3]``
    (:func:`~pyroute_rel.reliability.crossings._points`, :func:`~pyroute_rel.reliability.crossings._quantities`: a
    relative angle as ``field - course`` in [-180, 180))."""
    ax, ay, az, ux, uy, uz, omega = frame
    for j in range(3):
        fr = s0 + (s1 - s0) * (NUDGE if j == 0 else 0.5 if j == 1 else 1.0 - NUDGE)
        t = fr * omega
        c_, s_ = math.cos(t), math.sin(t)
        x, y, z = ax * c_ + ux * s_, ay * c_ + uy * s_, az * c_ + uz * s_
        vx, vy, vz = ux * c_ - ax * s_, uy * c_ - ay * s_, uz * c_ - az * s_
        lon, lat = _lonlat(x, y, z)
        lr = np.radians(lon)
        sl, cl = math.sin(lr), math.cos(lr)
        east = -sl * vx + cl * vy
        north = vz * math.sqrt(x * x + y * y) - z * (cl * vx + sl * vy)
        course = np.degrees(math.atan2(east, north))
        course += 360.0 * (course < 0.0)
        if course >= 360.0:
            course = 0.0
        _fields_at(lon, lat, base, boxes, values, work[:, 3])
        for c in range(base.size):
            v = work[c, 3]
            if relative[c]:
                v = (v - course + 180.0) % 360.0 - 180.0
            work[c, j] = v


@numba.njit(nogil=True, cache=True, inline="always", error_model="numpy")
def _reach(work, relative, edges, n_edges, right, bin_state, fill_state, n_slots, reach):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The states each criterion's range over the piece reaches (``reach[c, slot]``, from its values in
    ``work[c, 0:3]``: :func:`~pyroute_rel.reliability.crossings._ranges` and
    :func:`~pyroute_rel.reliability.crossings._box_max`'s classification); False where some criterion reaches none (the
    piece then gives no state)."""
    for c in range(n_slots.size):
        v0, v1, v2 = work[c, 0], work[c, 1], work[c, 2]
        if relative[c]:  # unwrapped about the middle
            v0 = v1 + (v0 - v1 + 180.0) % 360.0 - 180.0
            v2 = v1 + (v2 - v1 + 180.0) % 360.0 - 180.0
            v1 = v1 + (v1 - v1 + 180.0) % 360.0 - 180.0
        lo = fmin(fmin(v0, v1), v2)
        hi = fmax(fmax(v0, v1), v2)
        if relative[c]:
            lo, hi = _fold_range(lo, hi)
        for k in range(n_slots[c]):
            reach[c, k] = False
        if lo == lo:
            b_lo = _bin(lo, edges, n_edges[c], right[c], c)
            b_hi = _bin(hi, edges, n_edges[c], right[c], c)
            for bb in range(b_lo, b_hi + 1):
                reach[c, bin_state[c, bb]] = True
        elif fill_state[c] >= 0:
            reach[c, fill_state[c]] = True
        else:
            return False
    return True


@numba.njit(nogil=True, cache=True, inline="always", error_model="numpy")
def _entries(reach, n_slots, stride, p_flat, p_over, bits, best, fired):  # type: ignore[no-untyped-def]  # pragma: no cover
    """``best`` and ``fired`` updated with every table entry whose states are all reached (an odometer over each
    criterion's reached slots): the largest p_f, and the criteria of the entries above apf."""
    n_crit = n_slots.size
    idx = np.zeros(n_crit, dtype=np.intp)
    for c in range(n_crit):
        while not reach[c, idx[c]]:
            idx[c] += 1
    while True:
        e = 0
        for c in range(n_crit):
            e += idx[c] * stride[c]
        p = p_flat[e]
        if p > best:
            best = p
        if p_over[e]:
            fired |= bits[e]
        c = n_crit - 1
        while c >= 0:  # the next reached slot of the last criterion, carrying into the ones before
            idx[c] += 1
            while idx[c] < n_slots[c] and not reach[c, idx[c]]:
                idx[c] += 1
            if idx[c] < n_slots[c]:
                break
            idx[c] = 0
            while not reach[c, idx[c]]:
                idx[c] += 1
            c -= 1
        if c < 0:
            return best, fired


@numba.njit(nogil=True, cache=True, inline="always", error_model="numpy")
def _bin(x, edges, m, right, c):  # type: ignore[no-untyped-def]  # pragma: no cover
    """numpy's searchsorted of ``x`` in criterion ``c``'s edges (side "right" where ``right``)."""
    b = 0
    for j in range(m):
        b += (edges[c, j] <= x) if right else (edges[c, j] < x)
    return b


@numba.njit(nogil=True, cache=True, inline="always", error_model="numpy")
def _fold(x):  # type: ignore[no-untyped-def]  # pragma: no cover
    """:func:`~pyroute_rel.geodesy.fold_angle_deg` of one value below 720 deg."""
    d = abs(x)
    if d > 360.0:
        d = d % 360.0
    return min(d, 360.0 - d)


@numba.njit(nogil=True, cache=True, inline="always", error_model="numpy")
def _fold_range(lo, hi):  # type: ignore[no-untyped-def]  # pragma: no cover
    """:func:`~pyroute_rel.reliability.crossings._fold_range` of one range."""
    m = lo % 360.0
    h = m + (hi - lo)
    fm, fh = _fold(m), _fold(h)
    lo, hi = min(fm, fh), max(fm, fh)
    if (m <= 180.0 and h >= 180.0) or (m <= 540.0 and h >= 540.0):
        hi = 180.0
    if m == 0.0 or (m <= 360.0 and h >= 360.0):
        lo = 0.0
    return lo, hi


@numba.njit(nogil=True, cache=True, error_model="numpy")
def needs_judging(lon, lat, course, seg_nm, boxes, base, values, relative, edges, n_edges, work):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Whether an arc's samples (``lon``, ``lat``, ``course`` [deg], one value per sample) cannot judge it alone:
    :func:`~pyroute_rel.reliability.crossings.needs_pieces` for patches (an arc that may reach a patch edge, or whose
    course may carry a heading-dependent quantity across a bin edge), with the arc's own latitude bound. ``seg_nm``: its
    sub-segment length [nm]; ``base``, ``values``: the fields (:class:`BoxFields`); ``work``: scratch of one value per
    criterion."""
    half = np.degrees(seg_nm * 0.5 * KM_PER_NM / EARTH_RADIUS_KM) * 1.001 + 1e-9
    la_lo, la_hi = np.inf, -np.inf
    lo_lo, lo_hi = np.inf, -np.inf
    for s in range(lon.size):
        la_lo, la_hi = min(la_lo, lat[s]), max(la_hi, lat[s])
        lo_lo, lo_hi = min(lo_lo, lon[s]), max(lo_hi, lon[s])
    la_lo -= half
    la_hi += half
    big = max(abs(la_lo), abs(la_hi))
    if big > 89.0:
        return True  # near a pole: judged on its pieces (the course turns without bound there)
    lon_margin = half / math.cos(np.radians(big))
    lo_lo -= lon_margin
    lo_hi += lon_margin
    if lo_hi - lo_lo > 180.0:  # across the antimeridian: judged whole
        return True
    for p in range(boxes.shape[0]):
        by0, by1 = boxes[p, 2], boxes[p, 3]
        lat_in = la_hi >= by0 and la_lo <= by1
        for shift in (-360.0, 0.0, 360.0):  # a patch's edges a turn either way (the samples' longitudes may be)
            bx0, bx1 = boxes[p, 0] + shift, boxes[p, 1] + shift
            lon_in = lo_hi >= bx0 and lo_lo <= bx1
            if lat_in and ((lo_lo <= bx0 and lo_hi >= bx0) or (lo_lo <= bx1 and lo_hi >= bx1)):
                return True
            if lon_in and ((la_lo <= by0 and la_hi >= by0) or (la_lo <= by1 and la_hi >= by1)):
                return True
    turn = half * (math.tan(np.radians(big)) * 1.01) + 1e-9
    c0 = course[0]
    _fields_at(lon[0], lat[0], base, boxes, values, work)
    margin = 2.0 * turn
    for s in range(1, course.size):
        margin = max(margin, abs((course[s] - c0 + 180.0) % 360.0 - 180.0) + 2.0 * turn)
    for c in range(base.size):
        if relative[c]:
            if not np.isfinite(work[c]):
                return True
            q0 = _fold(work[c] - c0)
            for j in range(n_edges[c]):
                if abs(q0 - edges[c, j]) <= margin:
                    return True
    return False
