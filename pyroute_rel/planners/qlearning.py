"""Tabular Q-learning (Jing et al. 2021) on the DP's rank digraph or on the published grid of cells.

Two state spaces (``[planner.qlearning].space``):

``"graph"`` (default)
    States are the rank digraph's nodes (plus the start and the finish), actions its arcs: the DP's own graph, so
    the learned route can be compared with the DP's arc for arc. An arc forbidden by the failure model (``p_f >
    apf``), the polar, the weather, land or a zone is not an action.
``"cells"``
    The published grid: square cells of ``cell_nm`` (10 nm published), ``cells_across`` (10 published) across the
    course and as many along it as its length needs, the start and finish cells on the great circle; from a cell
    the craft moves to any of its 8 neighbours. A move takes ``2 d / (v_i + v_j)`` (the published edge time: ``d``
    the distance between the cells' centres, ``v_i`` and ``v_j`` the speed over ground on the move's course at each
    cell, currents included); a move the DP's arc cost forbids (failure model, polar, weather), or that touches land
    (grown by the scenario's margin, Jing's safety distance) or a zone, is not an action.

The agent learns ``Q(s, a)`` by one-step Q-learning with an epsilon-greedy policy (published alpha = 0.6,
gamma = 0.9, epsilon = 0.2, 3000 iterations), reward minus the move's time [h]; episodes start at the start and end
at the finish, at a dead end (a state with no action, reward -:data:`DEAD_END_H`) or after as many moves as there
are states. The route is the greedy policy from the start. With ``gamma < 1`` early moves weigh more than late
ones, so the learned route minimises a discounted time; ``gamma = 1`` learns the minimum-time route (on a static
problem, with enough episodes, the DP's route: tests/test_planners.py). The state is the position only (as
published).

Costing. The moves are costed before they are learned from, in vectorised calls, not one move at a time:

- On a static problem (steady weather, no zone with a time window) every action is costed once, in one call per
  rank (the DP's own arc costs, :meth:`pyroute_rel.routing.solve.RoutingProblem.costs`, with its obstacle mask).
- In time-varying weather (or with zones that have time windows) the actions are costed on a time lattice: the
  voyage's first ``max_voyage_h`` are cut into buckets of ``time_bucket_h``, and a move made at time ``t`` takes the
  time of its action costed at the middle of ``t``'s bucket. A group of states (a rank of the digraph, a few rows
  of cells) is costed for a bucket the first time an episode needs it, in one call, and kept. What this
  approximates: the weather (and the failure model's ``p_f``) met by a move are those of up to half a bucket
  earlier or later; with zones that have time windows a move is forbidden when a zone blocks it at its bucket's
  start, middle or end. Moves beyond ``max_voyage_h`` are not actions. The evaluator re-times the learned track
  exactly (:func:`pyroute_rel.analysis.evaluate.evaluate_track`), and that re-timing is the planner's reported voyage.

Learning runs in a compiled loop (numba) over the costed table, its random numbers drawn in blocks from the seeded
numpy generator, so results are reproducible.

References
----------
Watkins, C. J. C. H. and Dayan, P. (1992). Q-learning. Machine Learning 8, 279-292, doi:10.1007/BF00992698.
Jing et al. (2021): Q-learning route planning on a grid of cells, with the settings above.
"""

from __future__ import annotations

import math
import time as _time
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
import numpy.typing as npt

from pyroute_rel import geodesy
from pyroute_rel._kernels import qlearning as kernels
from pyroute_rel.planners.base import PlannedTrack, PlanningProblem
from pyroute_rel.planners.settings import QLearningSettings, episodes_for
from pyroute_rel.progress import progress_bar
from pyroute_rel.routing.grid import plan_grid
from pyroute_rel.times import hours_after
from pyroute_rel.units import KM_PER_NM

__all__ = [
    "QLearningPlanner",
    "TabularProblem",
    "CostLattice",
    "graph_states",
    "cell_states",
    "train_q",
    "greedy_path",
    "shortest_time",
]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.intp]

#: Reward of reaching a state with no action (a dead end), in hours: far worse than any voyage.
DEAD_END_H = 1.0e5
#: Random numbers drawn from the seeded generator at a time for the compiled learning loop.
RANDOM_BLOCK = 1 << 16
#: Actions costed together on the lattice of the grid of cells (rows are grouped up to this many actions).
CELL_GROUP_ACTIONS = 1024
#: Horizon of a cost lattice made without one (:func:`train_q`, :func:`greedy_path`) [h].
DEFAULT_HORIZON_H = 10_000.0


