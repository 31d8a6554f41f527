"""The polar lookup in compiled code: one point's TWA, boat speed and sub-segment time, for numba kernels.

:func:`~pyroute_rel.boat.polar.boat_speed_kn` (numpy, vectorised) is the reference; the functions here do the same
arithmetic, operation for operation, for one point at a time, so that a kernel's numbers are bit-identical to the
numpy path's. Both compiled kernels use them: :mod:`pyroute_rel._kernels.cost` (gridded weather) and
:mod:`pyroute_rel._kernels.dp` (the DP's rank step). They are numba functions (``inline="always"``: a call with
array arguments would cost more than the lookup) that take the tables of :func:`tables`.

The cell of a point is the one ``clip(searchsorted(axis, x, "right") - 1, 0, n - 2)`` finds, without a search: on
the short axes of a polar by counting the inner rows at or below the point (branch-free), on long ones (more than
:data:`SHORT_AXIS` inner rows) by a first guess from the axis's mean spacing (exact on a uniform axis), then a step
up or down while the guess is off (so any strictly increasing axis gives the same cell as the search).

numba caches a kernel with the functions it calls compiled in, and checks only the kernel's own file for changes:
after editing this module, delete the ``__pycache__`` caches (or touch ``_kernels/cost.py`` and
``_kernels/dp.py``) so that the kernels are compiled again.

Numpy twin: :func:`pyroute_rel.boat.polar.boat_speed_kn`; pinned by ``tests/test_polar_compiled.py`` (cells equal
numpy's ``searchsorted``, speeds equal the numpy lookup's).
"""

from __future__ import annotations

import numba
import numpy as np
import numpy.typing as npt

from pyroute_rel.boat.polar import Polar
from pyroute_rel.store import kept_by

__all__ = ["SHORT_AXIS", "blend", "cell", "cell_finder", "fold_twa", "sub_time", "speed_kn", "tables", "table_edges"]

FloatArray = npt.NDArray[np.float64]
#: What :func:`cell_finder` gives for an axis: ``(x0, scale, last, lower)``.
CellFinder = tuple[float, float, float, npt.NDArray[np.intp]]

#: Axes with at most this many inner rows are searched by counting the rows at or below a point (measured on the
#: square 160 x 160 grid with the maribot_vane polar, 9 and 4 inner rows: 12 ns a point, against 18 ns for a guess
#: from the spacing corrected by a step up or down, whose branches mispredict); longer ones by the guess.
SHORT_AXIS = 16


def tables(polar: Polar) -> tuple[FloatArray, FloatArray, FloatArray, float, float]:
    """The polar as the compiled functions take it, made once per polar and kept by it
    (:func:`~pyroute_rel.store.kept_by`).

    Parameters
    ----------
    polar : Boat polar.

    Returns
    -------
    ``twa_deg`` [deg] and ``tws_kn`` [kn] (the axes), ``speed_kn`` [kn] (the table, flattened row by row), each
    contiguous, writable float64 (one compiled signature), and the inverse mean spacing of each axis's inner rows
    (0 with fewer than two) for :func:`cell`'s first guess.
    """

    def make() -> tuple[FloatArray, FloatArray, FloatArray, float, float]:
        twa, tws, speed = (
            np.require(t, np.float64, ("C", "W")).reshape(-1) for t in (polar.twa_deg, polar.tws_kn, polar.speed_kn)
        )
        return twa, tws, speed, _inverse_step(twa), _inverse_step(tws)

    return kept_by(polar, "_kernel_tables", make)  # type: ignore[no-any-return]


def finder_tables(polar: Polar) -> tuple[FloatArray, FloatArray, FloatArray, CellFinder, CellFinder]:
    """The polar's table and axes as :func:`tables` gives them, each axis followed by its :func:`cell_finder`
    (``twa, tws, speed, twa_finder, tws_finder``), made once per polar and kept by it
    (:func:`~pyroute_rel.store.kept_by`)."""

    def make() -> tuple[FloatArray, FloatArray, FloatArray, CellFinder, CellFinder]:
        twa, tws, speed, _, _ = tables(polar)
        return twa, tws, speed, cell_finder(twa), cell_finder(tws)

    return kept_by(polar, "_kernel_finders", make)  # type: ignore[no-any-return]


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
    n_tws = tws_tab.size
    v = np.nan
    if ang == ang and w == w:
        i = cell(ang, twa_tab, twa_inv)
        j = cell(w, tws_tab, tws_inv)
        c = i * n_tws + j
        v = blend(
            ang,
            w,
            twa_tab[i],
            twa_tab[i + 1],
            tws_tab[j],
            tws_tab[j + 1],
            speed_tab[c],
            speed_tab[c + 1],
            speed_tab[c + n_tws],
            speed_tab[c + n_tws + 1],
            tws_tab[0],
        )
    return table_edges(v, ang, w, twa_tab[0], twa_tab[twa_tab.size - 1], tws_tab[n_tws - 1], forbid)


