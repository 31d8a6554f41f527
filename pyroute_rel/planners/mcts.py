"""MCTS-UCT (Barde 2023) with a receding horizon: a tree search over headings, one decision per step.

At each decision the craft, at its position and time, runs ``iterations`` UCT iterations (15 000 published) from
there, sails the most visited action for one step (``step_h``, 1 h published) and searches again from where it
arrives (the subtree below the action is kept). An iteration:

1. **selection** from the root by UCB1, ``W/N + 2 C_p sqrt(2 ln N_parent / N)`` (Kocsis and Szepesvári 2006;
   C_p = 1/sqrt(2) published), until a node with an action not tried yet;
2. **expansion** of one untried action, at random;
3. **rollout** from there: at each step the finish if it can be reached within the step, else a random heading
   among those that may be sailed and gain on the finish (within 90 deg of its bearing; any that may be sailed when
   none does), until arrival, a dead end, ``rollout_h`` or the time limit; a rollout that stops short is dated
   ``t + remaining distance / top speed``;
4. **backup** of the reward ``exp((TimeMax c - date) / (TimeMax c - TimeMin))`` (c = 1.001 published) along the
   path, 0 for a dead end; TimeMin is the great circle at the top speed over ground, TimeMax ``max_voyage_h``.

Actions are ``headings`` (8 published) headings evenly spaced from north; one is sailed for ``step_h`` at the speed
over ground on it at the step's start (:meth:`~pyroute_rel.planners.base.PlanningProblem.speed_kn`), then the leg is
costed like any arc (:meth:`~pyroute_rel.planners.base.PlanningProblem.sail`), so a step takes about ``step_h``. A
heading whose true wind angle is below ``nogo_min_deg`` (35 published) or above ``nogo_max_deg`` (160 published) is
not sailed, nor a leg the failure model forbids (``p_f > apf``), the polar or weather cannot sail, or that touches
land or a zone. When the finish can be reached within a step, sailing straight to it is one more action.

With ``graph = true`` the actions are instead the arcs of the scenario's rank digraph (the DP's graph, as
:mod:`.qlearning`'s ``"graph"`` space): the same search, for checks against the DP.

Uncertain weather: with ensemble members (:attr:`~pyroute_rel.planners.base.PlanningProblem.members`) each
iteration samples one member and simulates the tree's actions in it (open-loop UCT); the craft then sails the chosen
action in the scenario's weather.

References
----------
Kocsis, L. and Szepesvari, C. (2006). Bandit based Monte-Carlo planning. ECML 2006, doi:10.1007/11871842_29.
Browne, C. B. et al. (2012). A survey of Monte Carlo tree search methods. IEEE TCIAIG 4(1), 1-43,
doi:10.1109/TCIAIG.2012.2186810.
Barde (2023), ISAE-SUPAERO: MCTS-UCT routing of sailing craft (the settings above).
"""

from __future__ import annotations

import math
import time as _time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from pyroute_rel import geodesy
from pyroute_rel.errors import ScenarioError
from pyroute_rel.planners.base import PlannedTrack, PlanningProblem
from pyroute_rel.planners.qlearning import TabularProblem, graph_states
from pyroute_rel.planners.settings import MCTSSettings
from pyroute_rel.progress import progress_bar
from pyroute_rel.resources import MemoryEstimate, check_budget, resident_bytes
from pyroute_rel.units import KM_PER_NM

__all__ = [
    "MCTSPlanner",
    "State",
    "Moves",
    "weather_mode",
    "time_limits",
    "kernel_inputs",
    "plan_lattice",
    "python_decision",
]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class State:
    """Where and when the craft is: (lon, lat) [deg], time [h after departure], the graph state (-1 off the graph),
    and whether it is at the finish."""

    lon: float
    lat: float
    t_h: float
    node: int = -1
    done: bool = False


@dataclass(frozen=True)
class Moves:
    """The actions that may be taken from a state: their ids and the states they lead to."""

    actions: tuple[int, ...]
    states: tuple[State, ...]

    def get(self, action: int) -> State | None:
        """The state ``action`` leads to, or None when it may not be taken."""
        for a, s in zip(self.actions, self.states, strict=True):
            if a == action:
                return s
        return None


