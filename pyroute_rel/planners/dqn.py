"""A deep Q-network (after Mannocci & Bologna 2021) steering by a local wind image and the craft's state.

The craft sails steps of ``step_h``; at each it turns by ``-turn_deg``, 0 or ``+turn_deg`` (pi/8 in the paper) and
sails that heading for a step at its speed over ground there (the leg costed like any arc:
:meth:`~pyroute_rel.planners.base.PlanningProblem.sail`). A turn is not taken when the new heading is closer to the
wind than ``nogo_min_deg`` (45 in the paper) or its leg is forbidden (failure model ``p_f > apf``, polar, weather,
land, zones); with no turn left the voyage ends at a dead end. When the finish can be reached within a step the
craft sails straight to it.

What the network sees (:func:`features`): a ``2 x image_cells x image_cells`` image of the wind's east and north
components (the direction it blows to, over 30 kn) on a north-up square of side ``image_km`` centred on the craft
(the paper: 2 x 128 x 128 over 1000 km; no data, such as land, is zero wind, as in the paper), and 8 numbers of the
craft's state: sine and cosine of its heading and of the bearing to the finish, the distance to the finish over the
course's great circle, the true wind angle of the heading over 180 deg, the true wind speed over 30 kn and the time
over the time limit.

Learning: a dense Q-network (:class:`sklearn.neural_network.MLPRegressor`, ReLU, Adam; its ``partial_fit`` does the
back-propagation) with an experience replay of ``replay`` transitions sampled in batches of ``batch``, and a target
network copied from it every ``target_every`` learning steps (Mnih et al. 2015). Reward per step: ``(-dt + (d_before
- d_after) / v_mean) / step_h``, the time taken plus a potential-based shaping of the progress towards the finish at
the polar's mean speed (Ng et al. 1999: it does not change the best policy, it only tells the network sooner), -10
at a dead end. Epsilon-greedy exploration over the allowed turns. Each training voyage departs at a random time in
``[0, departure_spread_h]`` after the scenario's departure, in a random weather member when there are members. The
route is the greedy policy from the scenario's departure.

The trained network is saved to ``model`` (``.npz``: its weights and the settings it was trained with) and read
back instead of training when the file exists and was trained with the same settings; inference is a plain numpy
forward pass through the saved weights (the same numbers as the network's ``predict``).

Needs the optional extra ``planners`` (scikit-learn): ``pip install 'pyroute_rel[planners]'``.

References
----------
Mnih, V. et al. (2015). Human-level control through deep reinforcement learning. Nature 518, 529-533,
doi:10.1038/nature14236.
Ng, A. Y., Harada, D. and Russell, S. (1999). Policy invariance under reward transformations. ICML 1999.
Mannocci and Bologna (2021): a DQN sailing the Vendee Globe 2020/21 (wind image, 3 actions, no-go below 45 deg).
"""

from __future__ import annotations

import contextlib
import copy
import json
import time as _time
import zipfile
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from pyroute_rel import geodesy
from pyroute_rel.errors import PyrouteError, ScenarioError, brief
from pyroute_rel.files import brief_path, write_together
from pyroute_rel.planners.base import PlannedTrack, PlanningProblem
from pyroute_rel.planners.settings import DQNSettings
from pyroute_rel.progress import progress_bar
from pyroute_rel.units import KM_PER_NM

__all__ = ["DQNPlanner", "QNetwork", "features", "model_path", "N_ACTIONS", "DEAD_END_REWARD"]

FloatArray = npt.NDArray[np.float64]

#: Turn left, keep, turn right.
N_ACTIONS = 3
#: Reward of a dead end (no turn may be sailed) [-].
DEAD_END_REWARD = -10.0
#: Wind speed the image and the state are scaled by [kn].
WIND_SCALE_KN = 30.0
#: Number of the craft's state values after the image.
N_STATE = 8