@dataclass(frozen=True)
class TabularProblem:
    """A finite routing graph for tabular Q-learning, actions stored as a CSR table.

    Attributes
    ----------
    lon_deg, lat_deg : Position of each state [deg].
    ptr : State ``s``'s actions are ``ptr[s]:ptr[s + 1]`` [-].
    target : The state each action leads to [-].
    start, goal : The start and finish states [-].
    cost : ``cost(actions, t0_h)``: the time of the actions taken at ``t0_h`` [h], ``inf`` where forbidden.
    static_cost : The actions' times when they do not depend on time (steady weather, no zone with a time window),
        else None [h].
    rank_node : For the rank digraph, (rank, node) of each state (-1 for the start and the finish), else None.
    group_ptr : States costed together on the time lattice: group ``g`` is states ``group_ptr[g]:group_ptr[g + 1]``
        (a rank of the digraph, rows of cells).
    timed_obstacles : True when zones with time windows may forbid an action at one time and not another.
    """

    lon_deg: FloatArray
    lat_deg: FloatArray
    ptr: IntArray
    target: IntArray
    start: int
    goal: int
    cost: Callable[[IntArray, float], FloatArray]
    static_cost: FloatArray | None = None
    rank_node: npt.NDArray[np.intp] | None = None
    group_ptr: IntArray | None = None
    timed_obstacles: bool = False

    @property
    def n_states(self) -> int:
        """Number of states."""
        return int(self.ptr.size - 1)

    def groups(self) -> IntArray:
        """:attr:`group_ptr`, or one group per state."""
        return np.arange(self.n_states + 1, dtype=np.intp) if self.group_ptr is None else self.group_ptr


def _csr(source: IntArray, target: IntArray, n_states: int) -> tuple[IntArray, IntArray, IntArray]:
    """Actions sorted by source state: (ptr, target, order of the given actions)."""
    order = np.argsort(source, kind="stable")
    ptr = np.zeros(n_states + 1, dtype=np.intp)
    np.add.at(ptr, source + 1, 1)
    return np.cumsum(ptr), target[order], order


def graph_states(problem: PlanningProblem) -> TabularProblem:
    """The rank digraph as a tabular problem: state 0 the start, ``1 + k n_nodes + i`` node i of rank k, the last
    state the finish; one action per arc of the grid, its time the DP's arc cost with the obstacle mask."""
    grid, rp = problem.grid, problem.problem
    n_ranks, n_nodes = grid.n_ranks, grid.n_nodes
    goal = 1 + n_ranks * n_nodes
    src_s, dst_s, ends = [], [], []
    for k in range(n_ranks + 1):
        lon0, lat0, lon1, lat1, src, valid = grid.arcs(k)
        j, col = np.nonzero(valid)
        s = np.zeros(j.size, dtype=np.intp) if k == 0 else 1 + (k - 1) * n_nodes + src[j, col]
        d = np.full(j.size, goal, dtype=np.intp) if k == n_ranks else 1 + k * n_nodes + j
        src_s.append(s)
        dst_s.append(d)
        b = [np.broadcast_to(a, src.shape)[j, col] for a in (lon0, lat0, lon1, lat1)]
        ends.append((np.full(j.size, k), j, col, *b))
    source, target = np.concatenate(src_s), np.concatenate(dst_s)
    ptr, target, order = _csr(source, target, goal + 1)
    cols = [np.concatenate([e[i] for e in ends])[order] for i in range(7)]
    rank, dst, colx = (c.astype(np.intp) for c in cols[:3])
    a_lon0, a_lat0, a_lon1, a_lat1 = cols[3:]
    timed = rp.blocked is not None and rp.blocked.timed

    def cost(actions: IntArray, t0_h: float) -> FloatArray:
        """The actions' times leaving at ``t0_h``: the DP's arc costs, one mask per rank."""
        actions = np.asarray(actions, dtype=np.intp)
        legs = rp.costs(a_lon0[actions], a_lat0[actions], a_lon1[actions], a_lat1[actions], t0_h)
        out = np.array(legs.time_h, dtype=float, ndmin=1).reshape(actions.shape)
        if rp.blocked is not None:
            ranks = rank[actions]
            for k in np.unique(ranks):
                sel = np.flatnonzero(ranks == k)
                at = None if not timed else np.full(grid.pattern(int(k))[0].shape, hours_after(rp.departure, t0_h))
                hit = rp.blocked(int(k), at)[dst[actions[sel]], colx[actions[sel]]]
                out[sel[hit]] = np.inf
        return out

    static = None
    if rp.weather.steady and not timed:
        static = np.empty(target.size)
        for k in range(n_ranks + 1):  # one vectorised cost per rank
            pick = np.flatnonzero(rank == k)
            static[pick] = cost(pick, 0.0)
    lon = np.concatenate([[grid.start[0]], grid.lon_deg.ravel(), [grid.finish[0]]])
    lat = np.concatenate([[grid.start[1]], grid.lat_deg.ravel(), [grid.finish[1]]])
    rn = np.full((goal + 1, 2), -1, dtype=np.intp)
    rn[1:goal, 0] = np.repeat(np.arange(n_ranks), n_nodes)
    rn[1:goal, 1] = np.tile(np.arange(n_nodes), n_ranks)
    groups = np.concatenate([[0], 1 + np.arange(n_ranks + 1) * n_nodes, [goal + 1]]).astype(np.intp)
    return TabularProblem(lon, lat, ptr, target, 0, goal, cost, static, rn, groups, timed)


