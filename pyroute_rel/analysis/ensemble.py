"""Ensemble routing: route every member of an ensemble forecast, sail every route in every member, choose by risk.

Steps (:func:`route_ensemble`):

1. **Route every member** (:func:`pyroute_rel.analysis.members.member_scenario`: the scenario with ``[weather] member =
   k``, so a member's route is exactly ``pyroute-rel route`` with that key), and the ensemble-mean field (``member =
   "mean"``), in parallel on the local cores (one process per core, :mod:`concurrent.futures`) or on a dask cluster
   (``engine="dask"``: :mod:`pyroute_rel.batch.ensemble_dask`), each member in the next free process. A process keeps
   the weather file open from one member to the next and reads each member it routes once
   (:func:`~pyroute_rel.weather.io.readers.keep_files_open`); the mean field is read once, by the process routing it.
2. **Candidates** are the members' routes plus the route on the ensemble mean (a member with no feasible route gives
   no candidate).
3. **Sail every candidate in every member's weather** (:func:`pyroute_rel.analysis.evaluate.sail_tracks`, each leg
   costed as the router costs an arc): the time ``T[i, j]`` of candidate ``i`` in member ``j`` [h], its largest leg
   ``p_f`` and whether it is feasible there (no ``p_f > apf``, land, zone, or leg that cannot be sailed: then ``T =
   inf``). Each process sails every candidate in the members it routed, their weathers sampled together
   (:class:`~pyroute_rel.weather.gridded.MemberStack`: one call per leg, not one per member and leg).
4. **Regret** ``R[i, j] = T[i, j] - T*[j]``, ``T*[j]`` member ``j``'s own optimum (its route's voyage time): the
   hours lost by sailing candidate ``i`` when member ``j`` comes true. The diagonal is zero (re-timing a route gives
   its own figures); an entry is None where the candidate is infeasible in that member or the member has no route.
5. **Arrival distribution** of each candidate over the members (equally likely): mean, P5, P50, P95, CVaR at the
   chosen level and worst (:func:`arrival_stats`), and the fraction of members in which it meets ``p_f > apf``
   (``p_fail_conditions``) or is infeasible for any reason (``infeasible_members``).
6. **Choice**: among the candidates infeasible in the fewest members, the one with the least risk measure of its
   arrival times (:class:`Risk`: ``mean``, ``pXX``, ``cvar:ALPHA`` or ``worst``); the summary says by how many hours
   it beats the mean-field route.

Quantiles are empirical (the inverted CDF: ``P_q`` is the sorted time at index ``ceil(q n) - 1``); CVaR at level
``alpha`` is the mean of the worst ``1 - alpha`` of the distribution, ``(1 / (1 - alpha)) * integral from alpha to 1
of P_u du`` (Rockafellar and Uryasev 2002), which weighs the member straddling ``alpha`` by its share.

References
----------
Rockafellar, R. T. and Uryasev, S. (2002). Conditional value-at-risk for general loss distributions. Journal of
Banking & Finance 26, 1443-1471.
Tagliaferri, F. (2015). Risk-aware stochastic dynamic programming for yacht routing. PhD thesis, University of
Edinburgh (coherent risk measures over transition models).
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from pyroute_rel.analysis.evaluate import Track, evaluation_problem, member_figures
from pyroute_rel.analysis.members import member_count, member_scenario
from pyroute_rel.errors import (
    NoFeasibleRouteError,
    ScenarioError,
    WeatherCoverageError,
    brief,
    check_flag,
    check_instance,
    check_path,
)
from pyroute_rel.progress import progress_bar
from pyroute_rel.resources import pool_worker_init
from pyroute_rel.scenario import Scenario
from pyroute_rel.settings import Settings, get_settings, set_settings
from pyroute_rel.store import Shelf, current_store

__all__ = [
    "Risk",
    "parse_risk",
    "arrival_stats",
    "empirical_quantile",
    "cvar",
    "MemberRoute",
    "EnsembleResult",
    "route_ensemble",
    "route_member",
    "regret_matrix",
    "ENGINES",
]

FloatArray = npt.NDArray[np.float64]

#: Name of the route on the ensemble-mean field among the candidates.
MEAN_NAME = "mean"


@dataclass(frozen=True)
class Risk:
    """A risk measure of arrival times: ``kind`` is ``"mean"``, ``"quantile"`` (``level`` in (0, 1)), ``"cvar"``
    (``level`` in [0, 1)) or ``"worst"``."""

    kind: str
    level: float = 0.9

    def __str__(self) -> str:
        if self.kind == "quantile":
            return f"p{100 * self.level:g}"
        if self.kind == "cvar":
            return f"cvar:{self.level:g}"
        return self.kind

    def of(self, times_h: npt.ArrayLike) -> float:
        """The measure of arrival times [h] (``inf`` entries allowed: a route that cannot be completed)."""
        t = np.asarray(times_h, dtype=float)
        if self.kind == "mean":
            return float(np.mean(t)) if np.isfinite(t).all() else math.inf
        if self.kind == "quantile":
            return empirical_quantile(t, self.level)
        if self.kind == "cvar":
            return cvar(t, self.level)
        return float(np.max(t))


def parse_risk(text: str) -> Risk:
    """A :class:`Risk` from its name: ``mean``, ``pXX`` (``p90``: the 90th percentile), ``cvar:ALPHA``
    (``cvar:0.9``) or ``worst``.

    >>> parse_risk("p90"), parse_risk("cvar:0.75"), str(parse_risk("worst"))
    (Risk(kind='quantile', level=0.9), Risk(kind='cvar', level=0.75), 'worst')
    """
    s = str(text).strip().lower()
    try:
        if s in ("mean", "worst"):
            return Risk(s)
        if s.startswith("p") and 0.0 < float(s[1:]) < 100.0:
            return Risk("quantile", float(s[1:]) / 100.0)
        if s.startswith("cvar:") and 0.0 <= float(s[5:]) < 1.0:
            return Risk("cvar", float(s[5:]))
    except ValueError:
        pass
    raise ScenarioError(
        f"--risk must be mean, pXX (a percentile, e.g. p90), cvar:ALPHA (ALPHA in [0, 1), e.g. cvar:0.9) or worst "
        f"(got {brief(text)})"
    )


def empirical_quantile(times_h: npt.ArrayLike, q: float) -> float:
    """The empirical ``q``-quantile [h]: the sorted time at index ``ceil(q n) - 1`` (at least 0).

    >>> empirical_quantile([4.0, 1.0, 3.0, 2.0], 0.5), empirical_quantile([4.0, 1.0, 3.0, 2.0], 0.51)
    (2.0, 3.0)
    """
    t = np.sort(np.asarray(times_h, dtype=float))
    i = max(int(math.ceil(q * t.size - 1e-12)) - 1, 0)
    return float(t[i])


def cvar(times_h: npt.ArrayLike, alpha: float) -> float:
    """Conditional value at risk at level ``alpha`` [h]: the mean of the worst ``1 - alpha`` of equally likely times
    (the sorted time straddling ``alpha`` weighed by its share; see the module notes).

    >>> cvar([1.0, 2.0, 3.0, 4.0], 0.5), cvar([1.0, 2.0, 3.0, 4.0], 0.6), cvar([1.0, 2.0], 0.0)
    (3.5, 3.625, 1.5)
    """
    t = np.sort(np.asarray(times_h, dtype=float))
    n = t.size
    lo = np.arange(n) / n
    hi = (np.arange(n) + 1) / n
    w = np.clip(hi - np.maximum(lo, alpha), 0.0, None) / (1.0 - alpha)
    keep = w > 0
    return float(np.sum(w[keep] * t[keep]))


def arrival_stats(times_h: npt.ArrayLike, level: float = 0.9) -> dict[str, float]:
    """Mean, P5, P50, P95, CVaR at ``level`` and worst of equally likely arrival times [h] (``inf`` where a route
    cannot be completed: the measures that reach it are ``inf``)."""
    t = np.asarray(times_h, dtype=float)
    return {
        "mean": float(np.mean(t)) if np.isfinite(t).all() else math.inf,
        "p5": empirical_quantile(t, 0.05),
        "p50": empirical_quantile(t, 0.5),
        "p95": empirical_quantile(t, 0.95),
        "cvar": cvar(t, level),
        "worst": float(np.max(t)),
    }


@dataclass(frozen=True)
class MemberRoute:
    """One member's route, as a worker returns it: the track and its figures, or why there is none.

    Attributes
    ----------
    member : Member index (or ``"mean"``).
    lon_deg, lat_deg : Track points [deg] (empty without a route).
    voyage_time_h : Voyage time [h] (``inf`` without a route).
    max_failure_probability : The route's largest leg ``p_f`` sailed in its own member's weather (NaN before it is
        sailed, and for the mean-field route, which is sailed in the members only).
    error : Why there is no route (None when there is one).
    wait_h : The route's wait before each leg [h] (None: it never waits), kept so that it is sailed with them.
    """

    member: int | str
    lon_deg: FloatArray
    lat_deg: FloatArray
    voyage_time_h: float
    max_failure_probability: float = math.nan
    error: str | None = None
    wait_h: FloatArray | None = None

    @property
    def ok(self) -> bool:
        """True when the member has a route."""
        return self.error is None


# ------------------------------------------------------------------------------------------------ workers


# What a process keeps during one route_ensemble call: each member's scenario (and its weather) from its routing
# to its sailing (a member is sailed in the process that routed it), with the stamps of the files it was read from,
# and the course's grids, with the scenario file's stamp.
def _scenarios() -> Shelf:
    """Each member's scenario (with the stamps of the files it was read from, and the weather files it names), by
    (scenario file, member, member files, options), in the current store (:mod:`pyroute_rel.store`)."""
    return current_store().shelf("ensemble.scenarios", limit=1 << 16)


def _grids() -> Shelf:
    """The course's grids (with the scenario file's stamp), by scenario file and options, in the current store."""
    return current_store().shelf("ensemble.grids", limit=8)


def _inputs(path: str, files: tuple[str, ...] | None, weather: tuple[str, ...]) -> tuple[Any, ...]:
    """The stamps (path, size, modification time) of a member's files: the scenario file, the member files and the
    weather files the scenario names: a kept scenario is used again only while they are unchanged."""
    from pyroute_rel.weather.cache import file_stamps

    return file_stamps([path, *(files or ()), *weather])


def _weather_files(path: str) -> tuple[str, ...]:
    """The weather files a scenario file names (``[weather] paths``, resolved from its folder; none if it names
    none: reading it then says why)."""
    from pyroute_rel.analysis.members import scenario_table

    try:
        weather = scenario_table(Path(path)).get("weather", {})
    except ScenarioError:  # an unreadable file: the reading that follows says why
        return ()
    paths = weather.get("paths", []) if isinstance(weather, dict) else []
    if not isinstance(paths, list):
        return ()
    return tuple(str(Path(path).parent / str(p)) for p in paths)


def _scenario(path: str, member: int | str, files: tuple[str, ...] | None, options: dict[str, Any]) -> Scenario:
    """The member's scenario with the options, kept for the process while the files it was read from are
    unchanged (a scenario or weather file edited between calls is read again)."""
    key = (path, member, files, repr(sorted(options.items())))
    kept = _scenarios().get(key)
    if kept is not None and _inputs(path, files, kept[2]) == kept[1]:
        return kept[0]
    weather = _weather_files(path)
    stamps = _inputs(path, files, weather)  # before reading: an edit while it is read is seen next time
    sc = member_scenario(path, member, member_files=files).with_options(**options)
    _scenarios().put(key, (sc, stamps, weather))
    return sc


def route_member(
    path: str | Path,
    member: int | str,
    *,
    member_files: Sequence[str | Path] | None = None,
    options: dict[str, Any] | None = None,
) -> MemberRoute:
    """Route one member of a scenario file's ensemble (``"mean"``: the ensemble mean); a member without a feasible
    route (or whose weather does not cover the voyage) gives a :class:`MemberRoute` with its ``error``.

    The track and voyage time are those of ``pyroute-rel route`` with ``[weather] member = k`` (the same DP on the
    same grid); only the track is kept, not the route's per-leg description (:func:`route_ensemble` sails every
    track again in every member)."""
    files = None if member_files is None else tuple(str(f) for f in member_files)
    opts = dict(options or {})
    stamp = _inputs(str(path), None, ())
    sc = _scenario(str(path), member, files, opts)
    key = f"{path}:{sorted(opts.items())}"
    kept = _grids().get(key)
    if kept is not None and kept[1] == stamp:
        grids = kept[0]
    else:  # arc geometry and obstacle masks computed once per process (while the scenario file is unchanged)
        grids = sc.leg_grids()
        _grids().put(key, (grids, stamp))
    try:
        lon, lat, hours, waits = _track(sc, grids)
    except (NoFeasibleRouteError, WeatherCoverageError) as exc:
        return MemberRoute(member, np.zeros(0), np.zeros(0), math.inf, error=" ".join(str(exc).split()))
    return MemberRoute(member, lon, lat, hours, math.nan, wait_h=waits)


def _track(sc: Scenario, grids: list[Any]) -> tuple[FloatArray, FloatArray, float, FloatArray | None]:
    """The route's track, voyage time [h] and waits [h] (None: none): the forward DP's path on the grid when the course
    is one leg that the DP finishes exactly as :meth:`Scenario.route <pyroute_rel.scenario.Scenario.route>` does (no
    waypoints, refinement, start or finish line, zones, waiting or manoeuvre penalties), else that route's."""
    simple = (
        len(grids) == 1
        and not sc.refine
        and sc.start_line is None
        and sc.finish_line is None
        and not sc.avoid.zones
        and sc.time_step_h is None
    )
    problem = sc.problem(grid=grids[0]) if simple else None
    if problem is None or problem.sides:
        route = sc.route(grids=grids, relax_wider=False)
        waits = np.asarray(route.legs.wait_h, dtype=float)
        return route.lon_deg, route.lat_deg, route.voyage_time_h, waits if waits.any() else None
    from pyroute_rel.obstacles.mask import check_points
    from pyroute_rel.routing.solve import explain_infeasible, forward_dp

    check_points(sc.marks(), sc.avoid)
    grid = grids[0]
    s_lon, s_lat = grid.start_points
    lons, lats = [*s_lon, grid.finish[0]], [*s_lat, grid.finish[1]]
    sc.weather.check_coverage((min(lons), max(lons)), (min(lats), max(lats)), (sc.departure, sc.departure))
    result = forward_dp(grid, problem)
    if result.dead_rank is not None or not np.isfinite(result.finish_h):
        sc.route(grids=grids, relax_wider=False)  # raises the scenario's error, with what would make it route
        raise NoFeasibleRouteError(explain_infeasible(grid, problem, result))
    lon, lat = result.points(grid)
    return lon, lat, float(result.finish_h), None


