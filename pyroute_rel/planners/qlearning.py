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
problem, with enough episodes, the DP's route: tests/test_planners.py). Time-varying weather is costed at the
time each move is made, but the state is the position only (as published).

References
----------
Watkins, C. J. C. H. and Dayan, P. (1992). Q-learning. Machine Learning 8, 279-292, doi:10.1007/BF00992698.
Jing et al. (2021): Q-learning route planning on a grid of cells, with the settings above.
"""

from __future__ import annotations

import time as _time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from .. import geodesy
from ..grid import plan_grid
from ..progress import progress_bar
from ..units import KM_PER_NM
from .base import PlannedTrack, PlanningProblem
from .settings import QLearningSettings

__all__ = ["QLearningPlanner", "TabularProblem", "graph_states", "cell_states", "train_q", "greedy_path"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.intp]

#: Reward of reaching a state with no action (a dead end), in hours: far worse than any voyage.
DEAD_END_H = 1.0e5


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
    static_cost : The actions' times when they do not depend on time (steady weather), else None [h].
    rank_node : For the rank digraph, (rank, node) of each state (-1 for the start and the finish), else None.
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

    @property
    def n_states(self) -> int:
        """Number of states."""
        return int(self.ptr.size - 1)


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

    def cost(actions: IntArray, t0_h: float) -> FloatArray:
        legs = rp.costs(a_lon0[actions], a_lat0[actions], a_lon1[actions], a_lat1[actions], t0_h)
        out = np.array(legs.time_h, dtype=float, ndmin=1)
        if rp.blocked is not None:
            times = np.datetime64(rp.departure, "s") + np.timedelta64(int(round(t0_h * 3600.0)), "s")
            for i, a in enumerate(actions):
                k = int(rank[a])
                at = None if not rp.blocked.timed else np.full(grid.pattern(k)[0].shape, times)
                if rp.blocked(k, at)[dst[a], colx[a]]:
                    out[i] = np.inf
        return out

    static = None
    if rp.weather.steady and (rp.blocked is None or not rp.blocked.timed):
        static = _static_graph_costs(problem, rank, dst, colx, (a_lon0, a_lat0, a_lon1, a_lat1))
    lon = np.concatenate([[grid.start[0]], grid.lon_deg.ravel(), [grid.finish[0]]])
    lat = np.concatenate([[grid.start[1]], grid.lat_deg.ravel(), [grid.finish[1]]])
    rn = np.full((goal + 1, 2), -1, dtype=np.intp)
    rn[1:goal, 0] = np.repeat(np.arange(n_ranks), n_nodes)
    rn[1:goal, 1] = np.tile(np.arange(n_nodes), n_ranks)
    return TabularProblem(lon, lat, ptr, target, 0, goal, cost, static, rn)


def _static_graph_costs(
    problem: PlanningProblem, rank: IntArray, dst: IntArray, col: IntArray, ends: tuple[FloatArray, ...]
) -> FloatArray:
    """Every arc's time in steady weather, one vectorised cost per rank with its obstacle mask [h]."""
    rp, grid = problem.problem, problem.grid
    out = np.empty(rank.size)
    for k in range(grid.n_ranks + 1):
        pick = np.flatnonzero(rank == k)
        legs = rp.costs(*(e[pick] for e in ends), np.zeros(pick.size))
        t = np.array(legs.time_h, dtype=float, ndmin=1)
        if rp.blocked is not None:
            t = np.where(rp.blocked(k, None)[dst[pick], col[pick]], np.inf, t)
        out[pick] = t
    return out


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

    static = cost(np.arange(target.size), 0.0) if problem.problem.weather.steady else None
    return TabularProblem(lon, lat, ptr, target, 0, goal, cost, static)


def _action_times(tab: TabularProblem, lo: int, hi: int, t_h: float) -> FloatArray:
    if tab.static_cost is not None:
        return tab.static_cost[lo:hi]
    return tab.cost(np.arange(lo, hi), t_h)


def _best(q: FloatArray, times: FloatArray) -> float:
    """The best Q-value among the actions that may be taken now (``-DEAD_END_H`` at a dead end)."""
    allowed = np.isfinite(times)
    return float(q[allowed].max()) if allowed.any() else -DEAD_END_H


