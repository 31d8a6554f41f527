"""Compiled twin of one rank of the forward DP, for steady wind-only problems (issue 18).

Where the arc costs need nothing but the wind (steady weather, no failure model, wave speed loss, current, obstacle
mask, waiting or finish line), :func:`~pyroute_rel.solve.forward_dp` hands each rank to :func:`rank_step`: one
compiled loop over the arcs into each node that does what the numpy path does operation for operation -- TWA,
bilinear polar speed, time per sub-segment (the arithmetic of :func:`pyroute_rel.cost_compiled.sail_wind`), the
arc's reason flags, pruning (each node's four arcs of smallest lower bound first, then every arc whose bound does
not exceed the best of them, see ``RoutingProblem.prune``), the arrival from each source label with the time of a
change of side (:mod:`pyroute_rel.manoeuvre`: labels (node, side), the plain DP being the case of one label) and
the earliest arrival at each label -- without a temporary array per step. Its results are bit-identical to the
numpy path's (arrival times, back-pointers, labels, counts; property-tested); only the weather (and each arc's side
and manoeuvre time) is still computed in numpy, once per arc sample.

Kernels take contiguous, writable float64 arrays (one compiled signature). numba is imported only by problems this
path serves.
"""

from __future__ import annotations

import numba
import numpy as np
import numpy.typing as npt

from .manoeuvre import ManoeuvrePenalties
from .polar import MIN_SPEED_KN, Polar

__all__ = ["rank_step"]

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]


def rank_step(
    tws_kn: FloatArray,
    twd_deg: FloatArray,
    course_deg: FloatArray,
    seg_nm: FloatArray,
    t_prev: FloatArray,
    src: npt.NDArray[np.intp],
    valid: npt.NDArray[np.bool_],
    polar: Polar,
    *,
    beyond: str,
    bound_kn: float | None,
    from_sides: tuple[int, ...] = (-1,),
    penalties: ManoeuvrePenalties | None = None,
) -> tuple[
    FloatArray, npt.NDArray[np.intp], npt.NDArray[np.intp], npt.NDArray[np.uint8], npt.NDArray[np.bool_], BoolArray
]:
    """One rank of the DP: the earliest arrival at each label [h] and the arc and source label it comes by.

    Parameters
    ----------
    tws_kn, twd_deg : Wind speed [kn] and direction (from) [deg] at the arcs' samples, shape (nodes, arcs, samples).
    course_deg : Great-circle course at the samples [deg], same shape.
    seg_nm : Sub-segment length of each arc [nm], shape (nodes, arcs) (the geometry's ``seg_nm[..., 0]``).
    t_prev : Arrival at each label of the previous rank [h] (inf: not reached), shape (source nodes, source labels).
    src, valid : Source node of each arc and whether it exists, shape (nodes, arcs) (``grid.pattern(k)``).
    polar : Boat polar.
    beyond : Polar behaviour outside its table (``"clamp"`` or ``"forbid"``).
    bound_kn : Fastest speed over ground possible [kn], to prune with (``RoutingProblem.prune``; with side labels
        each label's arcs are pruned against that label's best, which the numpy path does not do: it then costs
        every arc, so ``arcs_evaluated`` differs, never the result); None costs every live arc.
    from_sides : Side of each source label (-1: none, no manoeuvre is counted from it).
    penalties : With side labels (:mod:`pyroute_rel.manoeuvre`), the time tacks and gybes cost: each arc's side,
        manoeuvre and its time come from the wind at its first sample, as :func:`~pyroute_rel.manoeuvre.wind_side`,
        :func:`~pyroute_rel.manoeuvre.manoeuvre_kind` and
        :meth:`~pyroute_rel.manoeuvre.ManoeuvrePenalties.penalty_h` compute them (``numpy.interp``'s arithmetic).
        None: one label per node.

    Returns
    -------
    ``t_best`` [h] (inf where no arc arrives), ``j_best`` the arc index and ``c_best`` the source label (first arc,
    then first source label, of equal ones; 0 where none), all of shape (nodes, labels); the reason flags of each
    costed arc (:data:`~pyroute_rel.cost.REASONS`; 0 elsewhere), which arcs were costed and which were live (leave a
    reached label).
    """
    n_dst, width = seg_nm.shape
    n_out = 1 if penalties is None else 2

    def c(a: npt.ArrayLike) -> FloatArray:
        return np.require(a, np.float64, ("C", "W"))

    tables = [c(t).reshape(-1) for t in (polar.twa_deg, polar.tws_kn, polar.speed_kn)]
    p = penalties or ManoeuvrePenalties()
    pen = [c(np.asarray(t, dtype=float)) for t in (p.tack_tws_kn, p.tack_penalty_s, p.gybe_tws_kn, p.gybe_penalty_s)]
    t_best = np.empty((n_dst, n_out))
    j_best = np.empty((n_dst, n_out), dtype=np.intp)
    c_best = np.empty((n_dst, n_out), dtype=np.intp)
    reason = np.zeros((n_dst, width), dtype=np.uint8)
    counted = np.zeros((n_dst, width), dtype=np.bool_)
    live = np.zeros((n_dst, width), dtype=np.bool_)
    _rank_kernel(  # type: ignore[call-arg]
        c(tws_kn),
        c(twd_deg),
        c(course_deg),
        c(seg_nm),
        c(t_prev),
        np.require(src, np.intp, ("C", "W")),
        np.require(valid, np.bool_, ("C", "W")),
        *tables,
        beyond == "forbid",
        MIN_SPEED_KN,
        -1.0 if bound_kn is None else float(bound_kn),
        np.asarray(from_sides, dtype=np.int64),
        *pen,
        t_best,
        j_best,
        c_best,
        reason,
        counted,
        live,
    )
    return t_best, j_best, c_best, reason, counted, live