def _sail_in_members(
    path: str,
    members: list[int],
    files: tuple[str, ...] | None,
    options: dict[str, Any],
    tracks: list[Track],
    land: bool,
) -> tuple[FloatArray, FloatArray, npt.NDArray[np.bool_], npt.NDArray[np.bool_], npt.NDArray[np.bool_]]:
    """Every candidate sailed in each of some members' weather, all together
    (:func:`~pyroute_rel.analysis.evaluate.member_figures`, the figures of
    :func:`~pyroute_rel.analysis.evaluate.sail_in_members`): (time [h], largest p_f, meets p_f > apf, feasible, touches
    land), each of shape (candidates, members); land (the same in every member) is tested only when ``land``."""
    scs = [_scenario(path, m, files, options) for m in members]
    avoid = scs[0].avoid if land else replace(scs[0].avoid, land=False)
    # the members' scenarios differ in their weather only: one problem (its grid built once), each member's weather
    # in it; a member whose weather lacks a field of the first's has its own (which refuses a missing field)
    first = evaluation_problem(scs[0])
    fields = scs[0].weather.fields
    problems = [
        replace(first, weather=sc.weather) if sc.weather.fields == fields else evaluation_problem(sc) for sc in scs
    ]
    fig = member_figures(problems, tracks, avoid=avoid)
    return fig.voyage_time_h, fig.max_p_f, fig.over_apf, fig.feasible, fig.on_land


