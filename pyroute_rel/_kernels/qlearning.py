"""Compiled Q-learning: the tabular agent's look-ups, action choice and learning episodes.

Used by :mod:`pyroute_rel.planners.qlearning` (which documents the method). No numpy twin: the learning has no
closed form, so ``tests/test_planners.py`` pins the result instead (the greedy route after learning is the DP's
route on the graph, Dijkstra's on cells, and is sailed exactly in time-varying weather). Excluded from coverage.
"""

from __future__ import annotations

import math

import numba


@numba.njit(cache=True)
def lookup(s, t, ptr, group_of, first_action, slot, bucket_h):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Offset of state ``s``'s action times at ``t`` in the pool: -2 beyond the horizon, -1 not costed yet."""
    b = int(t / bucket_h)
    if b >= slot.shape[1]:
        return -2, b
    g = group_of[s]
    if slot[g, b] < 0:
        return -1, b
    return slot[g, b] + ptr[s] - first_action[g], b


@numba.njit(cache=True)
def value(q, pool, lo, hi, o, dead_end):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The best Q-value among the actions that may be taken (``-dead_end`` with none) and how many there are."""
    best = -math.inf
    n = 0
    if o >= 0:
        for i in range(hi - lo):
            if math.isfinite(pool[o + i]):
                n += 1
                if q[lo + i] > best:
                    best = q[lo + i]
    return (best if n else -dead_end), n


@numba.njit(cache=True)
def choose(q, pool, lo, hi, o, n_ok, best, explore, u):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Index of the action taken: the ``u``-th allowed one when exploring, else the ``u``-th best."""
    n = n_ok
    if not explore:
        n = 0
        for i in range(hi - lo):
            if math.isfinite(pool[o + i]) and q[lo + i] == best:
                n += 1
    k = min(int(u * n), n - 1)
    for i in range(hi - lo):
        if math.isfinite(pool[o + i]) and (explore or q[lo + i] == best):
            if k == 0:
                return i
            k -= 1
    return -1


@numba.njit(cache=True)
def learn(q, ptr, target, group_of, first_action, slot, pool, bucket_h, start, goal, alpha, gamma, eps,
           max_steps, dead_end, u, st, clock, n_episodes):  # type: ignore[no-untyped-def]  # pragma: no cover  # fmt: skip
    """One-step Q-learning episodes until ``st[0] == n_episodes``; resumable.

    ``st`` = (episode, state, step, random position, group, bucket), ``clock[0]`` the time [h]. Returns 0 when
    done, 1 when group ``st[4]`` must be costed for bucket ``st[5]``, 2 when ``u`` is used up.
    """
    while st[0] < n_episodes:
        s, t = st[1], clock[0]
        lo, hi = ptr[s], ptr[s + 1]
        o, b = lookup(s, t, ptr, group_of, first_action, slot, bucket_h)
        if o == -1:
            st[4], st[5] = group_of[s], b
            return 1
        best, n_ok = value(q, pool, lo, hi, o, dead_end)
        end = n_ok == 0
        if not end:
            if st[3] + 2 > u.size:
                return 2
            i = choose(q, pool, lo, hi, o, n_ok, best, u[st[3]] < eps, u[st[3] + 1])
            a = lo + i
            nxt, t1 = target[a], t + pool[o + i]
            future = 0.0
            if nxt != goal:
                o1, b1 = lookup(nxt, t1, ptr, group_of, first_action, slot, bucket_h)
                if o1 == -1:
                    st[4], st[5] = group_of[nxt], b1
                    return 1
                future = value(q, pool, ptr[nxt], ptr[nxt + 1], o1, dead_end)[0]
            q[a] += alpha * (-pool[o + i] + gamma * future - q[a])
            st[3] += 2
            st[1], st[2], clock[0] = nxt, st[2] + 1, t1
            end = nxt == goal or st[2] >= max_steps
        if end:
            st[0] += 1
            st[1], st[2], clock[0] = start, 0, 0.0
    return 0
