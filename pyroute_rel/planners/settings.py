"""The ``[planner]`` table of a scenario: which planner routes it and each planner's settings, with the published
defaults.

::

    [planner]
    kind = "dp"          # "dp" (default), "mcts", "qlearning" or "dqn"
    seed = 0             # every random choice of the sampled and learned planners

    [planner.mcts]       # Barde (2023), ISAE-SUPAERO: MCTS-UCT
    iterations = 15000   # UCT iterations per decision
    exploration = 0.7071067811865476   # C_p = 1/sqrt(2)
    step_h = 1.0         # one decision per hour
    headings = 8         # 45 deg apart
    nogo_min_deg = 35.0  # no sailing closer than 35 deg to the wind ...
    nogo_max_deg = 160.0 # ... nor deeper than 160 deg
    reward_c = 1.001     # reward exp((TimeMax c - date) / (TimeMax c - TimeMin))
    rollout_h = 0.0      # rollout horizon [h] (0: until arrival or the time limit)
    max_voyage_h = 0.0   # give up after this long [h] (0: 3 x the great circle at the polar's mean speed)
    graph = false        # true: search the rank digraph's arcs instead of headings (for checks against the DP)
    final = "visits"     # sail the most visited action ("best": the one with the best reward below it)
    weather = "auto"     # "forecast", "members" (one per iteration), "perturbed" (N(mean, sigma^2) per step);
                         # "auto": "perturbed" from the members' spread when there are members, else "forecast"
    sigma_scale = 1.0    # "perturbed": the wind error's standard deviation times this (0: the mean weather)
    engine = "lattice"   # "lattice": compiled search over the problem sampled on a lattice; "python": reference
    lattice_deg = 0.25   # lattice spacing [deg] ("lattice")
    lattice_h = 6.0      # time between lattice slices [h] ("lattice")

    [planner.qlearning]  # Jing et al. (2021): tabular Q-learning
    space = "graph"      # "graph": states = rank-digraph nodes, actions = arcs; "cells": 8-neighbour grid of cells
    alpha = 0.6
    gamma = 0.9
    epsilon = 0.2
    episodes = 3000
    cell_nm = 10.0       # side of a cell [nm] ("cells")
    cells_across = 10    # cells across the course ("cells")
    time_costing = "passes"  # time-varying weather: "passes" (each rank at the route's time) or "buckets"
    time_passes = 3      # "passes": costing and learning passes
    time_bucket_h = 6.0  # "buckets": moves costed at the middle of their 6 h bucket
    max_voyage_h = 0.0   # moves after this are not actions [h] (0: 3 x the great circle at the polar's mean speed)

    [planner.dqn]        # Mannocci & Bologna (2021): DQN over a local wind image
    episodes = 200
    step_h = 6.0
    image_cells = 8      # the wind image is image_cells x image_cells (u, v) around the craft
    image_km = 1000.0    # its side [km]
    hidden = [64, 64]
    learning_rate = 0.001
    gamma = 0.99
    epsilon = 0.2
    epsilon_final = 0.05 # exploration falls linearly to this (at most epsilon) over the training voyages
    batch = 64
    replay = 20000
    target_every = 200   # learning steps between copies of the Q-network into the target network
    turn_deg = 22.5      # actions: turn by -turn, keep, +turn (pi/8 in the paper)
    nogo_min_deg = 45.0
    model = ""           # file to save the trained network to (and read it from when it exists); "" = keep none
    departure_spread_h = 72.0   # training voyages depart up to this long after the scenario's departure [h]

This module knows nothing of routing: it reads and checks values, so the scenario reader can use it.

References
----------
Barde (2023), ISAE-SUPAERO: MCTS-UCT routing of sailing craft (8 headings, 1 h steps, C_p = 1/sqrt(2), 15 000
iterations per decision, no-go below 35 deg and above 160 deg TWA).
Jing et al. (2021): tabular Q-learning route planning on a 10 x 10 grid of 10 nm cells, 8 neighbours (alpha = 0.6,
gamma = 0.9, epsilon = 0.2, 3000 iterations).
Mannocci and Bologna (2021): a DQN sailing the Vendee Globe 2020/21 (2 x 128 x 128 wind image over 1000 km, 3
actions: turn by pi/8 either way or keep).
Kocsis, L. and Szepesvári, C. (2006). Bandit based Monte-Carlo planning. ECML 2006, doi:10.1007/11871842_29.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from typing import Any

from pyroute_rel.errors import ScenarioError, brief, check_fields, show

__all__ = [
    "PLANNERS",
    "MCTSSettings",
    "QLearningSettings",
    "DQNSettings",
    "PlannerSettings",
    "parse_planner",
    "unused_settings",
]

#: The planners by name: the exact DP and the three sampled or learned planners.
PLANNERS = ("dp", "mcts", "qlearning", "dqn")
#: Spaces tabular Q-learning works in.
QLEARNING_SPACES = ("graph", "cells")
#: How MCTS samples the weather (``"auto"``: ``"perturbed"`` with members, else ``"forecast"``).
MCTS_WEATHER = ("auto", "forecast", "members", "perturbed")
#: The MCTS engines: compiled over a lattice, or the Python reference.
MCTS_ENGINES = ("lattice", "python")


@dataclass(frozen=True)
class MCTSSettings:
    """MCTS-UCT settings (Barde 2023); the defaults are the published ones.

    Attributes
    ----------
    iterations : UCT iterations per decision (15 000 published) [-].
    exploration : UCT exploration constant C_p (1/sqrt(2) published) [-].
    step_h : Time between decisions (1 h published) [h].
    headings : Number of headings, evenly spaced from north (8, 45 deg apart, published) [-].
    nogo_min_deg, nogo_max_deg : Headings with a true wind angle below / above these are not sailed (35 and 160
        published) [deg].
    reward_c : The ``c`` of the reward ``exp((TimeMax c - date) / (TimeMax c - TimeMin))`` (1.001 published) [-].
    rollout_h : Longest rollout [h]; 0: until arrival or :attr:`max_voyage_h`.
    max_voyage_h : Voyage time after which the search gives up [h] (TimeMax); 0: three times the great-circle
        distance at the polar's mean speed.
    graph : Search the scenario's rank digraph (actions = its arcs) instead of headings: the same tree search on
        the DP's graph, for checks against the DP.
    final : The action sailed after a decision's search: ``"visits"`` the most visited (published) or ``"best"``
        the one below which the best reward was found (exact once the tree holds every path).
    weather : How the search samples the weather: ``"forecast"`` the scenario's; ``"members"`` one ensemble member
        per iteration; ``"perturbed"`` each wind component drawn from N(mean, sigma^2) at each step (Barde), sigma
        from the members' spread, or without members from
        :class:`~pyroute_rel.analysis.monte_carlo.MonteCarloSettings`' forecast error; ``"auto"`` (default):
        ``"perturbed"`` when there are members (published), else ``"forecast"``.
    sigma_scale : In ``"perturbed"`` weather, multiplies the standard deviation of the wind error (1: as stated
        under ``weather``; 0: no noise, the same search as the mean weather) [-].
    engine : ``"lattice"`` (default): the compiled search (:mod:`~pyroute_rel._kernels.mcts`) over the
        problem sampled on a lattice (:mod:`~pyroute_rel.planners.mcts_lattice`), a new tree per decision;
        ``"python"``: the reference search with every step costed exactly, keeping the subtree (weather with
        currents needs it; no ``"perturbed"``). ``graph = true`` always searches with the Python engine.
    lattice_deg : Spacing of the lattice [deg].
    lattice_h : Time between the lattice's slices [h] (one slice when nothing changes in time).
    """

    iterations: int = 15_000
    exploration: float = 1.0 / math.sqrt(2.0)
    step_h: float = 1.0
    headings: int = 8
    nogo_min_deg: float = 35.0
    nogo_max_deg: float = 160.0
    reward_c: float = 1.001
    rollout_h: float = 0.0
    max_voyage_h: float = 0.0
    graph: bool = False
    final: str = "visits"
    weather: str = "auto"
    sigma_scale: float = 1.0
    engine: str = "lattice"
    lattice_deg: float = 0.25
    lattice_h: float = 6.0

    def __post_init__(self) -> None:
        check_fields(
            self,
            {
                "iterations": ("int", 1, 10_000_000),
                "exploration": ("float", 0.0, 100.0),
                "step_h": ("float", 0.0, 48.0, True),
                "headings": ("int", 2, 360),
                "nogo_min_deg": ("float", 0.0, 180.0),
                "nogo_max_deg": ("float", 0.0, 180.0),
                "reward_c": ("float", 1.0, 10.0, True),
                "rollout_h": ("float", 0.0, 100_000.0),
                "max_voyage_h": ("float", 0.0, 100_000.0),
                "graph": ("bool",),
                "final": ("choice", ("visits", "best")),
                "weather": ("choice", MCTS_WEATHER),
                "sigma_scale": ("float", 0.0, 100.0),
                "engine": ("choice", MCTS_ENGINES),
                "lattice_deg": ("float", 0.01, 5.0),
                "lattice_h": ("float", 0.1, 1000.0),
            },
            where="[planner.mcts].",
        )
        if self.nogo_min_deg >= self.nogo_max_deg:
            raise ScenarioError(
                f"[planner.mcts].nogo_min_deg must be below nogo_max_deg (got {self.nogo_min_deg:g} and "
                f"{self.nogo_max_deg:g})"
            )
        if self.engine == "python" and self.weather == "perturbed" and not self.graph:
            raise ScenarioError("[planner.mcts].weather = 'perturbed' needs engine = 'lattice' (got engine 'python')")


#: Q-learning's default episodes per state of its graph (``episodes = 0``), at least :data:`PUBLISHED_EPISODES`.
AUTO_EPISODES_PER_STATE = 2
#: Jing et al. (2021)'s 3000 iterations.
PUBLISHED_EPISODES = 3000


def episodes_for(settings: QLearningSettings, n_states: int) -> int:
    """The episodes Q-learning trains for: the settings' own, or with ``episodes = 0`` two per state of the graph,
    at least the published 3000.

    >>> episodes_for(QLearningSettings(), 57_762), episodes_for(QLearningSettings(), 100), episodes_for(
    ...     QLearningSettings(episodes=50), 57_762)
    (115524, 3000, 50)
    """
    if settings.episodes:
        return settings.episodes
    return max(PUBLISHED_EPISODES, AUTO_EPISODES_PER_STATE * n_states)


@dataclass(frozen=True)
class QLearningSettings:
    """Tabular Q-learning settings (Jing et al. 2021); the defaults are the published ones.

    Attributes
    ----------
    space : ``"graph"``: states are the rank digraph's nodes and actions its arcs; ``"cells"``: the published grid of
        square cells with 8 neighbours, edge time ``2 d / (v_i + v_j)``.
    alpha : Learning rate (0.6 published) [-].
    gamma : Discount factor (0.9 published) [-].
    epsilon : Exploration rate of the epsilon-greedy policy (0.2 published) [-].
    episodes : Training episodes [-]; 0 (the default): :data:`AUTO_EPISODES_PER_STATE` per state of the problem's
        graph, at least the published 3000 iterations (on the control course's default graph of 57 762 states,
        115 524 episodes: the greedy route then reaches the finish; 3000 leave it 413 nm short).
    cell_nm : Side of a cell (10 nm published) [nm].
    cells_across : Cells across the course (10 published) [-].
    time_costing : How moves are costed in time-varying weather (or with zones that have time windows; not
        published: the paper's weather is steady): ``"passes"`` every action once per pass at the time the last
        pass's route reaches its rank (its rows of cells), ``time_passes`` passes; ``"buckets"`` at the middle of
        its time bucket of ``time_bucket_h``, a (group, bucket) costed when first needed.
    time_passes : Passes of ``"passes"`` [-].
    time_bucket_h : Width of a time bucket of ``"buckets"`` [h].
    max_voyage_h : Moves starting this long after departure are not actions (the time lattice's extent) [h]; 0:
        three times the great circle at the polar's mean speed.
    """

    space: str = "graph"
    alpha: float = 0.6
    gamma: float = 0.9
    epsilon: float = 0.2
    episodes: int = 0
    cell_nm: float = 10.0
    cells_across: int = 10
    time_costing: str = "passes"
    time_passes: int = 3
    time_bucket_h: float = 6.0
    max_voyage_h: float = 0.0

    def __post_init__(self) -> None:
        check_fields(
            self,
            {
                "space": ("choice", QLEARNING_SPACES),
                "alpha": ("float", 0.0, 1.0, True),
                "gamma": ("float", 0.0, 1.0, True),
                "epsilon": ("float", 0.0, 1.0),
                "episodes": ("int", 0, 10_000_000),
                "cell_nm": ("float", 0.01, 10_000.0),
                "cells_across": ("int", 1, 10_001),
                "time_costing": ("choice", ("passes", "buckets")),
                "time_passes": ("int", 1, 100),
                "time_bucket_h": ("float", 0.0, 10_000.0, True),
                "max_voyage_h": ("float", 0.0, 100_000.0),
            },
            where="[planner.qlearning].",
        )


@dataclass(frozen=True)
class DQNSettings:
    """Deep Q-network settings (after Mannocci & Bologna 2021, scaled down to train in minutes on a CPU).

    Attributes
    ----------
    episodes : Training voyages, each from a random departure (and member) of the scenario's weather [-].
    step_h : Time between decisions [h].
    image_cells : Side of the wind image around the craft, in cells (the paper's 128) [-].
    image_km : Side of the wind image (the paper's 1000 km) [km].
    hidden : Sizes of the Q-network's hidden layers [-].
    learning_rate : Adam's step size [-].
    gamma : Discount factor [-].
    epsilon : Exploration rate of the first training voyage [-].
    epsilon_final : Exploration rate of the last training voyage, at most :attr:`epsilon`; it falls linearly from
        :attr:`epsilon` in between (not in the paper; equal to ``epsilon`` for a constant rate) [-].
    batch : Transitions per learning step [-].
    replay : Capacity of the experience replay [transitions].
    target_every : Learning steps between copies of the Q-network into the target network [-].
    turn_deg : The actions turn by ``-turn_deg``, 0 or ``+turn_deg`` (pi/8 = 22.5 deg in the paper) [deg].
    nogo_min_deg : Headings closer to the wind are not sailed (45 deg in the paper) [deg].
    model : File the trained network is saved to (``.npz``) and read from when it exists; ``""``: none.
    departure_spread_h : Training voyages depart at random times up to this long after the scenario's departure
        [h].
    """

    episodes: int = 200
    step_h: float = 6.0
    image_cells: int = 8
    image_km: float = 1000.0
    hidden: tuple[int, ...] = (64, 64)
    learning_rate: float = 1e-3
    gamma: float = 0.99
    epsilon: float = 0.2
    epsilon_final: float = 0.05
    batch: int = 64
    replay: int = 20_000
    target_every: int = 200
    turn_deg: float = 22.5
    nogo_min_deg: float = 45.0
    model: str = ""
    departure_spread_h: float = 72.0

    def __post_init__(self) -> None:
        check_fields(
            self,
            {
                "episodes": ("int", 1, 1_000_000),
                "step_h": ("float", 0.0, 48.0, True),
                "image_cells": ("int", 1, 256),
                "image_km": ("float", 1.0, 20_000.0),
                "learning_rate": ("float", 0.0, 1.0, True),
                "gamma": ("float", 0.0, 1.0, True),
                "epsilon": ("float", 0.0, 1.0),
                "epsilon_final": ("float", 0.0, 1.0),
                "batch": ("int", 1, 100_000),
                "replay": ("int", 1, 10_000_000),
                "target_every": ("int", 1, 10_000_000),
                "turn_deg": ("float", 0.0, 180.0, True),
                "nogo_min_deg": ("float", 0.0, 180.0),
                "model": ("str",),
                "departure_spread_h": ("float", 0.0, 100_000.0),
            },
            where="[planner.dqn].",
        )
        if self.epsilon_final > self.epsilon:
            raise ScenarioError(
                f"[planner.dqn].epsilon_final must be at most epsilon: exploration falls from epsilon to epsilon_final "
                f"(got epsilon_final {self.epsilon_final:g} and epsilon {self.epsilon:g})"
            )
        hidden = self.hidden
        if (
            isinstance(hidden, str | bytes)
            or not isinstance(hidden, list | tuple)
            or not hidden
            or len(hidden) > 8
            or not all(isinstance(h, numbers.Integral) and not isinstance(h, bool) and 1 <= h <= 4096 for h in hidden)
        ):
            raise ScenarioError(
                "[planner.dqn].hidden must be a list of 1 to 8 layer sizes, whole numbers in [1, 4096] "
                f"(got {brief(hidden)})"
            )
        object.__setattr__(self, "hidden", tuple(int(h) for h in hidden))


@dataclass(frozen=True)
class PlannerSettings:
    """The ``[planner]`` table: which planner routes the scenario, its seed and every planner's settings.

    Attributes
    ----------
    kind : One of :data:`PLANNERS` (``"dp"`` default).
    seed : Seed of every random choice (fixed: results are reproducible) [-].
    mcts, qlearning, dqn : Each planner's settings.
    """

    kind: str = "dp"
    seed: int = 0
    mcts: MCTSSettings = field(default_factory=MCTSSettings)
    qlearning: QLearningSettings = field(default_factory=QLearningSettings)
    dqn: DQNSettings = field(default_factory=DQNSettings)

    def __post_init__(self) -> None:
        if not isinstance(self.kind, str) or self.kind not in PLANNERS:
            raise ScenarioError(f"[planner].kind must be one of {list(PLANNERS)} (got {brief(self.kind)})")
        check_fields(self, {"seed": ("int", 0, 2**32 - 1)}, where="[planner].")
        for name, cls in (("mcts", MCTSSettings), ("qlearning", QLearningSettings), ("dqn", DQNSettings)):
            if not isinstance(getattr(self, name), cls):
                raise ScenarioError(
                    f"PlannerSettings.{name} must be a {cls.__name__} (got {brief(getattr(self, name))})"
                )


_TABLES = {"mcts": MCTSSettings, "qlearning": QLearningSettings, "dqn": DQNSettings}

#: Settings of a planner's table that only some of its modes use: (table, setting, mode setting, the modes that use
#: it). ``sigma_scale`` with ``weather = "auto"`` is not listed: "auto" is "perturbed" when there are members.
MODE_SETTINGS = (
    ("mcts", "lattice_deg", "engine", ("lattice",)),
    ("mcts", "lattice_h", "engine", ("lattice",)),
    ("mcts", "sigma_scale", "weather", ("perturbed", "auto")),
    ("qlearning", "cell_nm", "space", ("cells",)),
    ("qlearning", "cells_across", "space", ("cells",)),
    ("qlearning", "time_passes", "time_costing", ("passes",)),
    ("qlearning", "time_bucket_h", "time_costing", ("buckets",)),
)


def unused_settings(settings: PlannerSettings) -> list[str]:
    """What the scenario's planner (``settings.kind``) will not use of its own table: each setting changed from its
    default that the table's mode leaves unused (:data:`MODE_SETTINGS`; MCTS with ``graph = true`` searches with
    the Python engine, so the lattice's settings too), one line each. The other planners' tables are not looked at
    (a scenario may hold every planner's settings).

    >>> unused_settings(parse_planner({"kind": "qlearning", "qlearning": {"cell_nm": 60.0}, "mcts": {"lattice_h": 3}}))
    ["[planner.qlearning].cell_nm = 60.0 is not used: it applies to space = 'cells' (the table has space = 'graph')"]
    """
    kind = settings.kind
    if kind not in _TABLES:
        return []
    table = getattr(settings, kind)
    default = _TABLES[kind]()
    out = []
    for name, setting, mode, modes in MODE_SETTINGS:
        if name != kind or getattr(table, setting) == getattr(default, setting):
            continue
        value = getattr(table, setting)
        used = getattr(table, mode)
        graph = mode == "engine" and table.graph  # the graph search is the Python engine's
        if used not in modes or graph:
            wanted = " or ".join(repr(m) for m in modes if m != "auto")
            out.append(
                f"[planner.{kind}].{setting} = {value!r} is not used: it applies to {mode} = {wanted} "
                f"(the table has {'graph = true' if graph else f'{mode} = {used!r}'})"
            )
    return out


def parse_planner(raw: Any) -> PlannerSettings:
    """Read a scenario's ``[planner]`` table (unknown keys are refused, naming the key and those expected).

    >>> s = parse_planner({"kind": "mcts", "mcts": {"iterations": 200}})
    >>> s.kind, s.mcts.iterations, s.mcts.headings, round(s.mcts.exploration, 4), s.qlearning.alpha
    ('mcts', 200, 8, 0.7071, 0.6)
    """
    if not isinstance(raw, Mapping):
        raise ScenarioError("[planner] must be a table")
    top = {"kind", "seed", *_TABLES}
    for key in raw:
        if key not in top:
            raise ScenarioError(f"[planner]: unknown key '{show(key)}' (expected one of {', '.join(sorted(top))})")
    parts: dict[str, Any] = {}
    for name, cls in _TABLES.items():
        sub = raw.get(name, {})
        if not isinstance(sub, Mapping):
            raise ScenarioError(f"[planner.{name}] must be a table")
        known = [f.name for f in fields(cls)]
        for key in sub:
            if key not in known:
                raise ScenarioError(f"[planner.{name}]: unknown key '{show(key)}' (expected one of {', '.join(known)})")
        parts[name] = cls(**dict(sub))
    return PlannerSettings(kind=raw.get("kind", "dp"), seed=raw.get("seed", 0), **parts)