def _worker_init(engines: Settings | None = None) -> None:
    """A worker's set-up for one route_ensemble call: one thread, the caller's ``engines``
    (:mod:`pyroute_rel.settings`), then :func:`_begin`."""
    os.environ["PYROUTE_REL_THREADS"] = "1"  # one process per core: no threads inside
    if engines is not None:
        set_settings(engines)
    _begin()


def _begin() -> None:
    """A process's set-up for one route_ensemble call: nothing kept from an earlier call (the files may have
    changed), the weather files kept open from one member to the next
    (:func:`~pyroute_rel.weather.io.readers.keep_files_open`)."""
    from pyroute_rel.weather.io.readers import keep_files_open

    _scenarios().clear()
    _grids().clear()
    keep_files_open(True)


def _worker_done() -> None:
    """Drop what a process kept for a route_ensemble call, and close the files it kept open."""
    from pyroute_rel.weather.io.readers import keep_files_open

    _scenarios().clear()
    _grids().clear()
    keep_files_open(False)


#: Modules the worker processes' fork server imports before it forks them.
_PRELOAD = (
    "pyroute_rel.analysis.ensemble",
    "pyroute_rel._kernels.cost",
    "pyroute_rel.routing.solve",
    "pyroute_rel.analysis.evaluate",
    "pyroute_rel.weather.io.readers",
)