@numba.njit(nogil=True, cache=True)
def _arc_time(tws, twd, course, seg, d, a, twa_tab, tws_tab, speed_tab, forbid, min_speed):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Sailing time of arc (d, a) [h] and its reason flags (1: no speed, 2: missing wind), as the numpy cost kernel
    computes them: per sample the TWA, bilinear polar and ``seg / speed``, summed over the samples in order."""
    n_twa = twa_tab.size
    n_tws = tws_tab.size
    samples = tws.shape[2]
    total = 0.0
    flags = 0
    for s in range(samples):
        w = tws[d, a, s]
        wd = twd[d, a, s]
        ang = abs(wd - course[d, a, s])
        if ang > 360.0:
            ang = ang % 360.0
        ang = min(ang, 360.0 - ang)
        v = np.nan
        if ang == ang and w == w:
            i = 0
            for m in range(1, n_twa - 1):
                i += twa_tab[m] <= ang
            j = 0
            for m in range(1, n_tws - 1):
                j += tws_tab[m] <= w
            fa = (ang - twa_tab[i]) / (twa_tab[i + 1] - twa_tab[i])
            fa = min(max(fa, 0.0), 1.0)
            fw = (w - tws_tab[j]) / (tws_tab[j + 1] - tws_tab[j])
            fw = min(max(fw, 0.0), 1.0)
            cell = i * n_tws + j
            gw = 1.0 - fw
            low = speed_tab[cell] * gw + speed_tab[cell + 1] * fw
            high = speed_tab[cell + n_tws] * gw + speed_tab[cell + n_tws + 1] * fw
            v = high * fa - low * (fa - 1.0)
            if tws_tab[0] > 0.0 and w < tws_tab[0]:
                v *= w / tws_tab[0]
        if twa_tab[0] > 0.0 and ang < twa_tab[0]:
            v = 0.0
        if forbid and (ang > twa_tab[n_twa - 1] or w > tws_tab[n_tws - 1]):
            v = 0.0
        if not (np.isfinite(w) and np.isfinite(wd)):
            flags |= 2
            dt = np.inf
        elif v >= min_speed:
            dt = seg[d, a] / v
        else:
            flags |= 1
            dt = np.inf
        total = dt if s == 0 else total + dt
    if flags != 0:
        total = np.inf
    return total, flags


@numba.njit(nogil=True, cache=True)
def _arrival(t0, t, from_side, side, change):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Arrival over an arc left at ``t0`` taking ``t`` [h], in the numpy path's order of additions: a change of side
    from a source label with a side adds ``change`` after the sailing time (inf where ``t0`` is)."""
    if from_side < 0:
        return t0 + t
    return (t0 + t) + (change if side != from_side else 0.0)


