"""Time against reliability (issue 20): the bottleneck and voyage fronts, the label cap, failure-mode sensitivity.

References: every path of a small grid enumerated and costed leg by leg (``leg_costs``, ``leg_exposure``) with the
non-dominated ones picked by an O(n^2) comparison; routes at single apf values run separately; the failure table
read through ``p_fail`` with the criterion's evidence set by hand.
"""

from __future__ import annotations

import itertools
import json
import re
import subprocess
import sys
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pyroute_rel.errors import FailureModelError, LabelLimitError, ScenarioError
from pyroute_rel.reliability.exposure import leg_exposure
from pyroute_rel.reliability.failure import load_failure_model
from pyroute_rel.routing.grid import Grid
from pyroute_rel.routing.route import route_on_grid
from pyroute_rel.routing.solve import RoutingProblem, leg_costs
from pyroute_rel.routing.tradeoff import (
    Front,
    bottleneck_front,
    bounding_criterion,
    course_bottleneck_front,
    course_voyage_front,
    pareto_indices,
    refined_front,
    sensitivity,
    voyage_front,
)
from pyroute_rel.scenario import Scenario, load_scenario, scenario_from_mapping
from pyroute_rel.weather import Conditions, WeatherBase

ROOT = Path(__file__).resolve().parents[1]
CONTROL = ROOT / "examples" / "microtransat_control.toml"
REL = 1e-9


def small(seed: int, **grid: Any) -> Scenario:
    """A short all-to-all course (3 ranks of 5 nodes: 125 paths) with two random patches of the control course's
    kinds: 4 m waves (criterion WH) and waves from 240 deg (WD)."""
    rng = np.random.default_rng(seed)
    patches = []
    for field, value in (("hs_m", 4.0), ("wave_dir_deg", 240.0)):
        lon, lat = rng.uniform(-15.5, -12.5), rng.uniform(43.2, 44.8)
        w, h = rng.uniform(0.3, 1.5), rng.uniform(0.3, 1.5)
        patches.append({"lon": [lon - w, lon + w], "lat": [lat - h, lat + h], field: value})
    return scenario_from_mapping(
        {
            "route": {"start": [-12.0, 45.0], "finish": [-16.0, 43.0], "departure": "2018-06-01T00:00:00Z"},
            "grid": {"layout": "square", "n_ranks": 3, "n_nodes": 5, **grid},
            "weather": {
                "kind": "uniform",
                "tws_kn": 15.0,
                "twd_deg": 0.0,
                "hs_m": 1.0,
                "wave_dir_deg": 0.0,
                "patch": patches,
            },
            "avoid": {"land": False},
            "failure": {"model": "dickson2018", "apf": 1.0},
        }
    )


@dataclass(frozen=True)
class Unsteady(WeatherBase):
    """A weather source that says it varies in time (so nothing is screened or shared across departures), with
    ``hs_m`` raised to ``storm_hs_m`` inside ``box`` from ``storm_h`` hours after ``t0`` on (None: never)."""

    base: Any
    t0: np.datetime64
    box: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)
    storm_h: float | None = None
    storm_hs_m: float = 5.0

    steady = False

    @property
    def time_steps(self) -> np.ndarray:
        """Where the conditions change in time: at the storm's start (none without a storm)."""
        if self.storm_h is None:
            return np.array([], dtype="datetime64[ns]")
        return np.array([self.t0 + np.timedelta64(int(round(self.storm_h * 3600e9)), "ns")], dtype="datetime64[ns]")

    @property
    def fields(self) -> frozenset[str]:
        return self.base.fields

    @property
    def max_current_ms(self) -> float:
        return self.base.max_current_ms

    def sample(self, lon_deg: Any, lat_deg: Any, time: Any) -> Conditions:
        c = self.base.sample(lon_deg, lat_deg, self.t0)
        if self.storm_h is None:
            return c
        lon, lat = np.broadcast_arrays(np.asarray(lon_deg, float), np.asarray(lat_deg, float))
        hours = (np.asarray(time, dtype="datetime64[s]") - self.t0) / np.timedelta64(3600, "s")
        w, e, s, n = self.box
        storm = (lon >= w) & (lon <= e) & (lat >= s) & (lat <= n) & (hours >= self.storm_h)
        return replace(c, hs_m=np.where(storm, self.storm_hs_m, np.broadcast_to(c.hs_m, storm.shape)))

    def check_coverage(self, *args: Any) -> None:
        return None

    def prepare(self, lon_deg: Any, lat_deg: Any) -> tuple[Any, Any]:
        return lon_deg, lat_deg

    def sample_at(self, prepared: Any, departure: Any, *, offset_h: Any = None, fields: Any = None) -> Conditions:
        time = np.asarray(departure, dtype="datetime64[s]")
        if offset_h is not None:
            with np.errstate(invalid="ignore"):
                time = time + np.round(np.asarray(offset_h, dtype=float) * 3600.0).astype("timedelta64[s]")
        return self.sample(*prepared, time)