@dataclass(frozen=True)
class QNetwork:
    """A trained dense Q-network: its weights (what :class:`sklearn.neural_network.MLPRegressor` learned).

    Attributes
    ----------
    coefs, intercepts : Weights and biases of each layer (ReLU between layers, identity output).
    """

    coefs: tuple[FloatArray, ...]
    intercepts: tuple[FloatArray, ...]

    @classmethod
    def of(cls, mlp: Any) -> QNetwork:
        """The weights of a fitted ``MLPRegressor``."""
        return cls(tuple(np.array(c) for c in mlp.coefs_), tuple(np.array(b) for b in mlp.intercepts_))

    def __call__(self, x: npt.ArrayLike) -> FloatArray:
        """Q-values of each action for each row of ``x``: shape (n, :data:`N_ACTIONS`)."""
        h = np.atleast_2d(np.asarray(x, dtype=float))
        for i, (w, b) in enumerate(zip(self.coefs, self.intercepts, strict=True)):
            h = h @ w + b
            if i < len(self.coefs) - 1:
                h = np.maximum(h, 0.0)
        return h

    def save(self, path: Path, settings: DQNSettings) -> None:
        """Write the weights and the settings they were trained with (``.npz``, all or nothing)."""
        arrays = {f"coef_{i}": c for i, c in enumerate(self.coefs)}
        arrays.update({f"intercept_{i}": b for i, b in enumerate(self.intercepts)})

        def write(tmp: Path) -> None:
            with open(tmp, "wb") as fh:
                # (allow_pickle: numpy's default, named so that no array's name can take its place)
                np.savez(fh, settings=np.array(_settings_key(settings)), allow_pickle=True, **arrays)

        write_together(path.parent, {path.name: write}, option="[planner.dqn].model")

    @classmethod
    def load(cls, path: Path, settings: DQNSettings) -> QNetwork | None:
        """The weights saved at ``path`` when they were trained with ``settings``, else None (a model of other
        settings, trained again and replaced). A file that is not a model this planner wrote (text, pickled objects,
        another program's arrays) is a ScenarioError: it is never read as one, nor replaced."""
        where = f"[planner.dqn].model {brief_path(path)}"
        try:
            data = np.load(path, allow_pickle=False)
            if not isinstance(data, np.lib.npyio.NpzFile):  # (one array, .npy content, has no archive to close)
                raise ValueError("one array, not an archive of a network's weights")
            with data:
                if "settings" not in data.files:
                    raise ValueError("no network saved by pyroute_rel in it")
                key = str(data["settings"])
                json.loads(key)
                if key != _settings_key(settings):
                    return None
                n = sum(1 for k in data.files if k.startswith("coef_"))
                coefs = tuple(np.asarray(data[f"coef_{i}"], dtype=float) for i in range(n))
                intercepts = tuple(np.asarray(data[f"intercept_{i}"], dtype=float) for i in range(n))
        except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as exc:
            raise ScenarioError(
                f"{where} is not a DQN model this planner saved ({' '.join(str(exc).split())[:120]}): remove it or "
                "name another file (it is never replaced)"
            ) from None
        return cls(coefs, intercepts)


def model_path(base_dir: Path, model: str) -> Path:
    """The file ``[planner.dqn].model`` names, inside the scenario's folder ``base_dir``: a relative name that stays
    in it (issue 34: ``"../../elsewhere/x.npz"`` wrote outside the scenario folder and any ``--out``)."""
    name = Path(model)
    base = Path(base_dir).resolve()
    path = (base / name).resolve()
    if name.is_absolute() or not path.is_relative_to(base) or path == base:
        raise ScenarioError(
            f"[planner.dqn].model must name a file inside the scenario's folder {brief_path(base)} (got {brief(model)})"
        )
    return path


def _settings_key(settings: DQNSettings) -> str:
    """What a saved network depends on: its settings other than the file name."""
    return json.dumps({k: v for k, v in asdict(settings).items() if k != "model"}, sort_keys=True)


@dataclass(frozen=True)
class _Craft:
    lon: float
    lat: float
    t_h: float
    heading: float
    done: bool = False