def _forget(path: str, member: int | str, files: tuple[str, ...] | None, options: dict[str, Any]) -> None:
    """Drop a member's scenario from the process (the mean field's, once routed: it is not sailed in)."""
    _scenarios().discard((path, member, files, repr(sorted(options.items()))))


class _Workers:
    """Worker processes, each one process, so that a task can be sent to the process that holds a member's weather
    (None for one worker: everything runs in this process)."""

    def __init__(self, n: int) -> None:
        self.pools: list[ProcessPoolExecutor] = []
        if n > 1:
            import multiprocessing
            from multiprocessing import forkserver

            context = multiprocessing.get_context("forkserver")  # not fork: this process may run threads
            # the server imports what a member's routing needs once, and forks the processes from it: they start
            # with it imported (each importing it costs 1.5 processor seconds); ignored if the server already runs
            context.set_forkserver_preload(["__main__", *_PRELOAD])
            # started now, without waiting: it imports while this process counts the members; the processes are
            # forked at the first task (forking one waits until the server has imported everything)
            forkserver.ensure_running()
            self.pools = [
                ProcessPoolExecutor(
                    max_workers=1,
                    mp_context=context,
                    initializer=pool_worker_init,
                    initargs=(os.getpid(), _worker_init, get_settings()),
                )
                for _ in range(n)
            ]

    @property
    def size(self) -> int:
        """Processes (1 for this process)."""
        return max(len(self.pools), 1)

    def balanced(self, tasks: list[tuple[Any, ...]], fn: Any, bar: Any) -> tuple[list[Any], list[int]]:
        """``[fn(*t) for t in tasks]``, each task sent to the next free process, in order; with the process each
        ran in."""
        if not self.pools:
            out = []
            for t in tasks:
                out.append(fn(*t))
                bar.update(1)
            return out, [0] * len(tasks)
        from concurrent.futures import FIRST_COMPLETED, wait

        results: list[Any] = [None] * len(tasks)
        where = [0] * len(tasks)
        running: dict[Any, tuple[int, int]] = {}
        todo = iter(range(len(tasks)))
        free = list(range(len(self.pools)))
        while True:
            for w in free:
                i = next(todo, None)
                if i is not None:
                    running[self.pools[w].submit(fn, *tasks[i])] = (i, w)
            free = []
            if not running:
                return results, where
            done, _ = wait(running, return_when=FIRST_COMPLETED)
            for f in done:
                i, w = running.pop(f)
                results[i], where[i] = f.result(), w
                free.append(w)
                bar.update(1)

    def each(self, tasks: list[tuple[Any, ...] | None], fn: Any) -> list[Any]:
        """``fn(*tasks[w])`` in process ``w`` (None: nothing there), all at once."""
        if not self.pools:
            return [None if t is None else fn(*t) for t in tasks]
        futures = [None if t is None else self.pools[w].submit(fn, *t) for w, t in enumerate(tasks)]
        return [None if f is None else f.result() for f in futures]

    def close(self) -> None:
        for p in self.pools:
            p.shutdown(cancel_futures=True)


