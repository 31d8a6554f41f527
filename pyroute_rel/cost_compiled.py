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

from . import polar_compiled
from .polar import MIN_SPEED_KN, Polar, check_beyond
from .polar_compiled import fold_twa, speed_kn, sub_time

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
    # contiguous, writable float64 everywhere (one compiled signature: a read-only array would be another); an
    # input of the full shape is passed as it is when it already is that (no copy), and the sub-segment lengths
    # of shape (..., 1) (one per arc, the geometry's) are passed once per arc, each used for ``every`` points
    flat = [_flat(a, shape) for a in (tws_kn, twd_deg, course_deg)]
    every = 1
    if shape and seg_nm.shape == shape[:-1] + (1,) and shape[-1] > 1:
        seg, every = np.require(seg_nm, np.float64, ("C", "W")).reshape(-1), shape[-1]
    else:
        seg = _flat(seg_nm, shape)
    twa, v, dt = (np.empty(flat[0].size) for _ in range(3))
    _wind_kernel(*flat, seg, every, *polar_compiled.tables(polar), beyond == "forbid", MIN_SPEED_KN, twa, v, dt)  # type: ignore[call-arg]
    return twa.reshape(shape), v.reshape(shape), dt.reshape(shape)


def _flat(a: FloatArray, shape: tuple[int, ...]) -> FloatArray:
    """``a`` broadcast to ``shape`` as a contiguous, writable float64 vector (copied only if it is not one)."""
    if a.shape != shape:
        a = np.broadcast_to(a, shape)  # read-only: np.require copies it
    return np.require(a, np.float64, ("C", "W")).reshape(-1)


@numba.njit(nogil=True, cache=True)
def _wind_kernel(
    tws,
    twd,
    course,
    seg,
    every,
    twa_tab,
    tws_tab,
    speed_tab,
    twa_inv,
    tws_inv,
    forbid,
    min_speed,
    twa_out,
    v_out,
    dt_out,
):  # type: ignore[no-untyped-def]  # pragma: no cover
    """One point at a time: fold TWA, bilinear polar, then ``seg / speed`` or ``inf`` (missing wind, no speed)
    (:mod:`pyroute_rel.polar_compiled`), in the numpy path's order of operations; points ``i * every`` to
    ``(i + 1) * every - 1`` sail ``seg[i]``."""
    for i in range(tws.size // every):  # arc by arc (no division per point)
        s = seg[i]
        for k in range(i * every, (i + 1) * every):
            a = fold_twa(twd[k], course[k])
            twa_out[k] = a
            v = speed_kn(a, tws[k], twa_tab, tws_tab, speed_tab, twa_inv, tws_inv, forbid)
            v_out[k] = v
            dt_out[k] = sub_time(s, v, tws[k], twd[k], min_speed)[0]
