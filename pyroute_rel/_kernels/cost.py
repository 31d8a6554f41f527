"""Compiled twins of the cost kernel's arithmetic, for weather sampled in compiled code (gridded files).

:func:`sail_wind` computes the TWA, polar speed and time of sub-segments as the numpy cost kernel does, operation for
operation, in one compiled loop (numba, no GIL), so its numbers are bit-identical to the numpy path's (tested); it
covers wind only (no current, no wave speed loss). :func:`evidence_index` (and :func:`evidence_point`, one point)
classify a failure model's quantities as :meth:`~pyroute_rel.reliability.failure.FailureModel.evidence_index` does;
:func:`judge_tables` gives a model's tables as the kernels take them. The compiled march
(:mod:`pyroute_rel._kernels.march`) is built from these.

Imported only by routes over gridded weather, which load numba anyway: its import costs half a second,
which the default routes do not pay.

Numpy twin: :func:`pyroute_rel.routing.cost._sample_speeds` and
:meth:`~pyroute_rel.reliability.failure.FailureModel.evidence_index`; pinned by
``tests/test_cost.py::test_compiled_wind_kernel_is_bit_identical_to_numpy`` (and the march's tests).
"""

from __future__ import annotations

import math
from typing import Any

import numba
import numpy as np
import numpy.typing as npt

from pyroute_rel._kernels import polar as polar_compiled
from pyroute_rel._kernels.polar import SHORT_AXIS, blend, fold_twa, sub_time, table_edges
from pyroute_rel.boat.polar import MIN_SPEED_KN, Polar, check_beyond
from pyroute_rel.reliability.failure import QUANTITY_FIELDS, FailureModel
from pyroute_rel.store import kept_by
from pyroute_rel.weather.base import Conditions