def every_path(
    grid: Grid, problem: RoutingProblem, exposure: RoutingProblem | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Voyage time [h], largest leg p_f and hazard of every sailable path, each costed leg by leg; the hazard in
    ``exposure``'s weather (default ``problem``'s): a steady problem's when ``problem`` wraps steady weather as
    time-varying (to screen nothing), since exposure times a leg's sub-arcs by their own speeds in steady weather and
    on the leg's sailed sub-segments (pyroute_rel.boat.march) in weather that changes in time."""
    adj = []
    for k in range(grid.n_ranks + 1):
        src, valid = grid.pattern(k)
        adj.append({(int(src[j, c]), j) for j, c in zip(*np.nonzero(valid), strict=True)})
    out = []
    for nodes in itertools.product(range(grid.n_nodes), repeat=grid.n_ranks):
        if (0, nodes[0]) not in adj[0] or (nodes[-1], 0) not in adj[-1]:
            continue
        if any((nodes[k - 1], nodes[k]) not in adj[k] for k in range(1, grid.n_ranks)):
            continue
        ranks = np.arange(grid.n_ranks)
        lon = np.concatenate([[grid.start[0]], grid.lon_deg[ranks, list(nodes)], [grid.finish[0]]])
        lat = np.concatenate([[grid.start[1]], grid.lat_deg[ranks, list(nodes)], [grid.finish[1]]])
        elapsed, costs = leg_costs(problem, lon, lat)
        if not np.all(np.isfinite(costs.time_h)):
            continue
        h = leg_exposure(
            exposure or problem, lon, lat, elapsed[:-1], costs.time_h, costs.p_f, marks_h=costs.marks_h
        ).hazard.sum()
        out.append((elapsed[-1], float(np.max(costs.p_f)), h))
    a = np.array(out)
    return a[:, 0], a[:, 1], a[:, 2]


def nondominated(a: np.ndarray, b: np.ndarray) -> list[tuple[float, float]]:
    """The non-dominated (a, b) pairs by an O(n^2) comparison (duplicates once), sorted by a."""
    pts = set()
    for i in range(a.size):
        dominated = np.any((a <= a[i]) & (b <= b[i]) & ((a < a[i]) | (b < b[i])))
        if not dominated and np.isfinite(a[i]):
            pts.add((float(a[i]), float(b[i])))
    return sorted(pts)


def same_points(got: list[tuple[float, float]], want: list[tuple[float, float]]) -> None:
    assert len(got) == len(want), (got, want)
    for (t1, x1), (t2, x2) in zip(got, want, strict=True):
        assert t1 == pytest.approx(t2, rel=REL)
        assert x1 == pytest.approx(x2, rel=REL, abs=1e-12)


def check_sorted_nondominated(front: Front, objective: str) -> None:
    t = np.array([p.voyage_time_h for p in front.points])
    x = np.array([getattr(p, objective) for p in front.points])
    assert np.all(np.diff(t) > 0) and np.all(np.diff(x) < 0)
    assert nondominated(t, x) == sorted(zip(t.tolist(), x.tolist(), strict=True))


def on_or_dominated(front: Front, objective: str, t: float, x: float) -> bool:
    return any(
        p.voyage_time_h <= t * (1 + REL) and getattr(p, objective) <= x + 1e-12 + REL * abs(x) for p in front.points
    )


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 6), st.integers(0, 6)), min_size=1, max_size=30))
def test_pareto_indices_keep_exactly_the_nondominated_points_sorted(pairs: list[tuple[int, int]]) -> None:
    a, b = (np.array(v, dtype=float) for v in zip(*pairs, strict=True))
    idx = pareto_indices(a, b)
    assert [(a[i], b[i]) for i in idx] == nondominated(a, b)


SEEDS = [0, *(pytest.param(s, marks=pytest.mark.slow) for s in (1, 2, 3))]