class _Env:
    """The sailing environment of one voyage (see the module notes)."""

    def __init__(self, problem: PlanningProblem, s: DQNSettings, weather: Any, time_max: float) -> None:
        self.p, self.s, self.weather, self.time_max = problem, s, weather, time_max
        self.rp = problem.problem if weather is None else replace(problem.problem, weather=weather)
        gc = problem.great_circle_km()
        self.gc_nm = gc / KM_PER_NM
        half = s.image_km / 2.0
        offs = (np.arange(s.image_cells) + 0.5) / s.image_cells * s.image_km - half
        self.east_km, self.north_km = np.meshgrid(offs, offs[::-1])
        polar = problem.problem.polar.speed_kn
        self.v_mean = float(np.mean(polar[polar > 0]))

    def start(self) -> _Craft:
        bearing = float(geodesy.initial_bearing_deg(*self.p.start, *self.p.finish))
        return _Craft(*self.p.start, 0.0, round(bearing / self.s.turn_deg) * self.s.turn_deg % 360.0)

    def features(self, c: _Craft) -> FloatArray:
        return features(self, c)

    def step_all(self, c: _Craft) -> tuple[list[_Craft | None], FloatArray]:
        """The craft after each turn (None where it may not be taken) and each turn's reward."""
        s, p = self.s, self.p
        headings = (c.heading + np.array([-s.turn_deg, 0.0, s.turn_deg])) % 360.0
        twa, lon1, lat1, legs = p.headings_step(c.lon, c.lat, c.t_h, headings, s.step_h, weather=self.weather)
        d0 = float(geodesy.distance_nm(c.lon, c.lat, *p.finish))
        if legs.ok[-1] and legs.time_h[-1] <= s.step_h:  # in reach: every action sails straight to the finish
            dt = float(legs.time_h[-1])
            done = _Craft(*p.finish, c.t_h + dt, c.heading, True)
            return [done] * N_ACTIONS, np.full(N_ACTIONS, (-dt + d0 / self.v_mean) / s.step_h)
        ok = legs.ok[:-1] & (twa >= s.nogo_min_deg)
        out: list[_Craft | None] = []
        rewards = np.full(N_ACTIONS, DEAD_END_REWARD)
        for i in range(N_ACTIONS):
            if not ok[i]:
                out.append(None)
                continue
            nxt = _Craft(float(lon1[i]), float(lat1[i]), c.t_h + float(legs.time_h[i]), float(headings[i]))
            d1 = float(geodesy.distance_nm(nxt.lon, nxt.lat, *p.finish))
            rewards[i] = (-float(legs.time_h[i]) + (d0 - d1) / self.v_mean) / s.step_h
            out.append(nxt)
        return out, rewards


def features(env: Any, c: Any) -> FloatArray:
    """The network's input for a craft: the wind image then the craft's state (see the module notes)."""
    p = env.p
    lon, lat = geodesy.destination_point(c.lon, c.lat, 90.0, env.east_km)
    lon, lat = geodesy.destination_point(lon, lat, 0.0, env.north_km)
    cond = env.rp.weather_at(lon, lat, c.t_h)
    to = np.radians(np.asarray(cond.twd_deg, dtype=float) + 180.0)
    tws = np.asarray(cond.tws_kn, dtype=float)
    u = np.nan_to_num(tws * np.sin(to) / WIND_SCALE_KN)
    v = np.nan_to_num(tws * np.cos(to) / WIND_SCALE_KN)
    here = env.rp.weather_at(c.lon, c.lat, c.t_h)
    bearing = np.radians(float(geodesy.initial_bearing_deg(c.lon, c.lat, *p.finish)))
    h = np.radians(c.heading)
    twa = float(geodesy.angle_diff_deg(float(np.asarray(here.twd_deg)), c.heading))
    state = [
        np.sin(h),
        np.cos(h),
        np.sin(bearing),
        np.cos(bearing),
        float(geodesy.distance_nm(c.lon, c.lat, *p.finish)) / env.gc_nm,
        np.nan_to_num(twa / 180.0),
        np.nan_to_num(float(np.asarray(here.tws_kn)) / WIND_SCALE_KN),
        c.t_h / env.time_max,
    ]
    return np.concatenate([u.ravel(), v.ravel(), state])