@numba.njit(nogil=True, cache=True, inline="always")
def blend(ang, w, a0, a1, w0, w1, s00, s01, s10, s11, tws_first):  # type: ignore[no-untyped-def]  # pragma: no cover
    """:func:`speed_kn` inside the table (``ang`` and ``w`` not NaN): bilinear between the cell's corners, TWA
    ``a0`` to ``a1`` [deg] and TWS ``w0`` to ``w1`` [kn] with speeds ``s00`` (a0, w0), ``s01`` (a0, w1), ``s10``
    (a1, w0), ``s11`` (a1, w1) [kn], weights clipped to [0, 1], times ``w / tws_first`` below a first column
    ``tws_first`` [kn] above 0. Scalars only: a kernel reads the table itself (an array passed to a function numba
    inlines is reference-counted at every call, which cost more than the lookup)."""
    fa = (ang - a0) / (a1 - a0)
    fa = min(max(fa, 0.0), 1.0)
    fw = (w - w0) / (w1 - w0)
    fw = min(max(fw, 0.0), 1.0)
    gw = 1.0 - fw
    low = s00 * gw + s01 * fw
    high = s10 * gw + s11 * fw
    v = high * fa - low * (fa - 1.0)
    if tws_first > 0.0 and w < tws_first:
        v *= w / tws_first
    return v


@numba.njit(nogil=True, cache=True, inline="always")
def table_edges(v, ang, w, twa_first, twa_last, tws_last, forbid):  # type: ignore[no-untyped-def]  # pragma: no cover
    """:func:`speed_kn`'s last two rules on the speed ``v`` [kn]: 0 below the first row ``twa_first`` [deg] when it
    is above 0 (no-go), and, with ``forbid``, 0 beyond the last row ``twa_last`` [deg] or column ``tws_last`` [kn]."""
    if twa_first > 0.0 and ang < twa_first:
        v = 0.0
    if forbid and (ang > twa_last or w > tws_last):
        v = 0.0
    return v


def cell_finder(axis: FloatArray) -> CellFinder:
    """What a kernel needs to find :func:`cell`'s cell in constant time, with no search: ``(x0, scale, last,
    lower)``; the cell of ``x`` (not NaN) on ``axis`` is then ``i = lower[int(min(max((x - x0) * scale, 0),
    last))]``, stepped up while ``i < n - 2`` and ``axis[i + 1] <= x``.

    The bins ``b(x) = int((x - x0) * scale)`` (clipped) rise with ``x`` (rounding is monotonic), so ``lower[b]``,
    the number of inner rows whose own bin is below ``b``, counts only rows below ``x``: it is never above the
    cell, and the steps up make it exact whatever the rounding. With ``scale`` at two bins per narrowest step, no two
    rows share a bin, and one step at most is needed. ``x0`` is the first inner row; at most 4096 bins.
    """
    axis = np.asarray(axis, dtype=np.float64)
    inner = axis[1:-1]
    if inner.size < 2:
        return float(axis[0]), 1.0, 0.0, np.zeros(1, dtype=np.intp)  # one bin (a finite scale: inf x 0 is NaN)
    x0, span = float(inner[0]), float(inner[-1] - inner[0])
    scale = min(2.0 / float(np.min(np.diff(inner))), 4096.0 / span)
    bins = np.minimum(np.maximum((inner - x0) * scale, 0.0), np.inf).astype(np.intp)
    last = int(bins[-1])
    lower = np.searchsorted(bins, np.arange(last + 1), "left").astype(np.intp)  # rows with a bin below each bin
    return x0, scale, float(last), lower


@numba.njit(nogil=True, cache=True, inline="always")
def sub_time(seg, v, w, twd, min_speed):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Time to sail a sub-segment of ``seg`` [nm] at ``v`` [kn] [h] and its reason flag
    (:data:`~pyroute_rel.routing.cost.REASONS`): ``inf`` and 2 where the wind ``w`` [kn] or ``twd`` [deg] is missing
    (not finite), ``inf`` and 1 where the speed is below ``min_speed`` [kn] (or NaN), else 0."""
    if not (np.isfinite(w) and np.isfinite(twd)):
        return np.inf, 2
    if v >= min_speed:
        return seg / v, 0
    return np.inf, 1


@numba.njit(nogil=True, cache=True, inline="always")
def fmin(a, b):  # type: ignore[no-untyped-def]  # pragma: no cover
    """numpy's fmin of two numbers: the smaller, NaN ignored (shared by the compiled march and pieces' judge)."""
    if a != a:
        return b
    if b != b:
        return a
    return a if a <= b else b


@numba.njit(nogil=True, cache=True, inline="always")
def fmax(a, b):  # type: ignore[no-untyped-def]  # pragma: no cover
    """numpy's fmax of two numbers: the larger, NaN ignored (shared by the compiled march and pieces' judge)."""
    if a != a:
        return b
    if b != b:
        return a
    return a if a >= b else b