@numba.njit(nogil=True, cache=True)
def _rank_kernel(  # type: ignore[no-untyped-def]  # pragma: no cover
    tws, twd, course, seg, t_prev, src, valid, twa_tab, tws_tab, speed_tab, forbid, min_speed, bound, from_sides,
    tack_x, tack_y, gybe_x, gybe_y, t_best, j_best, c_best, reason, counted, live,
):  # fmt: skip
    """Per node: the arcs' departures from each source label, prune (when ``bound`` > 0, for each label: the four
    arcs of smallest lower bound into it, then those whose bound does not exceed the best arrival over them) or cost
    every live arc, and keep the first earliest arrival at each label."""
    n_dst, width = seg.shape
    n_in = t_prev.shape[1]
    polar = (twa_tab, tws_tab, speed_tab, forbid, min_speed)
    times = np.empty(width)
    t_src = np.empty((width, n_in))
    side = np.zeros(width, dtype=np.int8)
    up = np.zeros(width, dtype=np.bool_)
    change = np.zeros(width)
    pen = (tack_x, tack_y, gybe_x, gybe_y)
    n_out = t_best.shape[1]
    for d in range(n_dst):
        if n_out == 2:
            _sides(twd, course, d, side, up)
        for a in range(width):
            for c in range(n_in):
                t_src[a, c] = t_prev[src[d, a], c] if valid[d, a] else np.inf
                if np.isfinite(t_src[a, c]):
                    live[d, a] = True
        if bound > 0.0:
            _prune_and_cost(tws, twd, course, seg, t_src, polar, bound, from_sides, side, up, pen, change, d, live[d],
                            times, reason, counted, n_out)  # fmt: skip
        else:
            for a in range(width):
                if live[d, a]:
                    counted[d, a] = True
                    t, f = _arc_time(tws, twd, course, seg, d, a, *polar)
                    reason[d, a] = f
                    times[a] = t
        if n_out == 2:  # the manoeuvre's time, where an arc can be sailed
            for a in range(width):
                if counted[d, a] and reason[d, a] == 0:
                    change[a] = _change(tws, d, a, up, *pen)
        _best_labels(t_src, from_sides, side, change, d, times, reason, counted, t_best, j_best, c_best)


@numba.njit(nogil=True, cache=True)
def _interp(x, xp, fp):  # type: ignore[no-untyped-def]  # pragma: no cover
    """``numpy.interp(x, xp, fp)`` for one finite ``x``, in numpy's arithmetic (constant beyond the ends)."""
    n = xp.size
    if n == 1 or x <= xp[0]:
        return fp[0]
    if x >= xp[n - 1]:
        return fp[n - 1]
    j = 0
    while xp[j + 1] <= x:
        j += 1
    if xp[j] == x:
        return fp[j]
    slope = (fp[j + 1] - fp[j]) / (xp[j + 1] - xp[j])
    out = slope * (x - xp[j]) + fp[j]
    if out != out:
        out = slope * (x - xp[j + 1]) + fp[j + 1]
        if out != out and fp[j] == fp[j + 1]:
            out = fp[j]
    return out