__all__ = ["evidence_index", "evidence_point", "judge_tables", "sail_wind"]

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
    beyond : Polar behaviour outside its table, one of :data:`~pyroute_rel.boat.polar.BEYOND_MODES`.

    Returns
    -------
    ``twa_deg`` in [0, 180] and ``speed_kn`` (NaN where the wind is missing), and ``time_h`` (``inf`` where the
    wind is missing or the speed is below :data:`~pyroute_rel.boat.polar.MIN_SPEED_KN`: the numpy kernel's time
    without a failure model).
    """
    check_beyond(beyond)
    shape = tws_kn.shape
    if not (twd_deg.shape == shape and course_deg.shape == shape and seg_nm.shape == shape[:-1] + (1,)):
        shape = np.broadcast_shapes(tws_kn.shape, twd_deg.shape, course_deg.shape, seg_nm.shape)
    # contiguous, writable float64 everywhere (one compiled signature: a read-only array would be another); an
    # input of the full shape is passed as it is when it already is that (no copy), and the sub-segment lengths
    # of shape (..., 1) (one per arc, the geometry's) are passed once per arc, each used for ``every`` points
    tws, twd, course = (_flat(a, shape) for a in (tws_kn, twd_deg, course_deg))
    every = 1
    if shape and seg_nm.shape == shape[:-1] + (1,) and shape[-1] > 1:
        seg, every = _vector(seg_nm, np.float64), shape[-1]
    else:
        seg = _flat(seg_nm, shape)
    twa, v, dt = (np.empty(tws.size) for _ in range(3))
    tables = polar_compiled.finder_tables(polar)
    _wind_kernel(tws, twd, course, seg, every, *tables, beyond == "forbid", MIN_SPEED_KN, twa, v, dt)
    return twa.reshape(shape), v.reshape(shape), dt.reshape(shape)


def evidence_index(
    model: FailureModel, conditions: Conditions, course_deg: FloatArray
) -> tuple[npt.NDArray[np.intp], npt.NDArray[np.bool_] | None]:
    """:meth:`FailureModel.evidence_index <pyroute_rel.reliability.failure.FailureModel.evidence_index>` of the
    quantities :func:`pyroute_rel.reliability.failure.arc_quantities` makes of the weather ``conditions`` on
    ``course_deg`` [deg] (no current: the heading is the course), in one compiled loop: each quantity's field, or its
    angle to the course (:func:`~pyroute_rel._kernels.polar.fold_twa`, the TWA :func:`sail_wind` gives), classified as
    the model's numpy rules classify it (the same flat index and unknown points;
    :meth:`~pyroute_rel.reliability.failure.FailureModel.evidence_rules`).

    Returns
    -------
    ``(index, unknown)`` with ``course_deg``'s shape; ``unknown`` None where no point's evidence is unknown.
    """
    shape = course_deg.shape
    edges, n_edges, contrib, right, fill, attrs, relative = model_rules(model)
    values = np.empty((len(attrs), math.prod(shape)))
    for row, attr in zip(values, attrs, strict=True):
        value = getattr(conditions, attr)
        row[:] = (value if value.shape == shape else np.broadcast_to(value, shape)).reshape(-1)
    index = np.empty(values.shape[1], dtype=np.intp)
    unknown = np.empty(values.shape[1], dtype=np.bool_)
    course = _flat(course_deg, shape)
    lost = _evidence_kernel(values, relative, course, edges, n_edges, contrib, right, fill, index, unknown)
    return index.reshape(shape), unknown.reshape(shape) if lost else None


def model_rules(model: FailureModel) -> tuple[Any, ...]:
    """:meth:`~pyroute_rel.reliability.failure.FailureModel.evidence_rules` of a model, followed by each criterion's
    :class:`~pyroute_rel.weather.Conditions` field and whether it is taken relative to the course
    (:data:`~pyroute_rel.reliability.failure.QUANTITY_FIELDS`), made once and kept by the model
    (:func:`~pyroute_rel.store.kept_by`)."""

    def make() -> tuple[Any, ...]:
        sources = [QUANTITY_FIELDS[c.quantity] for c in model.criteria]
        relative = np.array([rel for _, rel in sources], dtype=np.bool_)
        return (*model.evidence_rules(), tuple(attr for attr, _ in sources), relative)

    return kept_by(model, "_kernel_rules", make)  # type: ignore[no-any-return]


def judge_tables(model: FailureModel, apf: float) -> tuple[FloatArray, npt.NDArray[np.bool_], npt.NDArray[np.uint32]]:
    """A model's table (:attr:`~pyroute_rel.reliability.failure.FailureModel.p_flat`), its entries above ``apf`` and its
    fired criteria (:attr:`~pyroute_rel.reliability.failure.FailureModel.fired_bits_flat`), as :func:`judge_samples`
    takes them (contiguous, writable copies), made once per model and apf (the DP costs every rank with the same) and
    kept by the model (:func:`~pyroute_rel.store.kept_by`)."""
    per_apf: dict[float, Any] = kept_by(model, "_kernel_judge", dict)
    tables = per_apf.get(apf)
    if tables is None:
        p_flat = np.array(model.p_flat, dtype=np.float64)
        bits = np.array(model.fired_bits_flat, dtype=np.uint32)
        tables = per_apf[apf] = (p_flat, np.array(p_flat > apf, dtype=np.bool_), bits)
    return tables


@numba.njit(nogil=True, cache=True)
def _evidence_kernel(values, relative, course, edges, n_edges, contrib, right, fill, index_out, unknown_out):  # type: ignore[no-untyped-def]  # pragma: no cover
    """:func:`evidence_index` into the outputs (:func:`evidence_point` point by point); returns whether any point's
    evidence is unknown."""
    any_lost = False
    for k in range(values.shape[1]):
        e, lost = evidence_point(values[:, k], relative, course[k], edges, n_edges, contrib, right, fill)
        index_out[k] = e
        unknown_out[k] = lost
        any_lost |= lost
    return any_lost


@numba.njit(nogil=True, cache=True, inline="always")
def evidence_point(values, relative, course, edges, n_edges, contrib, right, fill):  # type: ignore[no-untyped-def]  # pragma: no cover
    """One point's flat evidence index and whether it is unknown. Per criterion ``c``: the value ``values[c]``
    (folded to its angle to ``course`` [deg] where ``relative[c]``), its bin (the edges below it, or at or below with
    ``right``: numpy's searchsorted; NaN: the fill, or unknown in the last bin, the first with one edge, as numpy
    classifies a NaN) and that bin's contribution, summed over the criteria."""
    e = 0
    lost = False
    for c in range(values.size):
        x = values[c]
        if relative[c]:
            x = fold_twa(x, course)
        m = n_edges[c]
        if x != x:
            if fill[c] >= 0:
                e += fill[c]
                continue
            lost = True
            b = 0 if m == 1 else m
        else:
            b = 0
            for j in range(m):
                b += (edges[c, j] <= x) if right[c] else (edges[c, j] < x)
        e += contrib[c, b]
    return e, lost


