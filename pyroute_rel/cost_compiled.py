"""Compiled twin of the cost kernel's timing pass, for weather sampled in compiled code (gridded files).

With time-varying weather :func:`~pyroute_rel.cost.geometry_costs` first times every sub-segment with the
weather at the departure time (speeds only), then samples each point at the time the craft gets there. On
the paper's square 160 x 160 grid that first pass is 8 million points per route, and numpy spends more time
allocating temporaries for the polar lookup than computing it. :func:`sail_wind` does the same arithmetic
(TWA, polar speed, time), operation for operation, in one compiled loop (numba, no GIL), so its numbers are
bit-identical to the numpy path's (tested); it covers wind only (no current, no wave speed loss), where the
cost kernel uses it, in the second pass too (there the numpy code adds the failure model).

Imported only by routes over gridded weather, which load numba anyway: its import costs half a second,
which the default routes do not pay.
"""

from __future__ import annotations

import numba
import numpy as np
import numpy.typing as npt

from .polar import MIN_SPEED_KN, Polar, check_beyond

__all__ = ["sail_wind"]

FloatArray = npt.NDArray[np.float64]


def sail_wind(
    tws_kn: FloatArray,
    twd_deg: FloatArray,
    course_deg: FloatArray,
    seg_nm: FloatArray,
    polar: Polar,
    *,
    beyond: str = "clamp",
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """TWA [deg], polar speed [kn] and time to sail each sub-segment [h], as the numpy cost kernel computes them
    with no current and no wave speed loss.

    Parameters
    ----------
    tws_kn, twd_deg : Wind speed [kn] and direction (from) [deg] at the sample points, shape (..., samples).
    course_deg : Great-circle course at the sample points [deg], same shape.
    seg_nm : Sub-segment lengths [nm], broadcast to that shape (the geometry's (..., 1)).
    polar : Boat polar.
    beyond : Polar behaviour outside its table, one of :data:`~pyroute_rel.polar.BEYOND_MODES`.

    Returns
    -------
    ``twa_deg`` in [0, 180] and ``speed_kn`` (NaN where the wind is missing), and ``time_h`` (``inf`` where the
    wind is missing or the speed is below :data:`~pyroute_rel.polar.MIN_SPEED_KN`: the numpy kernel's time
    without a failure model).
    """
    check_beyond(beyond)
    shape = np.broadcast_shapes(tws_kn.shape, twd_deg.shape, course_deg.shape, seg_nm.shape)
    # contiguous, writable float64 everywhere: one compiled signature (a read-only array would be another)
    flat = [
        np.require(np.broadcast_to(a, shape), np.float64, ("C", "W")).reshape(-1)
        for a in (tws_kn, twd_deg, course_deg, seg_nm)
    ]
    twa, v, dt = (np.empty(flat[0].size) for _ in range(3))
    tables = [np.require(t, np.float64, ("C", "W")).reshape(-1) for t in (polar.twa_deg, polar.tws_kn, polar.speed_kn)]
    _wind_kernel(*flat, *tables, beyond == "forbid", MIN_SPEED_KN, twa, v, dt)  # type: ignore[call-arg]
    return twa.reshape(shape), v.reshape(shape), dt.reshape(shape)


@numba.njit(nogil=True, cache=True)
def _wind_kernel(tws, twd, course, seg, twa_tab, tws_tab, speed_tab, forbid, min_speed, twa_out, v_out, dt_out):  # type: ignore[no-untyped-def]  # pragma: no cover
    """One point at a time: fold TWA, bilinear polar (:func:`~pyroute_rel.polar.boat_speed_kn`), then
    ``seg / speed`` or ``inf`` (missing wind, no speed), in the numpy path's order of operations."""
    n_twa = twa_tab.size
    n_tws = tws_tab.size
    for k in range(tws.size):
        w = tws[k]
        d = twd[k]
        a = abs(d - course[k])
        if a > 360.0:
            a = a % 360.0
        a = min(a, 360.0 - a)
        twa_out[k] = a
        v = np.nan  # NaN in, NaN out (but for the no-go and "forbid" rules, applied last as in the numpy code)
        if a == a and w == w:
            # cells as clip(searchsorted(table, x, "right") - 1, 0, n - 2), by counting the inner rows at or below
            # x: polar tables are short, and a search that branches mispredicts once per point (half the time)
            i = 0
            for m in range(1, n_twa - 1):
                i += twa_tab[m] <= a
            j = 0
            for m in range(1, n_tws - 1):
                j += tws_tab[m] <= w
            fa = (a - twa_tab[i]) / (twa_tab[i + 1] - twa_tab[i])
            fa = min(max(fa, 0.0), 1.0)
            fw = (w - tws_tab[j]) / (tws_tab[j + 1] - tws_tab[j])
            fw = min(max(fw, 0.0), 1.0)
            c = i * n_tws + j
            gw = 1.0 - fw
            low = speed_tab[c] * gw + speed_tab[c + 1] * fw
            high = speed_tab[c + n_tws] * gw + speed_tab[c + n_tws + 1] * fw
            v = high * fa - low * (fa - 1.0)
            if tws_tab[0] > 0.0 and w < tws_tab[0]:
                v *= w / tws_tab[0]
        if twa_tab[0] > 0.0 and a < twa_tab[0]:
            v = 0.0
        if forbid and (a > twa_tab[n_twa - 1] or w > tws_tab[n_tws - 1]):
            v = 0.0
        v_out[k] = v
        # missing weather (an infinite wind, too) or no speed: forbidden
        dt_out[k] = seg[k] / v if v >= min_speed and np.isfinite(w) and np.isfinite(d) else np.inf