# ------------------------------------------------------------------------------------------------ the ensemble


@dataclass(frozen=True, eq=False)
class EnsembleResult:
    """Every member routed and every candidate sailed in every member (:func:`route_ensemble`).

    Attributes
    ----------
    members : Member indices.
    routes : Each member's route (:class:`MemberRoute`, with its ``error`` where it has none), in ``members`` order.
    mean_route : The route on the ensemble-mean field (None when not routed).
    names : Candidate names: ``"member k"`` for member routes, ``"mean"`` for the mean-field route.
    sources : The member each candidate was routed in (``"mean"`` for the mean field).
    tracks : Each candidate's track, (N, 2) lon, lat [deg].
    time_h : Voyage time of candidate ``i`` sailed in member ``j`` [h], shape (candidates, members); ``inf`` where it
        cannot be completed.
    max_p_f : Its largest leg ``p_f`` there.
    p_fail : Whether it meets ``p_f > apf`` there.
    feasible : Whether it is feasible there (no ``p_f > apf``, land, zone, or leg that cannot be sailed).
    risk : The risk measure the choice minimises.
    """

    members: tuple[int, ...]
    routes: tuple[MemberRoute, ...]
    mean_route: MemberRoute | None
    names: tuple[str, ...]
    sources: tuple[int | str, ...]
    tracks: tuple[FloatArray, ...]
    time_h: FloatArray
    max_p_f: FloatArray
    p_fail: npt.NDArray[np.bool_]
    feasible: npt.NDArray[np.bool_]
    risk: Risk

    @property
    def own_h(self) -> FloatArray:
        """Each member's own optimum: its route's voyage time [h] (``inf`` without a route)."""
        return np.array([r.voyage_time_h for r in self.routes])

    @property
    def regret_h(self) -> FloatArray:
        """Regret of candidate ``i`` in member ``j`` [h] (:func:`regret_matrix`); NaN where infeasible."""
        return regret_matrix(self.time_h, self.own_h, self.feasible)

    @property
    def risk_values(self) -> FloatArray:
        """The risk measure of each candidate's arrival times [h]."""
        return np.array([self.risk.of(t) for t in self.time_h])

    @property
    def infeasible_fraction(self) -> FloatArray:
        """Fraction of members in which each candidate is infeasible."""
        return 1.0 - self.feasible.mean(axis=1)

    @property
    def chosen(self) -> int:
        """Index of the chosen candidate: the least risk among those infeasible in the fewest members."""
        frac = self.infeasible_fraction
        best = np.flatnonzero(np.isclose(frac, frac.min(), rtol=0.0, atol=1e-12))
        values = self.risk_values[best]
        return int(best[int(np.argmin(values))])

    @property
    def mean_index(self) -> int | None:
        """Index of the mean-field candidate (None without one)."""
        return self.names.index(MEAN_NAME) if MEAN_NAME in self.names else None

    def summary(self) -> dict[str, Any]:
        """The JSON contract of ``pyroute-rel ensemble --json`` (see the module notes)."""
        level = self.risk.level if self.risk.kind == "cvar" else 0.9
        regret = self.regret_h
        chosen = self.chosen
        values = self.risk_values
        m = self.mean_index
        with np.errstate(invalid="ignore"):  # inf - inf: neither has a finite risk
            beats = None if m is None else _num(values[m] - values[chosen])
        return {
            "members": [
                {
                    "member": r.member,
                    "voyage_time_h": _num(r.voyage_time_h),
                    "feasible": r.ok,
                    **({} if r.ok else {"reason": r.error}),
                }
                for r in self.routes
            ],
            "candidates": [
                {
                    "name": name,
                    "arrival_h": {k: _num(v) for k, v in arrival_stats(self.time_h[i], level).items()},
                    "risk_h": _num(values[i]),
                    "p_fail_conditions": float(self.p_fail[i].mean()),
                    "infeasible_members": float(self.infeasible_fraction[i]),
                    "max_p_f": float(np.max(self.max_p_f[i])),
                }
                for i, name in enumerate(self.names)
            ],
            "chosen": {
                "name": self.names[chosen],
                "risk": str(self.risk),
                "value_h": _num(values[chosen]),
                "infeasible_members": float(self.infeasible_fraction[chosen]),
                "mean_field_infeasible_members": None if m is None else float(self.infeasible_fraction[m]),
                "mean_field_value_h": None if m is None else _num(values[m]),
                "beats_mean_field_by_h": beats,
            },
            "regret_h": [[_num(v) for v in row] for row in regret],
            "time_h": [[_num(v) for v in row] for row in self.time_h],
            "feasible": self.feasible.tolist(),
        }