@pytest.mark.slow
@pytest.mark.parametrize("seed", [0, 2])
def test_voyage_front_equals_every_path_enumerated_on_steady_weather(seed: int) -> None:
    sc = small(seed)
    grid = sc.make_grid()
    problem = sc.problem(grid=grid)
    front = voyage_front(grid, problem)
    check_sorted_nondominated(front, "hazard")
    reference = replace(problem, weather=Unsteady(problem.weather, problem.departure))  # nothing screened
    t, _, h = every_path(grid, reference, problem)
    same_points([(p.voyage_time_h, p.hazard) for p in front.points], nondominated(t, h))
    # the fastest and the safest paths are on it, and each point's route reports the voyage probability of its label
    assert front.points[0].voyage_time_h == pytest.approx(route_on_grid(grid, problem).voyage_time_h, rel=REL)
    assert front.points[-1].hazard == pytest.approx(h.min(), rel=REL, abs=1e-12)
    for p in front.points:
        assert p.route.voyage_failure_probability == pytest.approx(-np.expm1(-p.hazard), rel=REL, abs=1e-12)
        assert p.route.voyage_time_h == pytest.approx(p.voyage_time_h, rel=REL)
    assert 1 <= front.labels_mean <= front.labels_max  # type: ignore[operator]


@pytest.mark.slow
@pytest.mark.parametrize("seed", SEEDS)
def test_bottleneck_front_equals_every_path_and_dominates_every_single_apf_route(seed: int) -> None:
    sc = small(seed)
    grid = sc.make_grid()
    problem = sc.problem(grid=grid)
    front = bottleneck_front(grid, problem)
    check_sorted_nondominated(front, "max_failure_probability")
    t, m, _ = every_path(grid, problem)
    same_points([(p.voyage_time_h, p.max_failure_probability) for p in front.points], nondominated(t, m))
    for apf in (0.0, 0.1, 0.5, 0.9, 0.92, 0.95, 1.0):
        try:
            r = sc.with_options(apf=apf).route()
        except Exception:  # no route at this apf: nothing to place
            continue
        assert on_or_dominated(front, "max_failure_probability", r.voyage_time_h, r.max_failure_probability)


@pytest.mark.slow
def test_voyage_front_is_exact_over_fifo_time_varying_weather() -> None:
    """A storm (4 m -> 5 m waves, WH fires) grows over a box from hour 30: leaving an arc later never arrives
    earlier (the wind is steady) nor meets less hazard, so dropping dominated labels loses nothing."""
    sc = small(5)
    grid = sc.make_grid()
    base = sc.problem(grid=grid)
    weather = Unsteady(base.weather, base.departure, box=(-15.0, -13.0, 43.0, 44.5), storm_h=30.0)
    problem = replace(base, weather=weather)
    front = voyage_front(grid, problem)
    t, _, h = every_path(grid, problem)
    assert len(nondominated(t, h)) > 1
    same_points([(p.voyage_time_h, p.hazard) for p in front.points], nondominated(t, h))


@pytest.mark.parametrize("seed", [0, 4])
def test_voyage_front_points_are_their_routes_bit_for_bit(seed: int) -> None:
    """The figures and tracks computed for all front routes at once are those of each route built on its own
    (build_route on the label's path, the previous implementation), to the last bit."""
    sc = small(seed, n_nodes=6)
    grid = sc.make_grid()
    front = voyage_front(grid, sc.problem(grid=grid))
    assert len(front.points) > 1
    for p in front.points:
        r = p.route
        assert p.voyage_time_h == r.voyage_time_h and p.distance_nm == r.distance_nm
        assert p.max_failure_probability == r.max_failure_probability
        assert p.voyage_failure_probability == r.voyage_failure_probability + 0.0
        assert p.track() == r.summary()["track"]
        np.testing.assert_array_equal(p.elapsed_h, r.elapsed_h)


def two_legs(seed: int) -> Scenario:
    """:func:`small`'s course through a waypoint: two legs of 2 ranks of 5 nodes (25 paths each, 625 in all)."""
    sc = small(seed)
    return replace(sc, waypoints=((-14.0, 44.5),), n_ranks=4)


