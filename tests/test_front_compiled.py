"""The compiled label reduction (pyroute_rel._kernels.front) keeps exactly the non-dominated labels (issue 20)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pyroute_rel._kernels.front import extend_steady, nondominated


def brute_force(node: list[int], t: list[float], h: list[float]) -> list[int]:
    """Candidates no other at their node dominates (no worse in both, better in one), of equal ones the first;
    ordered by node, time, hazard: pairwise comparison, the definition."""
    n = len(node)
    kept = []
    for i in range(n):
        beaten = False
        for j in range(n):
            if j == i or node[j] != node[i]:
                continue
            if (t[j] <= t[i] and h[j] <= h[i] and (t[j] < t[i] or h[j] < h[i])) or (
                t[j] == t[i] and h[j] == h[i] and j < i
            ):
                beaten = True
                break
        if not beaten:
            kept.append(i)
    return sorted(kept, key=lambda i: (node[i], t[i], h[i]))


values = st.sampled_from([0.0, 0.5, 1.0, 1.5, 2.0, 3.0, np.inf])


@pytest.mark.slow
@settings(max_examples=300, deadline=None)
@given(
    st.lists(st.tuples(st.integers(0, 4), st.sampled_from([0.0, 1.0, 2.0, 2.5, 4.0]), values), max_size=40),
)
def test_nondominated_equals_pairwise_dominance(cands: list[tuple[int, float, float]]) -> None:
    node = [c[0] for c in cands]
    t = [c[1] for c in cands]
    h = [c[2] for c in cands]
    got = nondominated(np.array(node, dtype=np.intp), np.array(t), np.array(h), 5).tolist()
    assert got == brute_force(node, t, h)


def test_nondominated_keeps_a_front_per_node() -> None:
    rng = np.random.default_rng(7)
    node = rng.integers(0, 30, 3000)
    t, h = rng.random(3000), rng.random(3000)
    pick = nondominated(node, t, h, 30)
    assert np.all(np.diff(node[pick]) >= 0)
    for n in range(30):  # along a node's kept labels time increases and hazard decreases strictly
        sel = pick[node[pick] == n]
        assert np.all(np.diff(t[sel]) > 0) and np.all(np.diff(h[sel]) < 0)
        at = np.flatnonzero(node == n)
        expected = [int(at[i]) for i in brute_force([n] * at.size, t[at].tolist(), h[at].tolist())]
        assert sel.tolist() == expected


@pytest.mark.slow
@settings(max_examples=200, deadline=None)
@given(
    st.lists(st.lists(st.tuples(st.sampled_from([0.0, 1.0, 2.0, 3.0]), values), max_size=6), min_size=1, max_size=4),
    st.lists(st.tuples(st.integers(0, 3), st.integers(0, 3), st.sampled_from([0.5, 1.0]), values), max_size=16),
)
def test_extend_steady_equals_candidates_laid_out(
    sources: list[list[tuple[float, float]]], arcs: list[tuple[int, int, float, float]]
) -> None:
    """Extending every label along every arc and keeping the non-dominated ones per node, in one kernel (a merge of
    the arcs' runs of labels), is the pairwise dominance of the candidates laid out arc by arc (arcs sorted by
    destination, as the voyage front gives them; each source's labels non-dominated and sorted by time)."""
    n_src = len(sources)
    # each source's labels as a rank gives them: its non-dominated ones, by time (hazard then decreases strictly)
    sources = [
        [src[i] for i in brute_force([0] * len(src), [x[0] for x in src], [x[1] for x in src])] for src in sources
    ]
    arcs = sorted(((d, s % n_src, dt, dh) for d, s, dt, dh in arcs), key=lambda a: a[0])
    label_t = [lab[0] for src in sources for lab in src]
    label_h = [lab[1] for src in sources for lab in src]
    label_start = np.cumsum([0] + [len(src) for src in sources])
    node, t, h, parent = [], [], [], []
    for d, s, dt, dh in arcs:  # the candidates laid out arc by arc
        for lab in range(label_start[s], label_start[s + 1]):
            node.append(d)
            t.append(label_t[lab] + dt)
            h.append(label_h[lab] + dh)
            parent.append(lab)
    expected = brute_force(node, t, h)
    dest = np.array([a[0] for a in arcs], dtype=np.intp)
    got = extend_steady(
        np.array(label_t),
        np.array(label_h),
        label_start,
        np.searchsorted(dest, np.arange(5)),
        np.array([a[1] for a in arcs], dtype=np.intp),
        np.array([a[2] for a in arcs]),
        np.array([a[3] for a in arcs]),
    )
    assert got[0].tolist() == [node[i] for i in expected]
    assert got[3].tolist() == [parent[i] for i in expected]
    assert got[1].tolist() == [t[i] for i in expected] and got[2].tolist() == [h[i] for i in expected]


def test_extend_steady_equals_the_reduction_of_every_candidate_on_random_staircases() -> None:
    """Many labels per source and arcs with real-valued costs (sums that round to equal times and hazards): the
    merge keeps exactly what :func:`nondominated` keeps of every candidate laid out arc by arc."""
    rng = np.random.default_rng(11)
    n_src, n_dest = 12, 9
    label_t, label_h, label_start = [], [], [0]
    for _ in range(n_src):
        n = int(rng.integers(0, 80))  # a staircase: times up (some equal), hazards down (some equal, the first inf)
        t = np.cumsum(rng.choice([0.0, 0.1, 0.25, 0.3], n))
        h = np.cumsum(rng.choice([0.0, 0.1, 0.2], n))[::-1] + np.where(np.arange(n) == 0, np.inf, 0.0)
        pick = nondominated(np.zeros(t.size, dtype=np.intp), t, h, 1)
        label_t += t[pick].tolist()
        label_h += h[pick].tolist()
        label_start.append(len(label_t))
    dest = np.sort(rng.integers(0, n_dest, 60))
    src = rng.integers(0, n_src, 60)
    arc_t = rng.choice([0.1, 0.2, 0.3, 1e-17, 2.0], 60)
    arc_h = rng.choice([0.0, 0.1, 0.7, 1e-17, np.inf], 60)
    starts = np.asarray(label_start)
    per = starts[src + 1] - starts[src]
    parent = np.concatenate([np.arange(starts[s], starts[s + 1]) for s in src])
    node = np.repeat(dest, per)
    lt, lh = np.asarray(label_t), np.asarray(label_h)
    t = lt[parent] + np.repeat(arc_t, per)
    h = lh[parent] + np.repeat(arc_h, per)
    pick = nondominated(node, t, h, n_dest)
    got = extend_steady(lt, lh, starts, np.searchsorted(dest, np.arange(n_dest + 1)), src, arc_t, arc_h)
    assert pick.size > 50
    assert got[0].tolist() == node[pick].tolist() and got[3].tolist() == parent[pick].tolist()
    assert got[1].tolist() == t[pick].tolist() and got[2].tolist() == h[pick].tolist()