class _Replay:
    """A ring buffer of transitions (state, action, reward, next state, done)."""

    def __init__(self, capacity: int, n_features: int) -> None:
        self.x = np.zeros((capacity, n_features))
        self.x1 = np.zeros((capacity, n_features))
        self.a = np.zeros(capacity, dtype=np.intp)
        self.r = np.zeros(capacity)
        self.done = np.zeros(capacity, dtype=bool)
        self.mask1 = np.zeros((capacity, N_ACTIONS), dtype=bool)
        self.n = 0
        self.capacity = capacity

    def add(self, x: FloatArray, a: int, r: float, x1: FloatArray, done: bool, mask1: npt.NDArray[np.bool_]) -> None:
        i = self.n % self.capacity
        self.x[i], self.a[i], self.r[i], self.x1[i], self.done[i], self.mask1[i] = x, a, r, x1, done, mask1
        self.n += 1

    def sample(self, k: int, rng: np.random.Generator) -> npt.NDArray[np.intp]:
        return rng.integers(min(self.n, self.capacity), size=k)


@dataclass
class _Learner:
    """The Q-network, its target copy and the replay."""

    s: DQNSettings
    rng: np.random.Generator
    mlp: Any
    target: Any
    replay: _Replay
    steps: int = 0

    def q(self, x: FloatArray) -> FloatArray:
        return np.asarray(self.mlp.predict(np.atleast_2d(x))).reshape(-1, N_ACTIONS)

    def learn(self) -> None:
        """One learning step: a batch from the replay, targets from the target network, one ``partial_fit``."""
        rb = self.replay
        i = rb.sample(self.s.batch, self.rng)
        y = self.q(rb.x[i])
        q1 = np.asarray(self.target.predict(rb.x1[i])).reshape(-1, N_ACTIONS)
        q1 = np.where(rb.mask1[i], q1, -np.inf).max(axis=1)
        future = np.where(rb.done[i] | ~np.isfinite(q1), 0.0, q1)
        y[np.arange(i.size), rb.a[i]] = rb.r[i] + self.s.gamma * future
        self.mlp.partial_fit(rb.x[i], y)
        self.steps += 1
        if self.steps % self.s.target_every == 0:
            self.target = copy.deepcopy(self.mlp)


def _new_learner(s: DQNSettings, n_features: int, rng: np.random.Generator, seed: int) -> _Learner:
    try:
        from sklearn.neural_network import MLPRegressor
    except ImportError:
        raise ScenarioError("the dqn planner needs scikit-learn: pip install 'pyroute_rel[planners]'") from None
    mlp = MLPRegressor(hidden_layer_sizes=s.hidden, learning_rate_init=s.learning_rate, random_state=seed)
    mlp.partial_fit(np.zeros((1, n_features)), np.zeros((1, N_ACTIONS)))  # initialise the weights
    return _Learner(s, rng, mlp, copy.deepcopy(mlp), _Replay(s.replay, n_features))


def _time_max(problem: PlanningProblem, v_mean: float) -> float:
    return 3.0 * problem.great_circle_km() / KM_PER_NM / v_mean


def _episode(env: _Env, learner: _Learner, eps: float) -> bool:
    """One training voyage; True when it reached the finish."""
    c = env.start()
    x = env.features(c)
    nxt, rewards = env.step_all(c)
    while not c.done and c.t_h <= env.time_max:
        allowed = np.array([n is not None for n in nxt])
        if not allowed.any():
            return False
        if learner.rng.random() < eps:
            a = int(learner.rng.choice(np.flatnonzero(allowed)))
        else:
            a = int(np.argmax(np.where(allowed, learner.q(x)[0], -np.inf)))
        c1 = nxt[a]
        assert c1 is not None
        x1 = env.features(c1)
        mask1 = np.ones(N_ACTIONS, dtype=bool)
        nxt1, rewards1 = ([], rewards) if c1.done else env.step_all(c1)
        if not c1.done:
            mask1 = np.array([n is not None for n in nxt1])
            if not mask1.any():  # a dead end ahead: its value is the dead end's reward
                learner.replay.add(x, a, DEAD_END_REWARD, x1, True, mask1)
                return False
        learner.replay.add(x, a, float(rewards[a]), x1, c1.done, mask1)
        if learner.replay.n >= learner.s.batch:
            learner.learn()
        c, x, nxt, rewards = c1, x1, nxt1, rewards1
    return c.done