class _HeadingSim:
    """The published action space: headings, steps of ``step_h``, straight to the finish when it is in reach."""

    def __init__(self, problem: PlanningProblem, s: MCTSSettings) -> None:
        self.p, self.s = problem, s
        self.headings = np.arange(s.headings, dtype=np.float64) * (360.0 / s.headings)
        self.finish_action = s.headings

    def moves(self, state: State, weather: Any) -> Moves:
        p, s = self.p, self.s
        if state.done:
            return Moves((), ())
        twa, lon1, lat1, legs = p.headings_step(
            state.lon, state.lat, state.t_h, self.headings, s.step_h, weather=weather
        )
        if legs.ok[-1] and legs.time_h[-1] <= s.step_h:  # the finish is in reach: sail straight to it
            return Moves((self.finish_action,), (State(*p.finish, state.t_h + float(legs.time_h[-1]), -1, True),))
        ok = np.flatnonzero(legs.ok[:-1] & (twa >= s.nogo_min_deg) & (twa <= s.nogo_max_deg))
        return Moves(
            tuple(int(i) for i in ok),
            tuple(State(float(lon1[i]), float(lat1[i]), state.t_h + float(legs.time_h[i])) for i in ok),
        )

    def rollout_choice(self, state: State, moves: Moves, rng: np.random.Generator) -> int:
        if self.finish_action in moves.actions:
            return moves.actions.index(self.finish_action)
        bearing = float(geodesy.initial_bearing_deg(state.lon, state.lat, *self.p.finish))
        gain = [i for i, a in enumerate(moves.actions) if geodesy.angle_diff_deg(self.headings[a], bearing) < 90.0]
        pool = gain or list(range(len(moves.actions)))
        return int(pool[rng.integers(len(pool))])


class _GraphSim:
    """Actions are the arcs of the rank digraph (:func:`~pyroute_rel.planners.qlearning.graph_states`)."""

    def __init__(self, problem: PlanningProblem, s: MCTSSettings) -> None:
        self.p, self.s = problem, s
        self.tab: TabularProblem = graph_states(problem)

    def moves(self, state: State, weather: Any) -> Moves:
        tab = self.tab
        if state.done:
            return Moves((), ())
        lo, hi = int(tab.ptr[state.node]), int(tab.ptr[state.node + 1])
        if weather is None and tab.static_cost is not None:
            times = tab.static_cost[lo:hi]
        else:
            a = np.arange(lo, hi)
            src = np.full(a.size, state.node)
            legs = self.p.sail(tab.lon_deg[src], tab.lat_deg[src], *_ends(tab, a), state.t_h, weather=weather)
            times = legs.time_h
        ok = np.flatnonzero(np.isfinite(times))
        nxt = tab.target[lo:hi]
        return Moves(
            tuple(int(lo + i) for i in ok),
            tuple(
                State(
                    float(tab.lon_deg[nxt[i]]),
                    float(tab.lat_deg[nxt[i]]),
                    state.t_h + float(times[i]),
                    int(nxt[i]),
                    int(nxt[i]) == tab.goal,
                )
                for i in ok
            ),
        )

    def rollout_choice(self, state: State, moves: Moves, rng: np.random.Generator) -> int:
        return int(rng.integers(len(moves.actions)))


def _ends(tab: TabularProblem, actions: npt.NDArray[np.intp]) -> tuple[FloatArray, FloatArray]:
    return tab.lon_deg[tab.target[actions]], tab.lat_deg[tab.target[actions]]


@dataclass
class _Node:
    """A tree node: its children by action, visits, total and best reward, and its state in each weather member
    (None: the scenario's weather)."""

    children: dict[int, _Node] = field(default_factory=dict)
    untried: list[int] | None = None
    n: int = 0
    w: float = 0.0
    best: float = 0.0
    states: dict[Any, State] = field(default_factory=dict)
    moves: dict[Any, Moves] = field(default_factory=dict)


def time_limits(problem: PlanningProblem, s: MCTSSettings) -> tuple[float, float, float]:
    """The top speed over ground [kn] (the problem's speed bound, else the polar's largest), TimeMin (the great
    circle at that speed) [h] and TimeMax (``max_voyage_h``, else three times the great circle at the polar's mean
    speed) [h]."""
    gc_nm = problem.great_circle_km() / KM_PER_NM
    bound = problem.problem.speed_bound_kn() or float(np.max(problem.problem.polar.speed_kn))
    polar = problem.problem.polar.speed_kn
    mean = float(np.mean(polar[polar > 0])) if np.any(polar > 0) else bound
    return bound, gc_nm / bound, s.max_voyage_h or 3.0 * gc_nm / mean


