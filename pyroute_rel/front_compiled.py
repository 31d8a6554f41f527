"""Compiled reduction of a rank's labels to the non-dominated ones, for the voyage front (issue 20).

:func:`~pyroute_rel.tradeoff.voyage_front` extends every label of a rank along every arc out of its node, then keeps
at each node the candidates (arrival time, hazard) no other candidate there dominates. :func:`nondominated` does that
in one compiled pass: the candidates are bucketed by node (a counting sort, stable), each node's are ordered by time,
of a run of equal times only the first given of the smallest hazard can be kept, and it is kept when its hazard is
below every hazard kept before it at its node (a running minimum). The result is that of sorting all candidates by
(node, time, hazard, position) and keeping the running minima, without sorting a million keys three times (tested
against pairwise dominance).

numba is imported only by the voyage front.
"""

from __future__ import annotations

import numba
import numpy as np
import numpy.typing as npt

__all__ = ["nondominated", "extend_steady"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.intp]


def nondominated(node: npt.ArrayLike, t: npt.ArrayLike, h: npt.ArrayLike, n_nodes: int) -> IntArray:
    """Indices of the candidates no other candidate at the same node dominates, sorted by node then time.

    Parameters
    ----------
    node : Each candidate's node, in ``[0, n_nodes)``.
    t : Arrival times [h].
    h : Hazards [-] (not NaN; ``inf`` allowed).
    n_nodes : Number of nodes (> every node).

    Returns
    -------
    The kept candidates' indices: ordered by (node, time); of candidates with equal time and hazard at a node, the
    first given; a candidate is kept when its hazard is strictly below that of every candidate before it at its node.

    Examples
    --------
    >>> nondominated([1, 0, 1, 1, 0], [2.0, 1.0, 1.0, 3.0, 1.0], [1.0, 5.0, 2.0, 0.5, 5.0], 2).tolist()
    [1, 2, 0, 3]
    """
    nd = np.ascontiguousarray(node, dtype=np.int64)
    tt = np.ascontiguousarray(t, dtype=np.float64)
    hh = np.ascontiguousarray(h, dtype=np.float64)
    if nd.size == 0:
        return np.zeros(0, dtype=np.intp)
    return np.asarray(_nondominated(nd, tt, hh, int(n_nodes)), dtype=np.intp)


@numba.njit(nogil=True, cache=True)
def _nondominated(node, t, h, n_nodes):  # type: ignore[no-untyped-def]  # pragma: no cover - compiled
    n = node.size
    start = np.zeros(n_nodes + 1, dtype=np.int64)
    for i in range(n):
        start[node[i] + 1] += 1
    for j in range(n_nodes):
        start[j + 1] += start[j]
    fill = start[:-1].copy()
    order = np.empty(n, dtype=np.int64)
    for i in range(n):  # stable counting sort by node
        order[fill[node[i]]] = i
        fill[node[i]] += 1
    keep = np.empty(n, dtype=np.int64)
    n_keep = 0
    for j in range(n_nodes):
        s, e = start[j], start[j + 1]
        if e == s:
            continue
        idx = order[s:e]
        tg = t[idx]
        idx = idx[np.argsort(tg)]  # by time (ties are settled below, whatever their order here)
        m = 0
        first = True
        best = np.inf
        while m < idx.size:  # a run of equal times: only the first given of its smallest hazard may be kept
            pick = idx[m]
            m += 1
            while m < idx.size and t[idx[m]] == t[pick]:
                i = idx[m]
                if h[i] < h[pick] or (h[i] == h[pick] and i < pick):
                    pick = i
                m += 1
            if first or h[pick] < best:
                keep[n_keep] = pick
                n_keep += 1
                best = h[pick]
                first = False
    return keep[:n_keep]


def extend_steady(
    label_t: FloatArray,
    label_h: FloatArray,
    label_start: npt.NDArray[np.int64],
    arc_start: npt.NDArray[np.int64],
    arc_src: npt.NDArray[np.int64],
    arc_t: FloatArray,
    arc_h: FloatArray,
) -> tuple[IntArray, FloatArray, FloatArray, IntArray]:
    """Every label extended along every arc, then :func:`nondominated` at each destination node, in one pass without
    the candidates laid out (steady weather: an arc adds the same time and hazard to every label it extends).

    Parameters
    ----------
    label_t, label_h : The previous rank's labels, sorted by node: arrival [h] and hazard [-].
    label_start : Where each source node's labels start in them (one more entry than source nodes).
    arc_start : Where each destination node's arcs start (one more entry than destination nodes).
    arc_src : Each arc's source node.
    arc_t, arc_h : Each arc's time [h] and hazard [-].

    Returns
    -------
    node, t, h, parent
        The kept labels, sorted by node then time; ``parent`` the label each extends. The same as
        :func:`nondominated` on the candidates laid out arc by arc, each arc's labels in order.
    """
    args = [np.ascontiguousarray(a, dtype=np.float64) for a in (label_t, label_h, arc_t, arc_h)]
    starts = [np.ascontiguousarray(a, dtype=np.int64) for a in (label_start, arc_start, arc_src)]
    node, t, h, parent = _extend_steady(args[0], args[1], starts[0], starts[1], starts[2], args[2], args[3])
    return node.astype(np.intp), t, h, parent.astype(np.intp)


@numba.njit(nogil=True, cache=True)
def _extend_steady(label_t, label_h, label_start, arc_start, arc_src, arc_t, arc_h):  # type: ignore[no-untyped-def]  # pragma: no cover - compiled
    n_dest = arc_start.size - 1
    total = 0
    for a in range(arc_src.size):
        total += label_start[arc_src[a] + 1] - label_start[arc_src[a]]
    out_node = np.empty(total, dtype=np.int64)
    out_t = np.empty(total)
    out_h = np.empty(total)
    out_parent = np.empty(total, dtype=np.int64)
    n_out = 0
    biggest = 0
    for j in range(n_dest):
        n = 0
        for a in range(arc_start[j], arc_start[j + 1]):
            n += label_start[arc_src[a] + 1] - label_start[arc_src[a]]
        biggest = max(biggest, n)
    ct = np.empty(biggest)
    ch = np.empty(biggest)
    cp = np.empty(biggest, dtype=np.int64)
    for j in range(n_dest):
        n = 0
        for a in range(arc_start[j], arc_start[j + 1]):  # the candidates into node j, arc by arc
            s = arc_src[a]
            for lab in range(label_start[s], label_start[s + 1]):
                ct[n] = label_t[lab] + arc_t[a]
                ch[n] = label_h[lab] + arc_h[a]
                cp[n] = lab
                n += 1
        if n == 0:
            continue
        idx = np.argsort(ct[:n])  # by time (ties are settled below, whatever their order here)
        m = 0
        first = True
        best = np.inf
        while m < n:  # a run of equal times: only the first given of its smallest hazard may be kept
            pick = idx[m]
            m += 1
            while m < n and ct[idx[m]] == ct[pick]:
                i = idx[m]
                if ch[i] < ch[pick] or (ch[i] == ch[pick] and i < pick):
                    pick = i
                m += 1
            if first or ch[pick] < best:
                out_node[n_out] = j
                out_t[n_out] = ct[pick]
                out_h[n_out] = ch[pick]
                out_parent[n_out] = cp[pick]
                n_out += 1
                best = ch[pick]
                first = False
    return out_node[:n_out], out_t[:n_out], out_h[:n_out], out_parent[:n_out]