def _epsilon(s: DQNSettings, episode: int) -> float:
    """Exploration rate of a training voyage: from ``epsilon`` down to ``epsilon_final`` linearly over the voyages."""
    if s.episodes <= 1:
        return s.epsilon
    return s.epsilon + (s.epsilon_final - s.epsilon) * episode / (s.episodes - 1)


def _one_thread() -> Any:
    """Run the network's small matrix products on one thread: BLAS threads on a busy machine cost more than they
    bring for 64-row batches."""
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # pragma: no cover - a dependency of scikit-learn
        return contextlib.nullcontext()
    return threadpool_limits(limits=1)


def train(
    problem: PlanningProblem, s: DQNSettings, seed: int, *, progress: bool = False
) -> tuple[QNetwork, dict[str, Any]]:
    """Train the Q-network on the problem's weather: ``episodes`` voyages from random departures and members."""
    rng = np.random.default_rng(seed)
    members: list[Any] = list(problem.members) or [None]
    env0 = _Env(problem, s, None, 0.0)
    time_max = _time_max(problem, env0.v_mean)
    learner = _new_learner(s, 2 * s.image_cells**2 + N_STATE, rng, seed)
    bar = progress_bar(s.episodes, enabled=progress, desc="dqn training", unit="voyage")
    arrived = skipped = 0
    for episode in range(s.episodes):
        offset = float(rng.uniform(0.0, s.departure_spread_h)) if s.departure_spread_h else 0.0
        shifted = replace(
            problem,
            problem=replace(problem.problem, departure=problem.departure + np.timedelta64(int(offset * 3600), "s")),
        )
        env = _Env(shifted, s, members[int(rng.integers(len(members)))], time_max)
        try:
            arrived += _episode(env, learner, _epsilon(s, episode))
        except PyrouteError:  # e.g. a departure the weather does not cover: that voyage only
            skipped += 1
        bar.update(1)
    bar.close()
    return QNetwork.of(learner.mlp), {"arrived": arrived, "skipped": skipped, "learning_steps": learner.steps}


def sail_greedy(problem: PlanningProblem, s: DQNSettings, net: QNetwork) -> list[_Craft]:
    """The greedy policy's voyage from the scenario's departure, in its weather."""
    env = _Env(problem, s, None, 0.0)
    env.time_max = _time_max(problem, env.v_mean)
    c = env.start()
    track = [c]
    while not c.done and c.t_h <= env.time_max:
        nxt, _ = env.step_all(c)
        allowed = np.array([n is not None for n in nxt])
        if not allowed.any():
            break
        c = nxt[int(np.argmax(np.where(allowed, net(env.features(c))[0], -np.inf)))]  # type: ignore[assignment]
        track.append(c)
    return track


class DQNPlanner:
    """A DQN over a local wind image and the craft's state (see the module notes)."""

    name = "dqn"

    def __init__(self, settings: DQNSettings | None = None, *, seed: int | None = None) -> None:
        self.settings = settings
        self.seed = seed

    def plan(self, problem: PlanningProblem, *, progress: bool = False) -> PlannedTrack:
        """Train the network (or read it from ``model``), then sail its greedy policy."""
        problem.check_simple_course(self.name)
        s = self.settings or problem.settings.dqn
        seed = problem.settings.seed if self.seed is None else self.seed
        t0 = _time.perf_counter()
        path = model_path(problem.scenario.base_dir, s.model) if s.model else None
        net = QNetwork.load(path, s) if path is not None and path.exists() else None
        info: dict[str, Any] = {"loaded": net is not None}
        if net is None:
            with _one_thread():
                net, more = train(problem, s, seed, progress=progress)
            info.update(more)
            if path is not None:
                net.save(path, s)
        trained = _time.perf_counter() - t0
        track = sail_greedy(problem, s, net)
        stats = {
            "episodes": s.episodes,
            "training_s": trained if not info["loaded"] else 0.0,
            "runtime_s": _time.perf_counter() - t0,
            "model": str(path) if path is not None else None,
            "decisions": len(track) - 1,
            **info,
        }
        lon = np.array([c.lon for c in track])
        lat = np.array([c.lat for c in track])
        return PlannedTrack(self.name, lon, lat, np.array([c.t_h for c in track]), track[-1].done, stats)