class _Search:
    """UCT from a root (see the module notes)."""

    def __init__(self, sim: Any, problem: PlanningProblem, s: MCTSSettings, rng: np.random.Generator) -> None:
        self.sim, self.p, self.s, self.rng = sim, problem, s, rng
        self.top_kn, self.time_min, self.time_max = time_limits(problem, s)
        mode = weather_mode(s, problem, engine="python")
        self.members: list[Any] = list(problem.members) if mode == "members" else [None]

    def reward(self, date: float) -> float:
        if not math.isfinite(date):
            return 0.0
        c = self.s.reward_c
        return math.exp((self.time_max * c - date) / (self.time_max * c - self.time_min))

    def _moves(self, node: _Node, m: Any, weather: Any) -> Moves:
        if m not in node.moves:
            node.moves[m] = self.sim.moves(node.states[m], weather)
        return node.moves[m]

    def iterate(self, root: _Node) -> None:
        m = int(self.rng.integers(len(self.members))) if len(self.members) > 1 else 0
        weather = self.members[m]
        node, path = root, [root]
        while True:
            state = node.states[m]
            moves = self._moves(node, m, weather)
            if state.done:
                date = state.t_h
                break
            if not moves.actions or state.t_h > self.time_max:
                date = math.inf
                break
            if node.untried is None:
                node.untried = list(moves.actions)
            untried = [a for a in node.untried if a in moves.actions]
            if untried:
                a = untried[int(self.rng.integers(len(untried)))]
                node.untried.remove(a)
                child = node.children.setdefault(a, _Node())
                child.states[m] = moves.get(a)  # type: ignore[assignment]
                path.append(child)
                date = self.rollout(child.states[m], weather)
                break
            node = self._select(node, moves, m)
            path.append(node)
        r = self.reward(date)
        for n in path:
            n.n += 1
            n.w += r
            n.best = max(n.best, r)

    def _select(self, node: _Node, moves: Moves, m: int) -> _Node:
        log_n = math.log(max(node.n, 1))
        best, pick = -math.inf, None
        for a, nxt in zip(moves.actions, moves.states, strict=True):
            child = node.children.get(a)
            if child is None:
                continue
            ucb = child.w / max(child.n, 1) + 2.0 * self.s.exploration * math.sqrt(2.0 * log_n / max(child.n, 1))
            if ucb > best:
                best, pick = ucb, (child, nxt)
        assert pick is not None
        pick[0].states.setdefault(m, pick[1])
        return pick[0]

    def rollout(self, state: State, weather: Any) -> float:
        limit = self.time_max if not self.s.rollout_h else min(self.time_max, state.t_h + self.s.rollout_h)
        while not state.done:
            if state.t_h >= limit:
                rest = float(geodesy.distance_nm(state.lon, state.lat, *self.p.finish))
                return state.t_h + rest / self.top_kn
            moves = self.sim.moves(state, weather)
            if not moves.actions:
                return math.inf
            state = moves.states[self.sim.rollout_choice(state, moves, self.rng)]
        return state.t_h


def weather_mode(s: MCTSSettings, problem: PlanningProblem, *, engine: str = "lattice") -> str:
    """The weather the search samples: ``s.weather``, with ``"auto"`` resolved: ``"forecast"`` without members,
    else ``"perturbed"`` (published) with the lattice engine and ``"members"`` with the Python one."""
    if s.weather != "auto":
        return s.weather
    if not problem.members:
        return "forecast"
    return "perturbed" if engine == "lattice" else "members"


def _pick(moves: Moves, visits: dict[int, float], headings: FloatArray, bearing: float) -> int | None:
    """The action to sail among ``moves`` (sailed exactly): the one with the highest score, ties (and actions the
    search never tried) broken towards the finish's bearing; None when there are no moves."""
    if not moves.actions:
        return None

    def key(a: int) -> tuple[float, float]:
        off = 0.0 if a >= headings.size else float(geodesy.angle_diff_deg(headings[a], bearing))
        return (visits.get(a, 0.0), -off)

    return max(moves.actions, key=key)