def train_q(
    tab: TabularProblem,
    settings: QLearningSettings,
    rng: np.random.Generator,
    *,
    progress: bool = False,
    checkpoints: int = 0,
) -> tuple[FloatArray, list[tuple[int, float]]]:
    """One-step Q-learning with an epsilon-greedy policy over the actions that may be taken (see the module notes).

    An action forbidden at the time a state is reached (its time is ``inf``) is neither taken nor counted in the
    next state's value; a state with none is a dead end, worth ``-DEAD_END_H``.

    Returns
    -------
    The Q-table (one value per action) and, with ``checkpoints`` > 0, the greedy route's time after evenly spaced
    episodes: ``[(episode, time_h), ...]`` (``inf`` while it fails to arrive).
    """
    q = np.zeros(tab.target.size)
    alpha, gamma, eps = settings.alpha, settings.gamma, settings.epsilon
    marks = set(np.linspace(1, settings.episodes, checkpoints).round().astype(int).tolist()) if checkpoints else set()
    history: list[tuple[int, float]] = []
    bar = progress_bar(settings.episodes, enabled=progress, desc="q-learning", unit="episode")
    for episode in range(1, settings.episodes + 1):
        s, t = tab.start, 0.0
        lo, hi = int(tab.ptr[s]), int(tab.ptr[s + 1])
        times = _action_times(tab, lo, hi, t)
        for _ in range(tab.n_states):
            allowed = np.flatnonzero(np.isfinite(times))
            if allowed.size == 0:
                break  # a dead end
            if rng.random() < eps:
                i = int(allowed[rng.integers(allowed.size)])
            else:
                vals = q[lo:hi][allowed]
                i = int(allowed[rng.choice(np.flatnonzero(vals == vals.max()))])
            a, t1 = lo + i, t + float(times[i])
            nxt = int(tab.target[a])
            nlo, nhi = int(tab.ptr[nxt]), int(tab.ptr[nxt + 1])
            ntimes = _action_times(tab, nlo, nhi, t1) if nxt != tab.goal else np.zeros(0)
            future = 0.0 if nxt == tab.goal else _best(q[nlo:nhi], ntimes)
            q[a] += alpha * (-float(times[i]) + gamma * future - q[a])
            s, t, lo, hi, times = nxt, t1, nlo, nhi, ntimes
            if s == tab.goal:
                break
        if episode in marks:
            history.append((episode, _greedy(tab, q)[2]))
        bar.update(1)
    bar.close()
    return q, history


def _greedy(tab: TabularProblem, q: FloatArray) -> tuple[IntArray, bool, float]:
    """The greedy policy from the start over the actions that may be taken: states visited, whether it reached the
    finish (it stops at a dead end or a loop), and its time in the tabular problem's costs [h] (inf unless it
    arrived)."""
    path, seen, s, t = [tab.start], {tab.start}, tab.start, 0.0
    while s != tab.goal:
        lo, hi = int(tab.ptr[s]), int(tab.ptr[s + 1])
        times = _action_times(tab, lo, hi, t)
        allowed = np.isfinite(times)
        if not allowed.any():
            return np.asarray(path, dtype=np.intp), False, float("inf")
        i = int(np.argmax(np.where(allowed, q[lo:hi], -np.inf)))
        s, t = int(tab.target[lo + i]), t + float(times[i])
        if s in seen:
            return np.asarray(path, dtype=np.intp), False, float("inf")
        path.append(s)
        seen.add(s)
    return np.asarray(path, dtype=np.intp), True, t


def greedy_path(tab: TabularProblem, q: FloatArray) -> tuple[IntArray, bool]:
    """States visited by the greedy policy from the start (stops at the finish, a dead end or a loop) and whether it
    reached the finish."""
    path, reached, _ = _greedy(tab, q)
    return path, reached


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
        q, history = train_q(tab, s, np.random.default_rng(seed), progress=progress, checkpoints=checkpoints)
        trained = _time.perf_counter() - t0
        path, reached = greedy_path(tab, q)
        lon, lat = tab.lon_deg[path], tab.lat_deg[path]
        elapsed, _ = problem.retime(lon, lat)
        stats = {
            "space": s.space,
            "episodes": s.episodes,
            "states": tab.n_states,
            "actions": int(tab.target.size),
            "training_s": trained,
            "runtime_s": _time.perf_counter() - t0,
            "model_voyage_time_h": _greedy(tab, q)[2],
            "history": [[e, h] for e, h in history],
        }
        if tab.rank_node is not None:
            stats["nodes"] = tab.rank_node[path[1:-1], 1].tolist() if reached else []
        return PlannedTrack(self.name, lon, lat, elapsed, reached, stats)
