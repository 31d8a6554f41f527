"""Compiled reduction of a rank's labels to the non-dominated ones, for the voyage front (issue 20).

:func:`~pyroute_rel.routing.tradeoff.voyage_front` extends every label of a rank along every arc out of its node, then
keeps at each node the candidates (arrival time, hazard) no other candidate there dominates. :func:`nondominated` does
that in one compiled pass over candidates given in any order: the candidates are bucketed by node (a counting sort,
stable), each node's are ordered by time, of a run of equal times only the first given of the smallest hazard can be
kept, and it is kept when its hazard is below every hazard kept before it at its node (a running minimum). The result is
that of sorting all candidates by (node, time, hazard, position) and keeping the running minima, without sorting a
million keys three times (tested against pairwise dominance).

:func:`extend_steady` does the same for steady weather without sorting at all: an arc adds one time and one hazard to
every label of its source node, whose labels are already sorted by time (hazard strictly decreasing), so the
candidates an arc brings to a node are a sorted run. The runs into a node are merged (a binary heap over the in-arcs,
by time) and swept for the running minimum of hazard; after each kept label, every run it touched skips by bisection
the candidates whose hazard is not below it (hazards do not increase along a run), so dominated stretches are never
merged. The result is the same as :func:`nondominated` on every candidate laid out arc by arc (tested).

numba is imported only by the voyage front.

Numpy twin: pairwise dominance (the definition); pinned by
``tests/test_front_compiled.py::test_nondominated_equals_pairwise_dominance`` and
``::test_extend_steady_equals_candidates_laid_out``.
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
    the candidates laid out or sorted (steady weather: an arc adds the same time and hazard to every label it extends).

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
        :func:`nondominated` on the candidates laid out arc by arc, each arc's labels in order, provided each source
        node's labels are non-dominated and sorted by time (as this function and :func:`nondominated` return them):
        each arc's candidates are then a run sorted by time, and the runs are merged (module notes).
    """
    args = [np.ascontiguousarray(a, dtype=np.float64) for a in (label_t, label_h, arc_t, arc_h)]
    starts = [np.ascontiguousarray(a, dtype=np.int64) for a in (label_start, arc_start, arc_src)]
    node, t, h, parent = _extend_steady(args[0], args[1], starts[0], starts[1], starts[2], args[2], args[3])
    return node.astype(np.intp), t, h, parent.astype(np.intp)


@numba.njit(nogil=True, cache=True)
def _extend_steady(label_t, label_h, label_start, arc_start, arc_src, arc_t, arc_h):  # type: ignore[no-untyped-def]  # pragma: no cover - compiled
    n_dest = arc_start.size - 1
    total = 0
    width = 0
    for j in range(n_dest):
        n = 0
        for a in range(arc_start[j], arc_start[j + 1]):
            n += label_start[arc_src[a] + 1] - label_start[arc_src[a]]
        total += n
        width = max(width, arc_start[j + 1] - arc_start[j])
    out_node = np.empty(total, dtype=np.int64)
    out_t = np.empty(total)
    out_h = np.empty(total)
    out_parent = np.empty(total, dtype=np.int64)
    ptr = np.empty(width, dtype=np.int64)  # each in-arc's next label
    end = np.empty(width, dtype=np.int64)
    heap = np.empty(width, dtype=np.int64)  # in-arcs (local index) by the time of their next candidate
    key = np.empty(width)
    touched = np.empty(width, dtype=np.int64)
    n_out = 0
    for j in range(n_dest):
        a0 = arc_start[j]
        n_heap = 0
        for r in range(arc_start[j + 1] - a0):
            s = arc_src[a0 + r]
            ptr[r], end[r] = label_start[s], label_start[s + 1]
            if ptr[r] < end[r]:
                n_heap = _push(heap, key, n_heap, r, label_t[ptr[r]] + arc_t[a0 + r])
        first = True
        best = np.inf
        while n_heap > 0:  # the group of candidates of the smallest time: only the first given of its least hazard
            now = key[0]
            pick_h, pick_r, pick_lab = np.inf, -1, -1
            n_touched = 0
            while n_heap > 0 and key[0] == now:
                r = heap[0]
                n_heap = _pop(heap, key, n_heap)
                touched[n_touched] = r
                n_touched += 1
                a = a0 + r
                while ptr[r] < end[r] and label_t[ptr[r]] + arc_t[a] == now:
                    c = label_h[ptr[r]] + arc_h[a]
                    if (
                        pick_r < 0
                        or c < pick_h
                        or (c == pick_h and (r < pick_r or (r == pick_r and ptr[r] < pick_lab)))
                    ):
                        pick_h, pick_r, pick_lab = c, r, ptr[r]
                    ptr[r] += 1
            if first or pick_h < best:
                out_node[n_out] = j
                out_t[n_out] = now
                out_h[n_out] = pick_h
                out_parent[n_out] = pick_lab
                n_out += 1
                best = pick_h
                first = False
            for m in range(n_touched):  # skip the candidates that cannot be kept any more: their hazard >= best
                r = touched[m]
                a = a0 + r
                lo, hi = ptr[r], end[r]
                while lo < hi:  # hazards do not increase along a source's labels: bisect
                    mid = (lo + hi) // 2
                    if label_h[mid] + arc_h[a] < best:
                        hi = mid
                    else:
                        lo = mid + 1
                ptr[r] = lo
                if lo < end[r]:
                    n_heap = _push(heap, key, n_heap, r, label_t[lo] + arc_t[a])
    return out_node[:n_out], out_t[:n_out], out_h[:n_out], out_parent[:n_out]


@numba.njit(nogil=True, cache=True)
def _push(heap, key, n, item, value):  # type: ignore[no-untyped-def]  # pragma: no cover - compiled
    """Add ``item`` with ``value`` to the binary min-heap of ``n`` items; the new size."""
    i = n
    while i > 0:
        up = (i - 1) // 2
        if key[up] <= value:
            break
        heap[i], key[i] = heap[up], key[up]
        i = up
    heap[i], key[i] = item, value
    return n + 1


@numba.njit(nogil=True, cache=True)
def _pop(heap, key, n):  # type: ignore[no-untyped-def]  # pragma: no cover - compiled
    """Remove the heap's first item; the new size."""
    n -= 1
    item, value = heap[n], key[n]
    i = 0
    while True:
        c = 2 * i + 1
        if c >= n:
            break
        if c + 1 < n and key[c + 1] < key[c]:
            c += 1
        if value <= key[c]:
            break
        heap[i], key[i] = heap[c], key[c]
        i = c
    if n > 0:
        heap[i], key[i] = item, value
    return n