def _flat(a: npt.NDArray[Any], shape: tuple[int, ...], dtype: Any = np.float64) -> npt.NDArray[Any]:
    """``a`` broadcast to ``shape`` as a contiguous, writable vector of ``dtype`` (copied only if it is not one)."""
    if a.shape != shape:
        a = np.broadcast_to(a, shape)  # read-only: copied
    return _vector(a, dtype)


def _vector(a: npt.NDArray[Any], dtype: Any) -> npt.NDArray[Any]:
    """``a`` as a contiguous, writable vector of ``dtype``: a view where it is one (the kernels' one signature), else
    a copy (what ``np.require(a, dtype, ("C", "W"))`` gives, without its cost per call in the DP's loop)."""
    if a.dtype == dtype and a.flags.c_contiguous and a.flags.writeable:
        return a.reshape(-1)
    return np.require(a, dtype, ("C", "W")).reshape(-1)


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
    twa_finder,
    tws_finder,
    forbid,
    min_speed,
    twa_out,
    v_out,
    dt_out,
):  # type: ignore[no-untyped-def]  # pragma: no cover
    """One point at a time: fold TWA, bilinear polar, then ``seg / speed`` or ``inf`` (missing wind, no speed)
    (:mod:`pyroute_rel._kernels.polar`), in the numpy path's order of operations; points ``i * every`` to
    ``(i + 1) * every - 1`` sail ``seg[i]``. The table is read here (cells as :func:`~pyroute_rel._kernels.polar.cell`
    finds them: counted on short axes, from the axes' :func:`~pyroute_rel._kernels.polar.cell_finder` on long ones),
    and only scalars passed to the inlined helpers: an array passed to one is reference-counted at every point,
    which doubled the kernel's time."""
    a0, a_scale, a_last, a_lower = twa_finder
    w0, w_scale, w_last, w_lower = tws_finder
    n_tws = tws_tab.size
    top_a = twa_tab.size - 2
    top_w = n_tws - 2
    tws_first, twa_first = tws_tab[0], twa_tab[0]
    twa_last, tws_last = twa_tab[twa_tab.size - 1], tws_tab[n_tws - 1]
    short_a, short_w = top_a <= SHORT_AXIS, top_w <= SHORT_AXIS
    un, one = np.uint64(n_tws), np.uint64(1)  # table indices unsigned: no negative-index wraparound
    for i in range(tws.size // every):  # arc by arc (no division per point)
        s = seg[i]
        for k in range(i * every, (i + 1) * every):
            a = fold_twa(twd[k], course[k])
            twa_out[k] = a
            w = tws[k]
            v = np.nan
            if a == a and w == w:
                ia = jw = 0
                if short_a:  # count the inner rows at or below: no branch, no dependent load
                    for m in range(1, top_a + 1):
                        ia += twa_tab[m] <= a
                else:  # a first cell from the finder, stepped up
                    ia = a_lower[int(min(max((a - a0) * a_scale, 0.0), a_last))]
                    while ia < top_a and twa_tab[ia + 1] <= a:
                        ia += 1
                if short_w:
                    for m in range(1, top_w + 1):
                        jw += tws_tab[m] <= w
                else:
                    jw = w_lower[int(min(max((w - w0) * w_scale, 0.0), w_last))]
                    while jw < top_w and tws_tab[jw + 1] <= w:
                        jw += 1
                ua, uw = np.uint64(ia), np.uint64(jw)
                c = ua * un + uw
                v = blend(
                    a,
                    w,
                    twa_tab[ua],
                    twa_tab[ua + one],
                    tws_tab[uw],
                    tws_tab[uw + one],
                    speed_tab[c],
                    speed_tab[c + one],
                    speed_tab[c + un],
                    speed_tab[c + un + one],
                    tws_first,
                )
            v = table_edges(v, a, w, twa_first, twa_last, tws_last, forbid)
            v_out[k] = v
            dt_out[k] = sub_time(s, v, w, twd[k], min_speed)[0]