class MCTSPlanner:
    """MCTS-UCT with a receding horizon (Barde 2023; see the module notes)."""

    name = "mcts"

    def __init__(self, settings: MCTSSettings | None = None, *, seed: int | None = None) -> None:
        self.settings = settings
        self.seed = seed

    def plan(self, problem: PlanningProblem, *, progress: bool = False) -> PlannedTrack:
        """Search, sail the most visited action one step, and search again until the finish (or a dead end, or the
        time limit)."""
        problem.check_simple_course(self.name)
        s = self.settings or problem.settings.mcts
        seed = problem.settings.seed if self.seed is None else self.seed
        problem.check_members(s.weather)
        if s.engine == "lattice" and not s.graph:
            return plan_lattice(problem, s, seed, progress=progress)
        mode = weather_mode(s, problem, engine="python")
        if mode == "perturbed":
            raise ScenarioError("[planner.mcts].weather = 'perturbed' needs engine = 'lattice'")
        rng = np.random.default_rng(seed)
        t0 = _time.perf_counter()
        sim: Any = _GraphSim(problem, s) if s.graph else _HeadingSim(problem, s)
        search = _Search(sim, problem, s, rng)
        state = State(*problem.start, 0.0, 0 if s.graph else -1)
        n_members = len(search.members)
        root = _Node(states=dict.fromkeys(range(n_members), state))
        track = [state]
        decisions = 0
        bar = progress_bar(None, enabled=progress, desc="mcts", unit="iteration")
        while not state.done and state.t_h <= search.time_max:
            for i in range(s.iterations):
                search.iterate(root)
                if i % PROGRESS_EVERY == PROGRESS_EVERY - 1:
                    bar.update(PROGRESS_EVERY)
            bar.update(s.iterations % PROGRESS_EVERY)
            moves = sim.moves(state, None)  # the craft sails in the scenario's weather
            tried = [a for a in moves.actions if a in root.children]
            if not tried:
                break
            score = {b: root.children[b].best if s.final == "best" else root.children[b].n for b in tried}
            a = max(tried, key=score.__getitem__)
            state = moves.get(a)  # type: ignore[assignment]
            track.append(state)
            decisions += 1
            # the subtree is kept when the search sailed the scenario's weather itself; with members its states
            # were simulated from other positions, so the search starts afresh
            root = root.children[a] if n_members == 1 else _Node(states=dict.fromkeys(range(n_members), state))
        bar.close()
        runtime = _time.perf_counter() - t0
        lon = np.array([st.lon for st in track])
        lat = np.array([st.lat for st in track])
        stats: dict[str, Any] = {
            "iterations": s.iterations,
            "decisions": decisions,
            "iterations_total": s.iterations * decisions,
            "runtime_s": runtime,
            "training_s": 0.0,
            "graph": s.graph,
        }
        if s.graph and state.done:
            stats["nodes"] = [int(st.node - 1) % problem.grid.n_nodes for st in track[1:-1]]
        return PlannedTrack(self.name, lon, lat, np.array([st.t_h for st in track]), state.done, stats)


def kernel_inputs(problem: PlanningProblem, s: MCTSSettings, lattice: Any) -> tuple[Any, ...]:
    """The headings [deg], the polar tables and the scalar parameters (``pyroute_rel._kernels.mcts.PARAMS``) of the
    compiled search of ``problem`` over ``lattice``."""
    from pyroute_rel._kernels.mcts import PARAMS
    from pyroute_rel._kernels.polar import tables as polar_tables
    from pyroute_rel.boat.polar import MIN_SPEED_KN

    top, t_min, t_max = time_limits(problem, s)
    pol = problem.problem.polar
    values = {
        "lon0": lattice.lon0,
        "lat0": lattice.lat0,
        "dlon": lattice.spacing_deg,
        "dlat": lattice.spacing_deg,
        "slice_h": lattice.slice_h,
        "step_h": s.step_h,
        "nogo_min": s.nogo_min_deg,
        "nogo_max": s.nogo_max_deg,
        "finish_lon": problem.finish[0],
        "finish_lat": problem.finish[1],
        "time_max": t_max,
        "time_min": t_min,
        "reward_c": s.reward_c,
        "top_kn": top,
        "rollout_h": s.rollout_h,
        "cp": s.exploration,
        "min_speed": MIN_SPEED_KN,
        "forbid_beyond": float(problem.problem.beyond == "forbid"),
        "perturbed": float(lattice.perturbed),
    }
    params = np.array([values[k] for k in PARAMS], dtype=np.float64)
    return np.arange(s.headings) * (360.0 / s.headings), polar_tables(pol), params


