"""Compiled sampling of gridded weather: locating points on axes, bilinear interpolation in space and linear in
time, wind vectors turned into speed and bearing, the decoding of packed file values, and the neighbour checks of a
field's smoothness.

Numpy twins: :class:`pyroute_rel.weather.gridded.GriddedWeather` sampling with
:attr:`~pyroute_rel.settings.Settings.fused_sampling` off and :func:`pyroute_rel.geodesy.bearing_deg`; pinned by
``tests/test_interp_fast.py`` (the interpolation against a plain-Python reference, bit for bit),
``tests/test_weather_io.py::test_compiled_wind_vector_equals_numpy`` and ``tests/test_member_reading.py`` (the
decoding).
They release the GIL and are cached on disk after the first compilation; excluded from coverage.
"""

from __future__ import annotations

import math

import numba
import numpy as np


@numba.njit(nogil=True, cache=True)
def fill_codes(data, j, codes, table):  # type: ignore[no-untyped-def]  # pragma: no cover
    """``data[..., j] = table[codes]``, both (lat, lon, time)."""
    ny, nx, nt = codes.shape
    for y in range(ny):
        for x in range(nx):
            for t in range(nt):
                data[y, x, t, j] = table[codes[y, x, t]]


@numba.njit(nogil=True, cache=True, inline="always")
def axis_cell(axis, first, inv, x):  # type: ignore[no-untyped-def]  # pragma: no cover
    """(i, w): the cell ``axis[i] <= x < axis[i + 1]`` (clipped to the axis) and the weight of ``axis[i + 1]``.

    Regular axes are found by arithmetic (``inv``: cells per unit of the axis, its mean spacing's inverse), checked
    against the axis values and corrected by a step; anything else by a binary search, so the cell is always the
    binary search's. Outside the axis ``w`` is outside [0, 1]; NaN gives NaN.
    """
    n = axis.size
    if x != x:  # NaN
        return 0, x
    if x < axis[0]:
        i = 0
    elif x >= axis[n - 1]:
        i = n - 1
    else:
        i = min(max(int((x - first) * inv), 0), n - 2)  # a product, not a quotient: the guess may be one off
        if x < axis[i]:
            i = max(i - 1, 0)
        elif x >= axis[i + 1]:
            i = min(i + 1, n - 2)
        if not (axis[i] <= x < axis[i + 1]):
            lo, hi = 0, n - 1  # axis[lo] <= x < axis[hi]
            while hi - lo > 1:
                mid = (lo + hi) // 2
                if axis[mid] <= x:
                    lo = mid
                else:
                    hi = mid
            i = lo
    if i == n - 1:
        return i, 0.0 if x == axis[i] else (x - axis[i]) / math.inf
    return i, (x - axis[i]) / (axis[i + 1] - axis[i])


@numba.njit(nogil=True, cache=True)
def locate(axis, x, stride, i_out, w_out, step_out, ok_out):  # type: ignore[no-untyped-def]  # pragma: no cover
    """:func:`_locate` into preallocated outputs."""
    n = axis.size
    first = axis[0]
    last = axis[n - 1]
    inv = (n - 1) / (last - first) if n > 1 else 1.0
    for k in range(x.size):
        xk = x[k]
        i, w = axis_cell(axis, first, inv, xk)
        i_out[k] = i
        w_out[k] = w
        step_out[k] = stride if w > 0.0 else 0
        ok_out[k] = first <= xk <= last


@numba.njit(nogil=True, cache=True, inline="always")
def lerp(flat, b00, b10, b01, b11, st, c00, c10, c01, c11, t0w, wt):  # type: ignore[no-untyped-def]  # pragma: no cover
    """One stored value, trilinear: corners ``b00`` .. ``b11`` of ``flat`` (unsigned indices, the column's own) with
    weights ``c00`` .. ``c11``, each at two times ``st`` apart with weights ``t0w`` and ``wt``."""
    return (
        c00 * (t0w * flat[b00] + wt * flat[b00 + st])
        + c10 * (t0w * flat[b10] + wt * flat[b10 + st])
        + c01 * (t0w * flat[b01] + wt * flat[b01 + st])
        + c11 * (t0w * flat[b11] + wt * flat[b11 + st])
    )