@numba.njit(nogil=True, cache=True)
def _sides(twd, course, d, side, up):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Side of each arc into node ``d`` and whether a change of side onto it is a tack (upwind of the beam), from
    the wind direction and course at its first sample: :func:`~pyroute_rel.manoeuvre.wind_side` and
    :func:`~pyroute_rel.manoeuvre.manoeuvre_kind`, operation for operation."""
    for a in range(side.size):
        rel = np.mod(twd[d, a, 0] - course[d, a, 0], 360.0)
        side[a] = 1 if rel < 180.0 or rel != rel else 0  # NaN: starboard
        up[a] = min(rel, 360.0 - rel) < 90.0


@numba.njit(nogil=True, cache=True)
def _change(tws, d, a, up, tack_x, tack_y, gybe_x, gybe_y):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The time a change of side onto arc (d, a) costs [h]:
    :meth:`~pyroute_rel.manoeuvre.ManoeuvrePenalties.tables_h` of the wind speed at its first sample."""
    w = tws[d, a, 0]
    w = w if np.isfinite(w) else 0.0
    if up[a]:
        return _interp(w, tack_x, tack_y) / 3600.0
    return _interp(w, gybe_x, gybe_y) / 3600.0


@numba.njit(nogil=True, cache=True)
def _prune_and_cost(  # type: ignore[no-untyped-def]  # pragma: no cover
    tws, twd, course, seg, t_src, polar, bound, from_sides, side, up, pen, change, d, live, times, reason, counted,
    n_out,
):  # fmt: skip
    """Node ``d``'s arcs that can still win, costed: per label (an arc's side is known before it is costed) the four
    of smallest lower bound, then every one whose bound does not exceed the best arrival over those four (ties:
    lowest index; the numpy path's argpartition may pick another of equal bounds, which changes which arcs are
    costed, never the result)."""
    width = seg.shape[1]
    samples = tws.shape[2]
    n_in = t_src.shape[1]
    lower = np.full(width, np.inf)
    for a in range(width):
        for c in range(n_in):
            if np.isfinite(t_src[a, c]):
                lower[a] = min(lower[a], t_src[a, c] + seg[d, a] * samples / bound)
    for s in range(n_out):
        best_first = np.inf
        for _ in range(4):
            m = -1
            for a in range(width):
                mine = n_out == 1 or side[a] == s
                if mine and live[a] and not counted[d, a] and (m < 0 or lower[a] < lower[m]):
                    m = a
            if m < 0:
                break
            counted[d, m] = True
            t, f = _arc_time(tws, twd, course, seg, d, m, *polar)
            reason[d, m] = f
            times[m] = t
            if n_out == 2:
                change[m] = _change(tws, d, m, up, *pen)
            for c in range(n_in):
                tot = _arrival(t_src[m, c], t, from_sides[c], side[m], change[m])
                if f == 0 and tot < best_first:
                    best_first = tot
        for a in range(width):
            mine = n_out == 1 or side[a] == s
            if mine and live[a] and not counted[d, a] and lower[a] <= best_first:
                counted[d, a] = True
                t, f = _arc_time(tws, twd, course, seg, d, a, *polar)
                reason[d, a] = f
                times[a] = t


@numba.njit(nogil=True, cache=True)
def _best_labels(t_src, from_sides, side, change, d, times, reason, counted, t_best, j_best, c_best):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The earliest arrival at each label of node ``d``: source labels in order, arcs in order, first of equal
    ones."""
    width = times.size
    n_out = t_best.shape[1]
    for s in range(n_out):
        t_best[d, s] = np.inf
        j_best[d, s] = 0
        c_best[d, s] = 0
    for c in range(t_src.shape[1]):
        for a in range(width):
            t0 = t_src[a, c]
            if counted[d, a] and reason[d, a] == 0 and np.isfinite(t0):
                tot = _arrival(t0, times[a], from_sides[c], side[a], change[a])
                s = side[a] if n_out == 2 else 0
                if tot < t_best[d, s]:
                    t_best[d, s] = tot
                    j_best[d, s] = a
                    c_best[d, s] = c