#: The Python engine updates its bar every so many iterations.
PROGRESS_EVERY = 1000


def tree_estimate(iterations: int, headings: int) -> MemoryEstimate:
    """The memory of one decision's tree in the compiled search, and what the process holds already [bytes]: room
    for a node per iteration, each with its children (one per heading and the finish, int64), visits, wins and best
    reward, and the path of one iteration (:func:`pyroute_rel._kernels.mcts.search`)."""
    nodes = iterations + 2
    return MemoryEstimate(
        parts={"process": resident_bytes(), "search tree": nodes * 8 * (headings + 1 + 3) + 8 * (nodes + 1)},
        what=f"{iterations} iterations, {headings} headings",
        subject="this MCTS search",
    )


def plan_lattice(problem: PlanningProblem, s: MCTSSettings, seed: int, *, progress: bool = False) -> PlannedTrack:
    """The receding-horizon MCTS with the compiled search (``engine = "lattice"``): a new tree per decision over
    the problem on a lattice; the action sailed is the most visited (or best) among those that may be sailed
    exactly (:meth:`_HeadingSim.moves`)."""
    from pyroute_rel._kernels.mcts import search
    from pyroute_rel.planners.mcts_lattice import build_lattice

    check_budget(tree_estimate(s.iterations, s.headings), knobs="use fewer iterations per decision")
    t0 = _time.perf_counter()
    mode = weather_mode(s, problem)
    _, _, t_max = time_limits(problem, s)
    headings = np.arange(s.headings) * (360.0 / s.headings)
    lattice = build_lattice(
        problem,
        headings,
        spacing_deg=s.lattice_deg,
        slice_h=s.lattice_h,
        until_h=t_max + s.step_h,
        weather=mode,
        sigma_scale=s.sigma_scale,
    )
    headings, tables, params = kernel_inputs(problem, s, lattice)
    built = _time.perf_counter() - t0
    rng = np.random.SeedSequence(seed).generate_state(2, dtype=np.uint64)
    sim = _HeadingSim(problem, s)
    state = State(*problem.start, 0.0)
    track, decisions, blind, searched = [state], 0, 0, 0.0
    # the bar counts iterations: a decision of many shows its progress (issue 34: 10^7 showed nothing for minutes)
    bar = progress_bar(None, enabled=progress, desc="mcts", unit="iteration")
    while not state.done and state.t_h <= t_max:
        t1 = _time.perf_counter()
        root = np.array([state.lon, state.lat, state.t_h])
        visits, _, best = search(
            root, s.iterations, headings, lattice.weather, lattice.okh, lattice.open, tables, params, rng, bar.update
        )
        searched += _time.perf_counter() - t1
        score = dict(enumerate((best if s.final == "best" else visits).tolist()))
        moves = sim.moves(state, None)  # the craft sails in the scenario's weather, every leg costed exactly
        bearing = float(geodesy.initial_bearing_deg(state.lon, state.lat, *problem.finish))
        a = _pick(moves, score, headings, bearing)
        if a is None:
            break
        blind += score.get(a, 0.0) == 0.0
        state = moves.get(a)  # type: ignore[assignment]
        track.append(state)
        decisions += 1
    bar.close()
    stats = {
        "iterations": s.iterations,
        "decisions": decisions,
        "iterations_total": s.iterations * decisions,
        "runtime_s": _time.perf_counter() - t0,
        "training_s": 0.0,
        "graph": False,
        "engine": "lattice",
        "weather": mode,
        "lattice_s": built,
        "search_s": searched,
        "iterations_per_s": s.iterations * decisions / searched if searched > 0 else 0.0,
        "unsearched_decisions": int(blind),
    }
    lon, lat = np.array([st.lon for st in track]), np.array([st.lat for st in track])
    return PlannedTrack("mcts", lon, lat, np.array([st.t_h for st in track]), state.done, stats)


def python_decision(problem: PlanningProblem, s: MCTSSettings, seed: int) -> dict[int, int]:
    """The visits of each root action after one decision's search from the start with the Python engine (the
    heading space), e.g. to time it against the compiled search."""
    sim = _HeadingSim(problem, s)
    search = _Search(sim, problem, s, np.random.default_rng(seed))
    root = _Node(states=dict.fromkeys(range(len(search.members)), State(*problem.start, 0.0)))
    for _ in range(s.iterations):
        search.iterate(root)
    return {a: child.n for a, child in root.children.items()}