def _cell_centres(problem: PlanningProblem, s: QLearningSettings) -> tuple[FloatArray, FloatArray, float]:
    """Centres of the cells [deg] (rows along the course, ``cells_across`` columns) and the lateral centre."""
    cell_km = s.cell_nm * KM_PER_NM
    n_along = max(1, round(problem.great_circle_km() / cell_km) - 1)
    g = plan_grid(
        problem.start, problem.finish, layout="square", n_ranks=n_along, n_nodes=s.cells_across, spacing_km=cell_km
    )
    return g.lon_deg, g.lat_deg, (s.cells_across - 1) / 2.0


def cell_states(problem: PlanningProblem, settings: QLearningSettings | None = None) -> TabularProblem:
    """The published grid of cells with 8 neighbours as a tabular problem (see the module notes).

    State 0 is the start, ``1 + r n + c`` the cell of row r (along the course) and column c, the last state the
    finish. The start joins the first row's cells within one column of the great circle, the last row's such cells
    join the finish. An action's time is the published ``2 d / (v_i + v_j)`` [h]; a move that
    :meth:`~pyroute_rel.planners.base.PlanningProblem.sail` forbids is ``inf``.
    """
    s = settings or problem.settings.qlearning
    lon_c, lat_c, mid = _cell_centres(problem, s)
    rows, n = lon_c.shape
    goal = 1 + rows * n
    lon = np.concatenate([[problem.start[0]], lon_c.ravel(), [problem.finish[0]]])
    lat = np.concatenate([[problem.start[1]], lat_c.ravel(), [problem.finish[1]]])
    r, c = np.divmod(np.arange(rows * n), n)
    src, dst = [], []
    for dr in (-1, 0, 1):
        for dc in (-1, 0, 1):
            if dr or dc:
                ok = (r + dr >= 0) & (r + dr < rows) & (c + dc >= 0) & (c + dc < n)
                src.append(1 + r[ok] * n + c[ok])
                dst.append(1 + (r[ok] + dr) * n + c[ok] + dc)
    near = np.flatnonzero(np.abs(np.arange(n) - mid) <= 1.0)
    src += [np.zeros(near.size, dtype=np.intp), 1 + (rows - 1) * n + near]
    dst += [1 + near, np.full(near.size, goal, dtype=np.intp)]
    ptr, target, order = _csr(np.concatenate(src), np.concatenate(dst), goal + 1)
    source = np.repeat(np.arange(goal + 1), np.diff(ptr))

    def cost(actions: IntArray, t0_h: float) -> FloatArray:
        a, b = source[actions], target[actions]
        legs = problem.sail(lon[a], lat[a], lon[b], lat[b], t0_h)
        d_nm = geodesy.distance_nm(lon[a], lat[a], lon[b], lat[b])
        course_a = geodesy.initial_bearing_deg(lon[a], lat[a], lon[b], lat[b])
        course_b = (geodesy.initial_bearing_deg(lon[b], lat[b], lon[a], lat[a]) + 180.0) % 360.0
        v_a = problem.speed_kn(lon[a], lat[a], course_a, t0_h)
        v_b = problem.speed_kn(lon[b], lat[b], course_b, t0_h)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = 2.0 * d_nm / (v_a + v_b)
        return np.where(legs.ok & np.isfinite(t) & (t > 0), t, np.inf)

    rp = problem.problem
    timed = bool(problem.scenario.avoid.zones) and rp.blocked is not None and rp.blocked.timed
    static = cost(np.arange(target.size), 0.0) if rp.weather.steady and not timed else None
    rows_per_group = max(1, CELL_GROUP_ACTIONS // (8 * n))
    groups = np.concatenate([[0], 1 + np.arange(0, rows, rows_per_group) * n, [goal, goal + 1]]).astype(np.intp)
    return TabularProblem(lon, lat, ptr, target, 0, goal, cost, static, None, groups, timed)


class CostLattice:
    """The actions' times as the learning loop reads them (see the module notes): every action once on a static
    problem, else per (group of states, time bucket), costed the first time it is needed.

    Parameters
    ----------
    tab : The tabular problem.
    bucket_h : Width of a time bucket [h] (ignored on a static problem).
    horizon_h : Moves starting after this are not actions [h] (ignored on a static problem).
    """

    def __init__(self, tab: TabularProblem, bucket_h: float, horizon_h: float) -> None:
        self.tab = tab
        groups = tab.groups()
        self.first_action = tab.ptr[groups].astype(np.int64)
        self.group_of = (np.searchsorted(groups, np.arange(tab.n_states), side="right") - 1).astype(np.int64)
        n_groups = groups.size - 1
        self.fills = 0
        self.seconds = 0.0
        if tab.static_cost is not None:
            self.bucket_h = math.inf
            self.slot = self.first_action[:-1].reshape(n_groups, 1).copy()
            self.pool = np.asarray(tab.static_cost, dtype=float)
            self.size = self.pool.size
        else:
            self.bucket_h = float(bucket_h)
            self.slot = np.full((n_groups, max(1, math.ceil(horizon_h / bucket_h))), -1, dtype=np.int64)
            self.pool = np.empty(max(1024, tab.target.size))
            self.size = 0

    @classmethod
    def at_group_times(cls, tab: TabularProblem, group_times_h: FloatArray) -> CostLattice:
        """Every action costed once, leaving at its group's time ``group_times_h[g]`` [h]: a static table (one
        vectorised cost per group)."""
        lat = cls(tab, 1.0, 1.0)
        t0 = _time.perf_counter()
        pool = np.empty(tab.target.size)
        for g in range(lat.first_action.size - 1):
            lo, hi = int(lat.first_action[g]), int(lat.first_action[g + 1])
            if hi > lo:
                pool[lo:hi] = tab.cost(np.arange(lo, hi), float(group_times_h[g]))
        lat.bucket_h = math.inf
        lat.slot = lat.first_action[:-1].reshape(-1, 1).copy()
        lat.pool, lat.size = pool, pool.size
        lat.fills, lat.seconds = lat.slot.shape[0], _time.perf_counter() - t0
        return lat

    def fill(self, g: int, b: int) -> None:
        """Cost group ``g``'s actions for bucket ``b``: at the bucket's middle (and, with timed zones, forbidden
        where a zone blocks them at its start or end)."""
        t0 = _time.perf_counter()
        lo, hi = int(self.first_action[g]), int(self.first_action[g + 1])
        acts = np.arange(lo, hi)
        t = np.array(self.tab.cost(acts, (b + 0.5) * self.bucket_h), dtype=float) if acts.size else np.zeros(0)
        if self.tab.timed_obstacles and acts.size:
            for edge in (b * self.bucket_h, (b + 1) * self.bucket_h):
                t[~np.isfinite(self.tab.cost(acts, edge))] = np.inf
        while self.size + t.size > self.pool.size:
            self.pool = np.concatenate([self.pool, np.empty(self.pool.size)])
        self.pool[self.size : self.size + t.size] = t
        self.slot[g, b] = self.size
        self.size += t.size
        self.fills += 1
        self.seconds += _time.perf_counter() - t0

    def times(self, s: int, t_h: float) -> FloatArray:
        """The times of state ``s``'s actions taken at ``t_h`` [h] (``inf`` where forbidden)."""
        n = int(self.tab.ptr[s + 1] - self.tab.ptr[s])
        b = int(t_h / self.bucket_h)
        if b >= self.slot.shape[1]:
            return np.full(n, np.inf)
        g = int(self.group_of[s])
        if self.slot[g, b] < 0:
            self.fill(g, b)
        o = int(self.slot[g, b] + self.tab.ptr[s] - self.first_action[g])
        return self.pool[o : o + n]


def _horizon_h(problem: PlanningProblem, s: QLearningSettings) -> float:
    """``max_voyage_h``, or three times the great circle at the polar's mean speed [h]."""
    if s.max_voyage_h:
        return s.max_voyage_h
    polar = np.asarray(problem.problem.polar.speed_kn, dtype=float)
    return 3.0 * problem.great_circle_km() / KM_PER_NM / float(np.mean(polar[polar > 0]))


def train_q(
    tab: TabularProblem,
    settings: QLearningSettings,
    rng: np.random.Generator,
    *,
    progress: bool = False,
    checkpoints: int = 0,
    lattice: CostLattice | None = None,
    q0: FloatArray | None = None,
) -> tuple[FloatArray, list[tuple[int, float]]]:
    """One-step Q-learning with an epsilon-greedy policy over the actions that may be taken (see the module notes).

    An action forbidden at the time a state is reached (its time is ``inf``) is neither taken nor counted in the
    next state's value; a state with none is a dead end, worth ``-DEAD_END_H``.

    Parameters
    ----------
    tab : The tabular problem.
    settings : Learning rate, discount, exploration, episodes, time lattice.
    rng : Draws every random choice (in blocks of :data:`RANDOM_BLOCK`).
    progress : Show a progress bar.
    checkpoints : Record the greedy route's time after this many evenly spaced episodes.
    lattice : The costed actions (default a new :class:`CostLattice` with the settings' ``time_bucket_h`` and a
        horizon of ``max_voyage_h``).
    q0 : Q-table to start from (default zeros); it is not changed.

    Returns
    -------
    The Q-table (one value per action) and, with ``checkpoints`` > 0, the greedy route's time in the tabular
    problem's costs after evenly spaced episodes: ``[(episode, time_h), ...]`` (``inf`` while it fails to arrive).
    """
    lat = lattice or CostLattice(tab, settings.time_bucket_h, settings.max_voyage_h or DEFAULT_HORIZON_H)
    q = np.zeros(tab.target.size) if q0 is None else np.array(q0, dtype=float)
    n_ep = episodes_for(settings, tab.n_states)
    marks = sorted(set(np.linspace(1, n_ep, checkpoints).round().astype(int).tolist())) if checkpoints else []
    stops = sorted(set(marks) | set(np.linspace(0, n_ep, 101).round().astype(int).tolist()[1:]))
    st = np.array([0, tab.start, 0, 0, 0, 0], dtype=np.int64)
    clock = np.zeros(1)
    u = rng.random(RANDOM_BLOCK)
    history: list[tuple[int, float]] = []
    bar = progress_bar(n_ep, enabled=progress, desc="q-learning", unit="episode")
    done = 0
    for stop in stops:
        while True:
            code = kernels.learn(q, tab.ptr, tab.target, lat.group_of, lat.first_action, lat.slot, lat.pool,
                                 lat.bucket_h, tab.start, tab.goal, settings.alpha, settings.gamma, settings.epsilon,
                                 tab.n_states, DEAD_END_H, u, st, clock, stop)  # fmt: skip
            if code == 0:
                break
            if code == 1:
                lat.fill(int(st[4]), int(st[5]))
            else:
                u, st[3] = rng.random(RANDOM_BLOCK), 0
        if stop in marks:
            history.append((stop, _greedy(tab, q, lat)[2]))
        bar.update(stop - done)
        done = stop
    bar.close()
    return q, history


def _greedy(tab: TabularProblem, q: FloatArray, lattice: CostLattice) -> tuple[IntArray, bool, float]:
    """The greedy policy from the start over the actions that may be taken: states visited, whether it reached the
    finish (it stops at a dead end or a loop), and its time in the lattice's costs [h] (inf unless it arrived)."""
    path, reached, t, _ = _greedy_timed(tab, q, lattice)
    return path, reached, t


def _greedy_timed(
    tab: TabularProblem, q: FloatArray, lattice: CostLattice
) -> tuple[IntArray, bool, float, list[float]]:
    """:func:`_greedy` and the time at each state visited [h]."""
    path, seen, s, t = [tab.start], {tab.start}, tab.start, 0.0
    times_at = [0.0]
    while s != tab.goal:
        lo = int(tab.ptr[s])
        times = lattice.times(s, t)
        allowed = np.isfinite(times)
        if not allowed.any():
            return np.asarray(path, dtype=np.intp), False, float("inf"), times_at
        i = int(np.argmax(np.where(allowed, q[lo : lo + times.size], -np.inf)))
        s, t = int(tab.target[lo + i]), t + float(times[i])
        if s in seen:
            return np.asarray(path, dtype=np.intp), False, float("inf"), times_at
        path.append(s)
        times_at.append(t)
        seen.add(s)
    return np.asarray(path, dtype=np.intp), True, t, times_at


def greedy_path(tab: TabularProblem, q: FloatArray, lattice: CostLattice | None = None) -> tuple[IntArray, bool]:
    """States visited by the greedy policy from the start (stops at the finish, a dead end or a loop) and whether it
    reached the finish (``lattice``: the costs it was learned with; default every action at time 0 or static)."""
    lat = lattice or CostLattice(tab, QLearningSettings().time_bucket_h, DEFAULT_HORIZON_H)
    path, reached, _ = _greedy(tab, q, lat)
    return path, reached


def shortest_time(tab: TabularProblem) -> float:
    """The least time from the start to the finish on a static tabular problem (Dijkstra, scipy) [h]: what
    Q-learning with ``gamma = 1`` converges to (``inf`` when the finish cannot be reached)."""
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import dijkstra

    if tab.static_cost is None:
        raise ValueError("shortest_time needs a static problem (static_cost)")
    ok = np.isfinite(tab.static_cost)
    src = np.repeat(np.arange(tab.n_states), np.diff(tab.ptr))[ok]
    dst, w = tab.target[ok], tab.static_cost[ok]
    order = np.lexsort((w, dst, src))  # parallel actions: keep the least time (a sparse matrix would add them)
    src, dst, w = src[order], dst[order], w[order]
    first = np.ones(src.size, dtype=bool)
    first[1:] = (src[1:] != src[:-1]) | (dst[1:] != dst[:-1])
    # a zero time would read as no edge: nudged up
    g = csr_matrix((np.maximum(w[first], 1e-12), (src[first], dst[first])), shape=(tab.n_states, tab.n_states))
    return float(dijkstra(g, indices=tab.start, min_only=True)[tab.goal])


def _nominal_group_times(problem: PlanningProblem, tab: TabularProblem) -> FloatArray:
    """Each group's time for the first pass: its states' mean distance from the start at the polar's mean speed
    [h]."""
    polar = np.asarray(problem.problem.polar.speed_kn, dtype=float)
    v = float(np.mean(polar[polar > 0]))
    d_nm = geodesy.distance_nm(tab.lon_deg[0], tab.lat_deg[0], tab.lon_deg, tab.lat_deg)
    groups = tab.groups()
    return np.array([d_nm[a:b].mean() / v if b > a else 0.0 for a, b in zip(groups[:-1], groups[1:], strict=True)])


def _route_group_times(tab: TabularProblem, path: IntArray, times_at: list[float], previous: FloatArray) -> FloatArray:
    """Each group's time on a greedy route: when the route first enters it, interpolated between the groups it
    enters; groups after the last one entered keep ``previous`` shifted by the route's lateness there [h]."""
    groups = tab.groups()
    g_of = np.searchsorted(groups, np.asarray(path), side="right") - 1
    first: dict[int, float] = {}
    for g, t in zip(g_of.tolist(), times_at, strict=True):
        first.setdefault(int(g), float(t))
    gs = np.array(sorted(first))
    ts = np.array([first[g] for g in gs])
    out = np.interp(np.arange(previous.size), gs, ts)
    after = np.arange(previous.size) > gs[-1]
    out[after] = previous[after] + (ts[-1] - previous[gs[-1]])
    return out


def _train_in_passes(
    problem: PlanningProblem,
    tab: TabularProblem,
    s: QLearningSettings,
    rng: np.random.Generator,
    progress: bool,
    checkpoints: int,
) -> tuple[FloatArray, list[tuple[int, float]], CostLattice, list[float], float, int]:
    """Time-varying costs in ``time_passes`` passes (see the module notes): each pass costs every action at its
    group's time and learns on that static table from the last pass's Q; the greedy route is sailed exactly
    (:meth:`~pyroute_rel.planners.base.PlanningProblem.retime`) and the next pass's group times are when it reaches
    each group. Returns the Q of the pass whose route was fastest, the history, that pass's lattice, each pass's
    route's exact voyage time [h] (inf when it did not arrive), the seconds spent costing and the groups costed."""
    times = _nominal_group_times(problem, tab)
    q: FloatArray | None = None
    history: list[tuple[int, float]] = []
    passes: list[float] = []
    seconds, fills = 0.0, 0
    best: tuple[float, FloatArray, CostLattice] | None = None
    for k in range(s.time_passes):
        lattice = CostLattice.at_group_times(tab, times)
        seconds, fills = seconds + lattice.seconds, fills + lattice.fills
        q, hist = train_q(tab, s, rng, progress=progress, checkpoints=checkpoints, lattice=lattice, q0=q)
        history += [(k * s.episodes + e, h) for e, h in hist]
        path, reached, _, _ = _greedy_timed(tab, q, lattice)
        sailed, _ok = problem.retime(tab.lon_deg[path], tab.lat_deg[path])  # the route's exact times
        voyage = float(sailed[-1]) if reached else math.inf
        passes.append(voyage)
        if best is None or voyage < best[0]:
            best = (voyage, q, lattice)
        times = _route_group_times(tab, path, sailed.tolist(), times)
    assert best is not None
    return best[1], history, best[2], passes, seconds, fills


class QLearningPlanner:
    """Tabular Q-learning (Jing et al. 2021) on the rank digraph or the grid of cells (see the module notes)."""

    name = "qlearning"

    def __init__(self, settings: QLearningSettings | None = None, *, seed: int | None = None) -> None:
        self.settings = settings
        self.seed = seed

    def plan(self, problem: PlanningProblem, *, progress: bool = False, checkpoints: int = 0) -> PlannedTrack:
        """Learn Q from the problem's start, then sail the greedy route.

        ``checkpoints`` > 0 records the greedy route's time in the learning problem's own costs after that many
        evenly spaced episodes (``stats["history"]``): how many iterations it takes to find the best route.
        """
        problem.check_simple_course(self.name)
        s = self.settings or problem.settings.qlearning
        seed = problem.settings.seed if self.seed is None else self.seed
        t0 = _time.perf_counter()
        tab = graph_states(problem) if s.space == "graph" else cell_states(problem, s)
        s = replace(s, episodes=episodes_for(s, tab.n_states))  # 0: sized from the graph
        tabled = _time.perf_counter() - t0
        rng = np.random.default_rng(seed)
        passes: list[float] = []
        if tab.static_cost is not None or s.time_costing == "buckets":
            lattice = CostLattice(tab, s.time_bucket_h, _horizon_h(problem, s))
            q, history = train_q(tab, s, rng, progress=progress, checkpoints=checkpoints, lattice=lattice)
            seconds, fills = lattice.seconds, lattice.fills
        else:
            q, history, lattice, passes, seconds, fills = _train_in_passes(problem, tab, s, rng, progress, checkpoints)
        path, reached, model_h = _greedy(tab, q, lattice)
        lon, lat = tab.lon_deg[path], tab.lat_deg[path]
        elapsed, _ = problem.retime(lon, lat)
        stats = {
            "space": s.space,
            "episodes": s.episodes * max(1, len(passes)),
            "states": tab.n_states,
            "actions": int(tab.target.size),
            "time_costing": "static" if tab.static_cost is not None else s.time_costing,
            "lattice_fills": fills,
            "costing_s": tabled + seconds,
            "pass_voyage_times_h": passes,
            "training_s": _time.perf_counter() - t0,
            "runtime_s": _time.perf_counter() - t0,
            "model_voyage_time_h": model_h,
            "history": [[e, h] for e, h in history],
        }
        if tab.static_cost is not None:
            stats["optimum_h"] = shortest_time(tab)
        if tab.rank_node is not None:
            stats["nodes"] = tab.rank_node[path[1:-1], 1].tolist() if reached else []
        return PlannedTrack(self.name, lon, lat, elapsed, reached, stats)
