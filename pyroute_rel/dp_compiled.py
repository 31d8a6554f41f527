"""Compiled twin of one rank of the forward DP, for steady wind-only problems (issue 18).

Where the arc costs need nothing but the wind (steady weather, no failure model, wave speed loss, current, obstacle
mask, waiting, finish line or manoeuvre state), :func:`~pyroute_rel.solve.forward_dp` hands each rank to
:func:`rank_step`: one compiled loop over the arcs into each node that does what the numpy path does operation for
operation -- TWA, bilinear polar speed, time per sub-segment (the arithmetic of
:func:`pyroute_rel.cost_compiled.sail_wind`), the arc's reason flags, pruning (each node's four arcs of smallest lower
bound first, then every arc whose bound does not exceed the best of them, see ``RoutingProblem.prune``), the arrival
and the earliest one -- without a temporary array per step. Its results are bit-identical to the numpy path's
(arrival times, back-pointers, counts; property-tested); only the weather is still sampled in numpy, once per arc
sample.

Kernels take contiguous, writable float64 arrays (one compiled signature). numba is imported only by problems this
path serves.
"""

from __future__ import annotations

import numba
import numpy as np
import numpy.typing as npt

from .polar import MIN_SPEED_KN, Polar

__all__ = ["rank_step"]

FloatArray = npt.NDArray[np.float64]


def rank_step(
    tws_kn: FloatArray,
    twd_deg: FloatArray,
    course_deg: FloatArray,
    seg_nm: FloatArray,
    t_src: FloatArray,
    live: npt.NDArray[np.bool_],
    polar: Polar,
    *,
    beyond: str,
    bound_kn: float | None,
) -> tuple[FloatArray, npt.NDArray[np.intp], npt.NDArray[np.uint8], npt.NDArray[np.bool_]]:
    """One rank of the DP: the earliest arrival at each node [h] and the arc it comes by.

    Parameters
    ----------
    tws_kn, twd_deg : Wind speed [kn] and direction (from) [deg] at the arcs' samples, shape (nodes, arcs, samples).
    course_deg : Great-circle course at the samples [deg], same shape.
    seg_nm : Sub-segment length of each arc [nm], shape (nodes, arcs) (the geometry's ``seg_nm[..., 0]``).
    t_src : Departure time of each arc [h] (ignored where not live), shape (nodes, arcs).
    live : Arcs that exist and leave a reached node, shape (nodes, arcs).
    polar : Boat polar.
    beyond : Polar behaviour outside its table (``"clamp"`` or ``"forbid"``).
    bound_kn : Fastest speed over ground possible [kn], to prune with (``RoutingProblem.prune``); None costs every
        live arc.

    Returns
    -------
    ``t_best`` [h] (inf where no arc arrives), ``j_best`` the arc index (first of equal ones; 0 where none), the
    reason flags of each costed arc (:data:`~pyroute_rel.cost.REASONS`; 0 elsewhere) and which arcs were costed.
    """
    shape = live.shape

    def c(a: npt.ArrayLike) -> FloatArray:
        return np.require(a, np.float64, ("C", "W"))

    tables = [c(t).reshape(-1) for t in (polar.twa_deg, polar.tws_kn, polar.speed_kn)]
    t_best = np.empty(shape[0])
    j_best = np.empty(shape[0], dtype=np.intp)
    reason = np.zeros(shape, dtype=np.uint8)
    counted = np.zeros(shape, dtype=np.bool_)
    _rank_kernel(  # type: ignore[call-arg]
        c(tws_kn),
        c(twd_deg),
        c(course_deg),
        c(seg_nm),
        c(t_src),
        np.require(live, np.bool_, ("C", "W")),
        *tables,
        beyond == "forbid",
        MIN_SPEED_KN,
        -1.0 if bound_kn is None else float(bound_kn),
        t_best,
        j_best,
        reason,
        counted,
    )
    return t_best, j_best, reason, counted


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
def _rank_kernel(  # type: ignore[no-untyped-def]  # pragma: no cover
    tws, twd, course, seg, t_src, live, twa_tab, tws_tab, speed_tab, forbid, min_speed, bound, t_best, j_best, reason,
    counted,
):  # fmt: skip
    """Per node: prune (when ``bound`` > 0: the four arcs of smallest lower bound, then those whose bound does not
    exceed the best of them), cost, and keep the first earliest arrival."""
    n_dst, width = live.shape
    samples = tws.shape[2]
    lower = np.empty(width)
    times = np.empty(width)
    for d in range(n_dst):
        if bound > 0.0:
            for a in range(width):
                lower[a] = t_src[d, a] + seg[d, a] * samples / bound if live[d, a] else np.inf
            # the four smallest bounds among live arcs (ties: lowest index; the numpy path's argpartition may pick
            # another of equal bounds, which changes which arcs are costed, never the result)
            best_first = np.inf
            for _ in range(4):
                m = -1
                for a in range(width):
                    if live[d, a] and not counted[d, a] and (m < 0 or lower[a] < lower[m]):
                        m = a
                if m < 0:
                    break
                counted[d, m] = True
                t, f = _arc_time(tws, twd, course, seg, d, m, twa_tab, tws_tab, speed_tab, forbid, min_speed)
                reason[d, m] = f
                times[m] = t
                tot = t_src[d, m] + t
                if tot < best_first:
                    best_first = tot
            for a in range(width):
                if live[d, a] and not counted[d, a] and lower[a] <= best_first:
                    counted[d, a] = True
                    t, f = _arc_time(tws, twd, course, seg, d, a, twa_tab, tws_tab, speed_tab, forbid, min_speed)
                    reason[d, a] = f
                    times[a] = t
        else:
            for a in range(width):
                if live[d, a]:
                    counted[d, a] = True
                    t, f = _arc_time(tws, twd, course, seg, d, a, twa_tab, tws_tab, speed_tab, forbid, min_speed)
                    reason[d, a] = f
                    times[a] = t
        # the earliest arrival over the costed arcs, first of equal ones
        bt = np.inf
        bj = 0
        for a in range(width):
            if counted[d, a] and reason[d, a] == 0:
                tot = t_src[d, a] + times[a]
                if tot < bt:
                    bt = tot
                    bj = a
        t_best[d] = bt
        j_best[d] = bj
