"""The polar lookup in compiled code: one point's TWA, boat speed and sub-segment time, for numba kernels.

:func:`~pyroute_rel.polar.boat_speed_kn` (numpy, vectorised) is the reference; the functions here do the same
arithmetic, operation for operation, for one point at a time, so that a kernel's numbers are bit-identical to the
numpy path's. Both compiled kernels use them: :mod:`pyroute_rel.cost_compiled` (gridded weather) and
:mod:`pyroute_rel.dp_compiled` (the DP's rank step). They are numba functions (``inline="always"``: a call with
array arguments would cost more than the lookup) that take the tables of :func:`tables`.

The cell of a point is the one ``clip(searchsorted(axis, x, "right") - 1, 0, n - 2)`` finds, without a search: on
the short axes of a polar by counting the inner rows at or below the point (branch-free), on long ones (more than
:data:`SHORT_AXIS` inner rows) by a first guess from the axis's mean spacing (exact on a uniform axis), then a step
up or down while the guess is off (so any strictly increasing axis gives the same cell as the search).

numba caches a kernel with the functions it calls compiled in, and checks only the kernel's own file for changes:
after editing this module, delete the ``__pycache__`` caches (or touch ``cost_compiled.py`` and
``dp_compiled.py``) so that the kernels are compiled again.
"""

from __future__ import annotations

import numba
import numpy as np
import numpy.typing as npt

from .polar import Polar

__all__ = ["SHORT_AXIS", "cell", "fold_twa", "sub_time", "speed_kn", "tables"]

FloatArray = npt.NDArray[np.float64]

#: Axes with at most this many inner rows are searched by counting the rows at or below a point (measured on the
#: square 160 x 160 grid with the maribot_vane polar, 9 and 4 inner rows: 12 ns a point, against 18 ns for a guess
#: from the spacing corrected by a step up or down, whose branches mispredict); longer ones by the guess.
SHORT_AXIS = 16


def tables(polar: Polar) -> tuple[FloatArray, FloatArray, FloatArray, float, float]:
    """The polar as the compiled functions take it.

    Parameters
    ----------
    polar : Boat polar.

    Returns
    -------
    ``twa_deg`` [deg] and ``tws_kn`` [kn] (the axes), ``speed_kn`` [kn] (the table, flattened row by row), each
    contiguous, writable float64 (one compiled signature), and the inverse mean spacing of each axis's inner rows
    (0 with fewer than two) for :func:`cell`'s first guess.
    """
    twa, tws, speed = (
        np.require(t, np.float64, ("C", "W")).reshape(-1) for t in (polar.twa_deg, polar.tws_kn, polar.speed_kn)
    )
    return twa, tws, speed, _inverse_step(twa), _inverse_step(tws)


def _inverse_step(axis: FloatArray) -> float:
    """(inner rows - 1) / their span: the cells per unit of the axis between its second and last-but-one rows."""
    n = axis.size
    return float((n - 3) / (axis[n - 2] - axis[1])) if n > 3 else 0.0


@numba.njit(nogil=True, cache=True, inline="always")
def cell(x, axis, inv):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The cell of ``x`` (not NaN) on a strictly increasing ``axis``: ``clip(searchsorted(axis, x, "right") - 1, 0,
    n - 2)``. ``inv``: :func:`tables`' inverse spacing, for the first guess on a long axis."""
    top = axis.size - 2
    if top <= SHORT_AXIS:  # count the inner rows at or below x: no branch to mispredict
        i = 0
        for m in range(1, top + 1):
            i += axis[m] <= x
        return i
    f = (x - axis[1]) * inv + 1.0
    if not f > 1.0:  # below the second row, or NaN (infinite x)
        i = 0
    elif f < top:
        i = int(f)
    else:
        i = top
    while i < top and axis[i + 1] <= x:
        i += 1
    while i > 0 and axis[i] > x:
        i -= 1
    return i


@numba.njit(nogil=True, cache=True, inline="always")
def fold_twa(twd, course):  # type: ignore[no-untyped-def]  # pragma: no cover
    """True wind angle [deg] in [0, 180] of a wind from ``twd`` [deg] on ``course`` [deg]
    (:func:`~pyroute_rel.geodesy.angle_diff_deg`'s arithmetic; NaN in, NaN out)."""
    ang = abs(twd - course)
    if ang > 360.0:
        ang = ang % 360.0
    return min(ang, 360.0 - ang)


@numba.njit(nogil=True, cache=True, inline="always")
def speed_kn(ang, w, twa_tab, tws_tab, speed_tab, twa_inv, tws_inv, forbid):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Boat speed [kn] at TWA ``ang`` [deg] (folded) and TWS ``w`` [kn]: bilinear in the table, linear to 0 kn
    below its first column, 0 kn below its first row (no-go) and, with ``forbid``, beyond its last row or column;
    NaN where ``ang`` or ``w`` is (but for those two rules, applied last as in the numpy code)."""
    n_twa = twa_tab.size
    n_tws = tws_tab.size
    v = np.nan
    if ang == ang and w == w:
        i = cell(ang, twa_tab, twa_inv)
        j = cell(w, tws_tab, tws_inv)
        fa = (ang - twa_tab[i]) / (twa_tab[i + 1] - twa_tab[i])
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
    if twa_tab[0] > 0.0 and ang < twa_tab[0]:
        v = 0.0
    if forbid and (ang > twa_tab[n_twa - 1] or w > tws_tab[n_tws - 1]):
        v = 0.0
    return v


@numba.njit(nogil=True, cache=True, inline="always")
def sub_time(seg, v, w, twd, min_speed):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Time to sail a sub-segment of ``seg`` [nm] at ``v`` [kn] [h] and its reason flag
    (:data:`~pyroute_rel.cost.REASONS`): ``inf`` and 2 where the wind ``w`` [kn] or ``twd`` [deg] is missing (not
    finite), ``inf`` and 1 where the speed is below ``min_speed`` [kn] (or NaN), else 0."""
    if not (np.isfinite(w) and np.isfinite(twd)):
        return np.inf, 2
    if v >= min_speed:
        return seg / v, 0
    return np.inf, 1