@numba.njit(nogil=True, cache=True, inline="always")
def fused_mode(columns, ru, rv, rs, rc):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Which of :func:`interpolate`'s unrolled paths fits the call: 1 (two consecutive columns, the wind's u and
    v, turned), 2 (five consecutive columns: wind u and v turned, a third, a wave direction's sine and cosine turned),
    0 (any other: the general loop)."""
    n = columns.size
    for c in range(n):
        if columns[c] != columns[0] + c:
            return 0
    if n == 2 and ru == 0 and rv == 1 and rs < 0:
        return 1
    if n == 5 and ru == 0 and rv == 1 and rs == 3 and rc == 4:
        return 2
    return 0


@numba.njit(nogil=True, cache=True)
def interpolate(flat, nf, columns, base, sx, sy, wx, wy, ok, t, scale, shift, t_axis, ru, rv, rs, rc, kn, out):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Trilinear interpolation of the stored ``columns`` (of ``nf`` interleaved) at located points -> ``out``.

    ``base``/``sx``/``sy``/``wx``/``wy``/``ok`` are a :class:`_Where`; ``t * scale + shift`` [s] the points' times
    on ``t_axis`` (empty: a steady block, valid at any time; one value: valid at exactly that time). NaN outside.
    Rows ``ru``, ``rv`` (wind u, v [m/s]) become the wind's speed [``kn`` per m/s] and direction (from) [deg], row
    ``rs`` (with ``rc``: a wave direction's sine and cosine) the wave direction [deg], point by point, as
    :func:`vectors` turns them (-1: no such rows).

    The sampler's two usual calls (wind; wind, a scalar and the wave direction, consecutive columns) are unrolled
    (:func:`fused_mode`), each turned vector kept in registers; indices are unsigned (no negative-index wraparound).
    """
    nt = t_axis.size
    t_first = t_axis[0] if nt > 0 else 0.0
    t_last = t_axis[nt - 1] if nt > 0 else 0.0
    t_inv = (nt - 1) / (t_last - t_first) if nt > 1 else 1.0
    mode = fused_mode(columns, ru, rv, rs, rc)
    f0 = np.uint64(columns[0]) if mode > 0 else np.uint64(0)
    x_prev, it_prev, wt_prev = np.nan, 0, 0.0  # the last time's cell: runs of points share a time (one arc's)
    for k in range(base.size):
        good = ok[k]
        it = 0
        wt = 0.0
        if good and nt > 0:
            x = t[k] * scale + shift
            good = t_first <= x <= t_last
            if good:
                if x != x_prev:
                    x_prev = x
                    it_prev, wt_prev = axis_cell(t_axis, t_first, t_inv, x)
                it, wt = it_prev, wt_prev
        if not good:
            for c in range(columns.size):
                out[c, k] = np.nan
            mode_k = 0
        else:
            mode_k = mode
            st = np.uint64(nf) if wt > 0.0 else np.uint64(0)
            b = np.uint64(base[k] + it * nf)
            ax = wx[k]
            ay = wy[k]
            c00 = (1.0 - ax) * (1.0 - ay)
            c10 = ax * (1.0 - ay)
            c01 = (1.0 - ax) * ay
            c11 = ax * ay
            b10 = b + np.uint64(sx[k])
            b01 = b + np.uint64(sy[k])
            b11 = b10 + np.uint64(sy[k])
            t0w = 1.0 - wt
            if mode == 0:
                for c in range(columns.size):
                    f = np.uint64(columns[c])
                    out[c, k] = lerp(flat, b + f, b10 + f, b01 + f, b11 + f, st, c00, c10, c01, c11, t0w, wt)
            else:
                b, b10, b01, b11 = b + f0, b10 + f0, b01 + f0, b11 + f0
                u = lerp(flat, b, b10, b01, b11, st, c00, c10, c01, c11, t0w, wt)
                one, two = np.uint64(1), np.uint64(2)
                v = lerp(flat, b + one, b10 + one, b01 + one, b11 + one, st, c00, c10, c01, c11, t0w, wt)
                out[0, k], out[1, k] = speed_bearing(-1.0 * u, -1.0 * v, kn)
                if mode == 2:
                    b, b10, b01, b11 = b + two, b10 + two, b01 + two, b11 + two
                    out[2, k] = lerp(flat, b, b10, b01, b11, st, c00, c10, c01, c11, t0w, wt)
                    sin = lerp(flat, b + one, b10 + one, b01 + one, b11 + one, st, c00, c10, c01, c11, t0w, wt)
                    b, b10, b01, b11 = b + two, b10 + two, b01 + two, b11 + two
                    cos = lerp(flat, b, b10, b01, b11, st, c00, c10, c01, c11, t0w, wt)
                    out[3, k] = speed_bearing(sin, cos, 1.0)[1]
                    out[4, k] = cos
        if mode_k == 0:
            if ru >= 0:  # the wind's speed and direction, from its (u, v) just computed
                out[ru, k], out[rv, k] = speed_bearing(-1.0 * out[ru, k], -1.0 * out[rv, k], kn)
            if rs >= 0:
                out[rs, k] = speed_bearing(out[rs, k], out[rc, k], 1.0)[1]


@numba.njit(nogil=True, cache=True)
def vectors(east, north, sign, scale, speed_out, bearing_out):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Length x ``scale`` and bearing [deg, [0, 360)] of ``sign`` x (east, north), as
    :func:`~pyroute_rel.geodesy.bearing_deg` gives it (to 1e-13 deg); NaN in, NaN out. ``speed_out`` may be empty
    (bearing only).

    The bearing is ``atan`` of the smaller over the larger component, placed in its octant by selects: three times
    faster than the C library's ``atan2``, which took a sixth of the time of a route over gridded weather.
    """
    with_speed = speed_out.size > 0
    for k in range(east.size):
        speed, bearing = speed_bearing(sign * east[k], sign * north[k], scale)
        bearing_out[k] = bearing
        if with_speed:
            speed_out[k] = speed


@numba.njit(nogil=True, cache=True, inline="always")
def speed_bearing(e, n, scale):  # type: ignore[no-untyped-def]  # pragma: no cover
    """:func:`vectors` for one vector (east, north): its length x ``scale`` and bearing [deg, [0, 360)]."""
    ae = abs(e)
    an = abs(n)
    hi = max(ae, an)
    if hi > 0.0 and hi < math.inf and e == e and n == n:  # (max() may drop a NaN: tested apart)
        r = math.degrees(math.atan(min(ae, an) / hi))  # angle from the nearer axis, in [0, 45]
        r = 90.0 - r if ae > an else r  # from the north-south axis
        r = 180.0 - r if n < 0.0 else r
        d = 360.0 - r if e < 0.0 else r
    else:  # calm (signed zeros), infinite or NaN components: the library's rules
        d = math.degrees(math.atan2(e, n))
        if d < 0.0:
            d += 360.0
    if d >= 360.0:
        d = 0.0
    return math.sqrt(e * e + n * n) * scale, d + 0.0  # hypot's overflow care costs 15x here; + 0.0: no -0.0


@numba.njit(nogil=True, cache=True)
def neighbour_max_diff(data, c0, c1, axis):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Largest |difference| of column c0 (plus that of c1 when >= 0) between neighbours along ``axis``."""
    ny, nx, nt, _ = data.shape
    dj, di, dt = (1, 0, 0) if axis == 0 else ((0, 1, 0) if axis == 1 else (0, 0, 1))
    best = 0.0
    for j in range(ny - dj):
        for i in range(nx - di):
            for t in range(nt - dt):
                d = abs(np.float64(data[j + dj, i + di, t + dt, c0]) - data[j, i, t, c0])
                if c1 >= 0:
                    d += abs(np.float64(data[j + dj, i + di, t + dt, c1]) - data[j, i, t, c1])
                if d > best:  # False for NaN
                    best = d
    return best


@numba.njit(nogil=True, cache=True)
def neighbour_min_cos(data, c0, c1, axis, stop):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Smallest cosine of the angle between the vectors (column c0, column c1) of neighbours along ``axis`` (-1
    where one is zero), or the first one found below ``stop``."""
    ny, nx, nt, _ = data.shape
    dj, di, dt = (1, 0, 0) if axis == 0 else ((0, 1, 0) if axis == 1 else (0, 0, 1))
    worst = 1.0
    for j in range(ny - dj):
        for i in range(nx - di):
            for t in range(nt - dt):
                ax = np.float64(data[j, i, t, c0])
                ay = np.float64(data[j, i, t, c1])
                bx = np.float64(data[j + dj, i + di, t + dt, c0])
                by = np.float64(data[j + dj, i + di, t + dt, c1])
                norm = np.sqrt((ax * ax + ay * ay) * (bx * bx + by * by))
                if norm != norm:
                    continue
                c = (ax * bx + ay * by) / norm if norm > 0.0 else -1.0
                if c < worst:
                    worst = c
                    if c < stop:
                        return worst
    return worst


@numba.njit(nogil=True, cache=True)
def look_up_codes(codes, it, iy, ix, table, lookup, with_codes):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Codes read (time, lat, lon), taken along each axis at ``it``, ``iy``, ``ix`` -> (``lookup[codes]`` on (lat,
    lon, time); the codes on (lat, lon, time) when ``with_codes``, else empty; the smallest and largest
    ``table[codes]``, NaN ignored (NaN when all are NaN, as :func:`numpy.fmin.reduce` and :func:`numpy.fmax.reduce`);
    whether any of them is finite)."""
    nt, ny, nx = it.size, iy.size, ix.size
    out = np.empty((ny, nx, nt), np.float32)
    kept = np.empty((ny, nx, nt if with_codes else 0), codes.dtype)
    seen = np.zeros(table.size, np.bool_)
    for y in range(ny):
        yy = iy[y]
        for x in range(nx):
            xx, row, kept_row = ix[x], out[y, x], kept[y, x]
            for t in range(nt):  # (written in order, read across)
                c = codes[it[t], yy, xx]
                seen[c] = True
                row[t] = lookup[c]
                if with_codes:
                    kept_row[t] = c
    lo = np.float32(np.nan)
    hi = np.float32(np.nan)
    finite = False
    for c in range(table.size):
        v = table[c]
        if seen[c] and v == v:
            if not (lo <= v):  # (NaN so far)
                lo = v
            if not (hi >= v):
                hi = v
            finite |= abs(v) < np.inf
    return out, kept, lo, hi, finite