def _num(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def regret_matrix(time_h: npt.ArrayLike, own_h: npt.ArrayLike, feasible: npt.ArrayLike) -> FloatArray:
    """Regret ``time_h[i, j] - own_h[j]`` [h]; NaN where candidate ``i`` is infeasible in member ``j`` or member ``j``
    has no route (``own_h`` infinite).

    >>> regret_matrix([[10.0, 12.0], [11.0, 11.0]], [10.0, 11.0], [[True, True], [True, False]]).tolist()
    [[0.0, 1.0], [1.0, nan]]
    """
    t = np.asarray(time_h, dtype=float)
    own = np.asarray(own_h, dtype=float)[None, :]
    ok = np.asarray(feasible, dtype=bool) & np.isfinite(own) & np.isfinite(t)
    with np.errstate(invalid="ignore"):
        return np.where(ok, t - own, np.nan)


#: Engines of :func:`route_ensemble`.
ENGINES = ("auto", "inline", "processes", "dask")


def route_ensemble(
    path: str | Path,
    *,
    members: Sequence[int] | None = None,
    member_files: Sequence[str | Path] | None = None,
    risk: Risk | str = "cvar:0.9",
    mean_field: bool = True,
    workers: int | None = None,
    options: dict[str, Any] | None = None,
    progress: bool = False,
    engine: str = "auto",
    scheduler: str | None = None,
    connect_timeout_s: float = 10.0,
) -> EnsembleResult:
    """Route every member of a scenario's ensemble, sail every route in every member and choose by risk (see the
    module notes).

    Parameters
    ----------
    path : Scenario file whose ``[weather]`` files have a member dimension (or whose first file ``member_files``
        replace, one per member).
    members : Which members (default all).
    member_files : One weather file per member (:mod:`pyroute_rel.analysis.members`).
    risk : The risk measure (:func:`parse_risk`).
    mean_field : Also route the ensemble-mean field (with ``member_files``, their mean:
        :func:`~pyroute_rel.analysis.members.mean_of_files`).
    workers : Processes of the ``processes`` engine (default: the CPUs this process may use,
        :func:`~pyroute_rel.resources.default_workers`; 1: in this process), or of the ``dask`` engine's
        ``LocalCluster`` (default the same).
    options : Scenario options for every member (:meth:`~pyroute_rel.scenario.Scenario.with_options`).
    progress : Show progress bars.
    engine : Where members are routed and sailed: ``"auto"`` (the default: ``"dask"`` with a ``scheduler``, else
        ``"processes"``), ``"inline"`` (this process), ``"processes"`` (local processes) or ``"dask"``
        (``scheduler``'s cluster, else a ``LocalCluster`` of ``workers`` processes:
        :mod:`pyroute_rel.batch.ensemble_dask`). The result does not depend on the engine.
    scheduler : Address of a running dask scheduler, ``tcp://HOST:PORT``.
    connect_timeout_s : How long to try reaching ``scheduler`` (and to wait for a worker there) [s].

    Raises
    ------
    NoFeasibleRouteError
        When no member has a route.
    ScenarioError
        When the scenario has no ensemble, ``members`` names members it does not have, or the scheduler cannot be
        reached.
    """
    _check_ensemble_args(path, members, member_files, mean_field, workers, options, progress)
    engine = _check_engine(engine, workers, scheduler, connect_timeout_s)
    r = parse_risk(risk) if isinstance(risk, str) else check_instance(risk, Risk, "risk", ScenarioError)
    jobs = None if members is None else len(members) + int(bool(mean_field))
    pool = _engine(engine, workers, scheduler, connect_timeout_s, jobs)
    try:
        _begin()  # this process routes the members with the inline engine
        n = member_count(path, member_files=member_files)
        chosen = list(range(n)) if members is None else [int(m) for m in members]
        bad = [m for m in chosen if not 0 <= m < n]
        if bad or not chosen:
            raise ScenarioError(f"--members must name members in [0, {n - 1}] (got {bad or 'none'})")
        files = None if member_files is None else tuple(str(Path(f).resolve()) for f in member_files)
        with_mean = bool(mean_field)
        return _route_and_sail(path, chosen, files, dict(options or {}), with_mean, r, pool, progress)
    finally:
        pool.close()
        _worker_done()


def _check_ensemble_args(
    path: Any, members: Any, member_files: Any, mean_field: Any, workers: Any, options: Any, progress: Any
) -> None:
    """The arguments of :func:`route_ensemble` checked before any file is read: ScenarioError naming the argument."""
    check_path(path, "scenario", ScenarioError)
    if members is not None:
        check_instance(members, (list, tuple, range, np.ndarray), "members", ScenarioError, expected="a list of ints")
        if any(isinstance(m, bool) or not isinstance(m, int | np.integer) for m in members):
            raise ScenarioError(f"members must be whole numbers (member indices) (got {brief(members)})")
        twice = sorted({int(m) for m in members if list(members).count(m) > 1})
        if twice:  # each member is one equally likely weather: a repeat would weigh it twice in every risk measure
            raise ScenarioError(f"members must name each member once (got {twice} more than once)")
    if member_files is not None:
        check_instance(member_files, (list, tuple), "member_files", ScenarioError, expected="a list of file names")
        for f in member_files:
            check_path(f, "member_files item", ScenarioError)
    check_flag(mean_field, "mean_field", ScenarioError)
    check_flag(progress, "progress", ScenarioError)
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
        raise ScenarioError(f"workers must be a whole number >= 1 or None (got {brief(workers)})")
    if options is not None:
        check_instance(options, dict, "options", ScenarioError, expected="a dict of scenario options or None")


def _check_engine(engine: Any, workers: int | None, scheduler: Any, connect_timeout_s: Any) -> str:
    """The engine :func:`route_ensemble` uses (``"auto"`` resolved), its options checked: ScenarioError naming
    the option."""
    from pyroute_rel.batch.cluster import WorkersOption, check_engine_combinations, check_engine_name

    check_engine_name(engine, ENGINES, ScenarioError)
    if scheduler is not None and (not isinstance(scheduler, str) or not scheduler.strip()):
        raise ScenarioError(f"--scheduler must be a dask scheduler's address, tcp://HOST:PORT (got {brief(scheduler)})")
    meaning = WorkersOption(
        scheduler_engines=("auto", "dask"),
        with_scheduler="--workers sets a LocalCluster's processes: give it or --scheduler, not both",
        with_inline="--workers {workers} needs the processes or dask engine (got engine 'inline')",
        inline_allows=(1,),
    )
    check_engine_combinations(engine, workers, scheduler, meaning, ScenarioError)
    t = connect_timeout_s
    if isinstance(t, bool) or not isinstance(t, int | float) or not math.isfinite(t) or t <= 0:
        raise ScenarioError(f"connect_timeout_s (--connect-timeout) must be a finite number > 0 [s] (got {brief(t)})")
    if engine == "auto":
        return "dask" if scheduler is not None else "processes"
    return engine


def _engine(engine: str, workers: int | None, scheduler: str | None, timeout_s: float, jobs: int | None) -> Any:
    """The workers of an engine: :class:`_Workers` (local processes, or this process) or
    :class:`~pyroute_rel.batch.ensemble_dask.DaskWorkers`."""
    from pyroute_rel.resources import default_workers

    if engine == "dask":
        from pyroute_rel.batch.ensemble_dask import DaskWorkers, dask_client

        n = None if scheduler is not None else (workers or default_workers())
        return DaskWorkers(
            dask_client(scheduler, workers=n, timeout_s=timeout_s), setup=_worker_init, teardown=_worker_done
        )
    n = 1 if engine == "inline" else (default_workers() if workers is None else workers)
    return _Workers(n if jobs is None else min(n, jobs))


def _route_and_sail(
    path: str | Path,
    chosen: list[int],
    files: tuple[str, ...] | None,
    opts: dict[str, Any],
    with_mean: bool,
    r: Risk,
    pool: Any,
    progress: bool,
) -> EnsembleResult:
    """The two steps of :func:`route_ensemble`: route the members (and the mean, first: reading every member, it
    is the longest), each in the next free process; then sail every route in every member, each member in the
    process that routed it (which holds its weather), all its members together."""
    p = str(path)
    jobs = ([MEAN_NAME] if with_mean else []) + list(chosen)
    bar = progress_bar(len(jobs), enabled=progress, desc="routing members", unit="member")
    routed, where = pool.balanced([(p, m, files, opts) for m in jobs], _route_task, bar)
    bar.close()
    member_routes = tuple(routed[int(with_mean) :])
    mean_route = routed[0] if with_mean else None
    cands = [*member_routes, *([mean_route] if mean_route is not None else [])]
    cands = [x for x in cands if x is not None and x.ok]
    if not cands:
        raise NoFeasibleRouteError(f"no member has a feasible route: {member_routes[0].error}")
    names = tuple(MEAN_NAME if c.member == MEAN_NAME else f"member {c.member}" for c in cands)
    tracks = [np.column_stack([c.lon_deg, c.lat_deg]) for c in cands]
    sail = [Track(c.lon_deg, c.lat_deg, wait_h=c.wait_h) for c in cands]  # each sailed with its waits
    held: dict[int, list[int]] = {}
    for m, w in zip(jobs, where, strict=True):
        if m != MEAN_NAME:
            held.setdefault(w, []).append(int(m))
    n_w = pool.size
    tasks = [(p, held[w], files, opts, sail, w == min(held)) if w in held else None for w in range(n_w)]
    bar = progress_bar(len(chosen), enabled=progress, desc="sailing in members", unit="member")
    sailed = pool.each(tasks, _sail_task)
    bar.update(len(chosen))
    bar.close()
    column = {m: (w, i) for w in held for i, m in enumerate(held[w])}
    times, p_max, over, ok, on_land = (
        np.column_stack([sailed[column[m][0]][k][:, column[m][1]] for m in chosen]) for k in range(5)
    )
    ok = ok & ~on_land.any(axis=1, keepdims=True)  # land is tested in one process's members only
    own = {c.member: i for i, c in enumerate(cands)}
    member_routes = tuple(
        replace(mr, max_failure_probability=float(p_max[own[mr.member], j])) if mr.ok else mr
        for j, mr in enumerate(member_routes)
    )
    return EnsembleResult(
        members=tuple(chosen),
        routes=member_routes,
        mean_route=mean_route,
        names=names,
        sources=tuple(c.member for c in cands),
        tracks=tuple(tracks),
        time_h=times,
        max_p_f=p_max,
        p_fail=over,
        feasible=ok,
        risk=r,
    )


def _route_task(path: str, member: int | str, files: tuple[str, ...] | None, options: dict[str, Any]) -> MemberRoute:
    route = route_member(path, member, member_files=files, options=options)
    if member == MEAN_NAME:
        _forget(path, member, files, options)
    return route


def _sail_task(
    path: str, members: list[int], files: tuple[str, ...] | None, options: dict[str, Any], tracks: Any, land: bool
) -> Any:
    return _sail_in_members(path, members, files, options, tracks, land)
