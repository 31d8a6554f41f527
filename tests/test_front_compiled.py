"""The compiled label reduction (pyroute_rel.front_compiled) keeps exactly the non-dominated labels (issue 20)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from pyroute_rel.front_compiled import extend_steady, nondominated


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


@settings(max_examples=200, deadline=None)
@given(
    st.lists(st.lists(st.tuples(st.sampled_from([0.0, 1.0, 2.0]), values), max_size=4), min_size=1, max_size=4),
    st.lists(st.tuples(st.integers(0, 3), st.integers(0, 3), st.sampled_from([0.5, 1.0]), values), max_size=12),
)
def test_extend_steady_equals_candidates_laid_out(
    sources: list[list[tuple[float, float]]], arcs: list[tuple[int, int, float, float]]
) -> None:
    """Extending every label along every arc and keeping the non-dominated ones per node, in one kernel, is the
    pairwise dominance of the candidates laid out arc by arc (arcs sorted by destination, as the voyage front gives
    them)."""
    n_src = len(sources)
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