def every_course(sc: Scenario) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Voyage time [h], largest leg p_f and hazard of every path through the course: every path of each leg's grid
    (:func:`every_path`; the hazards with nothing screened) combined with every path of the other leg (steady
    weather: a leg's figures do not depend on when it is sailed)."""
    per_leg = []
    for g in sc.leg_grids():
        problem = sc.problem(grid=g)
        t, m, _ = every_path(g, problem)  # p_f as the router costs it (as for one grid)
        _, _, h = every_path(g, replace(problem, weather=Unsteady(problem.weather, problem.departure)), problem)
        per_leg.append((t, m, h))
    (t1, m1, h1), (t2, m2, h2) = per_leg
    return (t1[:, None] + t2).ravel(), np.maximum(m1[:, None], m2).ravel(), (h1[:, None] + h2).ravel()


@pytest.mark.parametrize("seed", [0, pytest.param(2, marks=pytest.mark.slow)])
def test_course_fronts_through_a_waypoint_equal_every_path_enumerated(seed: int) -> None:
    """The voyage front carries the labels at the mark into the next leg; the bottleneck front routes the course at
    each threshold: both equal the non-dominated paths of the concatenated graph, enumerated."""
    sc = two_legs(seed)
    legs = [(g, sc.problem(grid=g)) for g in sc.leg_grids()]
    assert [g.n_ranks for g, _ in legs] == [2, 2]
    t, m, h = every_course(sc)
    voyage = course_voyage_front(legs)
    check_sorted_nondominated(voyage, "hazard")
    assert len(voyage.points) > 2
    same_points([(p.voyage_time_h, p.hazard) for p in voyage.points], nondominated(t, h))
    bottleneck = course_bottleneck_front(legs)
    check_sorted_nondominated(bottleneck, "max_failure_probability")
    same_points([(p.voyage_time_h, p.max_failure_probability) for p in bottleneck.points], nondominated(t, m))
    assert bottleneck.points[0].route.voyage_time_h == sc.route().voyage_time_h  # the course as `route` sails it
    for p in voyage.points:  # each point is its joined route's, bit for bit
        r = p.route
        assert len(r.course_legs) == 2
        assert p.voyage_time_h == r.voyage_time_h and p.distance_nm == r.distance_nm
        assert p.voyage_failure_probability == r.voyage_failure_probability + 0.0
        assert p.max_failure_probability == r.max_failure_probability and p.track() == r.summary()["track"]


@pytest.mark.slow
def test_refined_bottleneck_front_is_no_worse_and_each_point_is_route_refine() -> None:
    """Each refined point is `route --apf P --refine 2` run on its own (a fresh grid), and every grid point is
    dominated by or equal to a refined one."""
    sc = load_scenario(CONTROL).with_options(n_ranks=24, apf=1.0)
    grid = sc.make_grid()
    front = bottleneck_front(grid, sc.problem(grid=grid))
    refined = refined_front(front, lambda apf: sc.with_options(apf=apf, refine=2).route(grids=[grid]))
    check_sorted_nondominated(refined, "max_failure_probability")
    assert refined.runs == front.runs + len(front.points)
    for p in front.points:
        assert on_or_dominated(refined, "max_failure_probability", p.voyage_time_h, p.max_failure_probability)
    assert refined.points[0].voyage_time_h < front.points[0].voyage_time_h  # the corridors gain something here
    for p in refined.points:
        alone = sc.with_options(apf=p.apf, refine=2).route()
        assert p.voyage_time_h == alone.voyage_time_h and p.max_failure_probability <= p.apf  # type: ignore[operator]
        assert p.route.meta["refine"]["levels"]
    with pytest.raises(ScenarioError, match="only the bottleneck front"):
        refined_front(replace(front, kind="voyage"), lambda apf: sc.route())


def test_label_cap_is_refused_naming_the_knob() -> None:
    sc = small(0)
    grid = sc.make_grid()
    problem = sc.problem(grid=grid)
    assert voyage_front(grid, problem).labels_max > 1  # type: ignore[operator]
    with pytest.raises(LabelLimitError, match="--max-labels") as info:
        voyage_front(grid, problem, max_labels=1)
    # how to choose the cap (issue 34): the labels held by then and their mean a node, for the user to scale from
    m = re.search(
        r"needs (\d+) non-dominated labels .* \(it held (\d+) labels by then, (\d+) a node on average", str(info.value)
    )
    assert m is not None, str(info.value)
    need, held, mean = (int(g) for g in m.groups())
    assert need > 1 and held >= need and 1 <= mean <= need
    with pytest.raises(ScenarioError, match="max_labels"):
        voyage_front(grid, problem, max_labels=0)
    with pytest.raises(ScenarioError, match="time_step_h"):
        voyage_front(grid, replace(problem, time_step_h=1.0))


def test_without_removes_a_criterion_from_the_table() -> None:
    m = load_failure_model("dickson2018")
    for node in ("WH", "WD"):
        w = m.without(node)
        for hs, awd in itertools.product([1.0, 4.5, np.nan], [10.0, 90.0, np.nan]):
            q = {"hs_m": np.array([hs]), "awd_deg": np.array([awd])}
            nominal = {"WH": {"hs_m": np.array([1.0])}, "WD": {"awd_deg": np.array([90.0])}}[node]
            want = m.p_fail({**q, **nominal})
            np.testing.assert_array_equal(w.p_fail(q), want)
    with pytest.raises(FailureModelError, match="no criterion 'XX'"):
        m.without("XX")


@pytest.mark.slow
@pytest.mark.parametrize("apf", [0.2, 0.5, 0.95])
def test_sensitivity_hours_are_the_difference_of_two_routes_run_separately(apf: float) -> None:
    sc = load_scenario(CONTROL).with_options(n_ranks=24, apf=apf)
    grid = sc.make_grid()
    problem = sc.problem(grid=grid)
    rows = sensitivity(grid, problem)
    with_all = sc.route()
    for row in rows:
        g = sc.make_grid()  # a grid of its own: nothing cached is shared with the sensitivity's runs
        alone = route_on_grid(g, replace(sc.problem(grid=g), failure=problem.failure.without(row.node)))  # type: ignore[union-attr]
        assert row.hours_cost == pytest.approx(with_all.voyage_time_h - alone.voyage_time_h, rel=REL, abs=1e-9)
        assert row.exposure_h == pytest.approx(with_all.exposure_by_criterion_h[row.criterion], rel=REL, abs=1e-12)
        assert (row.bound_h > 0) == bool(np.any(with_all.nodes != alone.nodes))
    which = bounding_criterion(rows, with_all.legs.n_legs)
    for i, row in enumerate(rows):
        assert np.all(row.bound_legs[which == i])


@pytest.mark.slow
def test_control_course_bottleneck_front_dominates_each_route_apf() -> None:
    sc = load_scenario(CONTROL).with_options(n_ranks=40)
    grid = sc.make_grid()
    front = bottleneck_front(grid, sc.problem(grid=grid))
    check_sorted_nondominated(front, "max_failure_probability")
    assert len(front.points) >= 2
    for apf in (0.0, 0.2, 0.5, 0.9, 0.95, 1.0):
        r = sc.with_options(apf=apf).route()
        assert on_or_dominated(front, "max_failure_probability", r.voyage_time_h, r.max_failure_probability)


@pytest.mark.slow
def test_control_course_voyage_front_dominates_each_route_apf() -> None:
    sc = load_scenario(CONTROL).with_options(n_ranks=40)
    grid = sc.make_grid()
    front = voyage_front(grid, sc.problem(grid=grid))
    check_sorted_nondominated(front, "hazard")
    for apf in (0.0, 0.2, 0.5, 0.9, 0.95, 1.0):
        r = sc.with_options(apf=apf).route()
        assert on_or_dominated(front, "voyage_failure_probability", r.voyage_time_h, r.voyage_failure_probability)


def small_toml(tmp_path: Path) -> Path:
    path = tmp_path / "small.toml"
    path.write_text(
        """[route]
start = [-12.0, 45.0]
finish = [-16.0, 43.0]
departure = "2018-06-01T00:00:00Z"
[grid]
layout = "square"
n_ranks = 3
n_nodes = 5
[weather]
kind = "uniform"
tws_kn = 15.0
twd_deg = 0.0
hs_m = 1.0
wave_dir_deg = 0.0
[[weather.patch]]
lon = [-15.0, -13.0]
lat = [43.5, 44.5]
hs_m = 4.0
[avoid]
land = false
[failure]
model = "dickson2018"
apf = 0.95
"""
    )
    return path


def cli(*args: str) -> subprocess.CompletedProcess[str]:
    """``python -m pyroute_rel`` in a child process (the package's own entry point)."""
    return subprocess.run([sys.executable, "-m", "pyroute_rel", *args], capture_output=True, text=True, cwd=ROOT)


def cli_here(capfd: pytest.CaptureFixture[str], *args: str) -> subprocess.CompletedProcess[str]:
    """The same command through :func:`pyroute_rel.cli.main` in this process (the function both entry points call:
    no interpreter to start; ``cli`` above keeps ``python -m pyroute_rel`` itself tested)."""
    from pyroute_rel.cli import main

    try:
        code = main(list(args))
    except SystemExit as exc:  # argparse's usage errors
        code = exc.code if isinstance(exc.code, int) else int(exc.code is not None)
    out, err = capfd.readouterr()
    return subprocess.CompletedProcess(["pyroute-rel", *args], code, out, err)


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["bottleneck", "voyage"])
def test_cli_json_contract_and_files(tmp_path: Path, kind: str, capfd: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "out"
    run = cli_here(
        capfd, "tradeoff", str(small_toml(tmp_path)), "--front", kind, "--json", "--out", str(out), "--quiet"
    )
    assert run.returncode == 0, run.stderr
    doc = json.loads(run.stdout)
    assert {"front", "sensitivity", "labels"} <= set(doc)
    assert doc["front"] and all(
        {"voyage_time_h", "max_failure_probability", "voyage_failure_probability", "track"} <= set(p)
        for p in doc["front"]
    )
    assert [r["criterion"] for r in doc["sensitivity"]] == ["WH: hs_m >= 4 m", "WD: awd_deg < 60 deg"]
    assert all({"criterion", "hours_cost", "exposure_h"} <= set(r) for r in doc["sensitivity"])
    assert set(doc["labels"]) == {"mean", "max"}
    assert (doc["labels"]["max"] is None) == (kind == "bottleneck")
    assert sorted(p.name for p in out.iterdir()) == ["front.png", "routes.png", "sensitivity.png", "tradeoff.json"]
    assert json.loads((out / "tradeoff.json").read_text())["front"] == doc["front"]


@pytest.mark.slow
def test_cli_refuses_a_bad_cap_with_exit_2(tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    run = cli_here(capfd, "tradeoff", str(small_toml(tmp_path)), "--front", "voyage", "--max-labels", "1", "--quiet")
    assert run.returncode == 2
    assert "--max-labels" in run.stderr and len(run.stderr.strip().splitlines()) == 1


@pytest.mark.slow
def test_cli_refuses_a_negative_cap_even_for_the_bottleneck_front(tmp_path: Path) -> None:
    out = tmp_path / "out"
    run = cli("tradeoff", str(small_toml(tmp_path)), "--max-labels", "-1", "--out", str(out), "--quiet")
    assert run.returncode == 2 and not out.exists()
    assert run.stderr.strip() == "pyroute-rel: error: --max-labels must be a whole number >= 1 (got -1)"


@pytest.mark.slow
def test_cli_refuses_a_cap_for_the_bottleneck_front_it_would_ignore(tmp_path: Path) -> None:
    """Issue 34: ``--max-labels`` was accepted and ignored for the bottleneck front."""
    out = tmp_path / "out"
    run = cli("tradeoff", str(small_toml(tmp_path)), "--max-labels", "5000", "--out", str(out), "--quiet")
    assert run.returncode == 2 and not out.exists()
    assert run.stderr.strip() == (
        "pyroute-rel: error: --max-labels applies to the voyage front (--front voyage): the bottleneck front holds "
        "one label a node"
    )


@pytest.mark.slow
def test_cli_through_a_waypoint_equals_the_library_and_refine_is_for_the_bottleneck_front(
    tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    path = small_toml(tmp_path)
    text = path.read_text().replace('departure = "2018', 'waypoints = [[-14.0, 44.5]]\ndeparture = "2018')
    path.write_text(text.replace("n_ranks = 3", "n_ranks = 4"))
    run = cli_here(capfd, "tradeoff", str(path), "--front", "voyage", "--json", "--quiet")
    assert run.returncode == 0, run.stderr
    sc = load_scenario(path)
    front = course_voyage_front([(g, sc.problem(grid=g)) for g in sc.leg_grids()])
    got = json.loads(run.stdout)["front"]
    assert [(p["voyage_time_h"], p["hazard"]) for p in got] == [(p.voyage_time_h, p.hazard) for p in front.points]
    assert all(len(p["track"]) == 7 for p in got)  # start, 2 nodes, the mark, 2 nodes, finish
    run = cli_here(capfd, "tradeoff", str(path), "--front", "voyage", "--refine", "1", "--quiet")
    assert run.returncode == 2 and "--refine applies to the bottleneck front" in run.stderr
    run = cli_here(capfd, "tradeoff", str(path), "--refine", "1", "--json", "--quiet")
    assert run.returncode == 0, run.stderr
    assert json.loads(run.stdout)["refine"] == 1
