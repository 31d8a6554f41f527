"""The compiled MCTS-UCT search (``engine = "lattice"``) and its weather modes (issue 22).

References: a brute-force enumeration of every heading sequence on a toy lattice, stepped with
:mod:`pyroute_rel.geodesy` and :func:`pyroute_rel.boat.polar.boat_speed_kn` (not the kernel's own arithmetic), and the
reward's closed form (Barde 2023); the evaluator's re-timing, GSHHG land and shapely for land, zones and apf on
densified tracks.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import shapely

from pyroute_rel import geodesy, scenario_from_mapping
from pyroute_rel._kernels.mcts import PARAMS, sailing_speeds, search
from pyroute_rel._kernels.polar import speed_kn
from pyroute_rel._kernels.polar import tables as polar_tables
from pyroute_rel.boat.polar import MIN_SPEED_KN, Polar, boat_speed_kn, get_polar
from pyroute_rel.errors import ScenarioError
from pyroute_rel.geodesy import gc_densify
from pyroute_rel.obstacles.land import points_on_land
from pyroute_rel.planners.mcts import MCTSPlanner
from pyroute_rel.planners.plan import plan
from pyroute_rel.planners.settings import parse_planner
from pyroute_rel.units import KM_PER_NM

evaluate = pytest.importorskip("pyroute_rel.analysis.evaluate")

#: The toy: 15 kn from the north, headings 45 deg apart of which only 135 and 225 may be sailed (TWA in
#: [100, 160]), 2 h steps, a lattice that ends 0.5 deg south of the start (leaving it is a dead end), the finish to the
#: south-east.
TOY = {
    "lon0": -0.5,
    "lat0": -0.5,
    "spacing": 0.05,
    "nx": 23,
    "ny": 15,
    "start": (0.0, 0.0),
    "finish": (0.2, -0.3),
    "step_h": 2.0,
    "nogo": (100.0, 160.0),
    "tws": 15.0,
    "time_max": 1000.0,
    "time_min": 1.0,
    "c": 1.001,
}


def toy_inputs(cp: float) -> tuple:
    polar = get_polar("maribot_vane")
    nx, ny = TOY["nx"], TOY["ny"]
    u = np.zeros((1, 1, ny, nx), dtype=np.float32)
    v = np.full((1, 1, ny, nx), TOY["tws"], dtype=np.float32)
    f = np.ones((1, 1, ny, nx), dtype=np.float32)
    sig = np.zeros((1, 1, 1), dtype=np.float32)
    okh = np.ones((1, 1, ny, nx, 8), dtype=np.uint8)
    open_ = np.ones((1, ny, nx), dtype=np.uint8)
    values = {
        "lon0": TOY["lon0"],
        "lat0": TOY["lat0"],
        "dlon": TOY["spacing"],
        "dlat": TOY["spacing"],
        "slice_h": 6.0,
        "step_h": TOY["step_h"],
        "nogo_min": TOY["nogo"][0],
        "nogo_max": TOY["nogo"][1],
        "finish_lon": TOY["finish"][0],
        "finish_lat": TOY["finish"][1],
        "time_max": TOY["time_max"],
        "time_min": TOY["time_min"],
        "reward_c": TOY["c"],
        "top_kn": float(np.max(polar.speed_kn)),
        "rollout_h": 0.0,
        "cp": cp,
        "min_speed": MIN_SPEED_KN,
        "forbid_beyond": 0.0,
        "perturbed": 0.0,
    }
    params = np.array([values[k] for k in PARAMS])
    return np.arange(8) * 45.0, (u, v, f, sig, sig), okh, open_, polar_tables(polar), params, polar


def _inside(lon: float, lat: float, half: float) -> bool:
    """The kernel's lattice: points within ``half`` a cell beyond its edge lookups (open) or on it (weather)."""
    d = TOY["spacing"]
    fx, fy = (lon - TOY["lon0"]) / d, (lat - TOY["lat0"]) / d
    return -half <= fx <= TOY["nx"] - 1 + half and -half <= fy <= TOY["ny"] - 1 + half


def _speed(polar, course: float) -> float:
    twa = float(geodesy.angle_diff_deg(0.0, course))
    return float(polar.speed(twa, TOY["tws"]))


def brute_force(polar, lon: float, lat: float, t: float) -> float:
    """The earliest arrival over every heading sequence from (lon, lat, t) [h] (inf: none arrives)."""
    if not _inside(lon, lat, 0.0):
        return math.inf
    fin = TOY["finish"]
    dist = float(geodesy.distance_nm(lon, lat, *fin))
    v_fin = _speed(polar, float(geodesy.initial_bearing_deg(lon, lat, *fin)))
    if v_fin >= MIN_SPEED_KN and dist <= v_fin * TOY["step_h"]:
        return t + dist / v_fin
    best = math.inf
    for h in np.arange(8) * 45.0:
        twa = float(geodesy.angle_diff_deg(0.0, h))
        v = _speed(polar, h)
        if not TOY["nogo"][0] <= twa <= TOY["nogo"][1] or v < MIN_SPEED_KN:
            continue
        lon1, lat1 = (float(x) for x in geodesy.destination_point(lon, lat, h, v * TOY["step_h"] * KM_PER_NM))
        if _inside(lon1, lat1, 0.499) and _inside((lon + lon1) / 2, (lat + lat1) / 2, 0.499):
            best = min(best, brute_force(polar, lon1, lat1, t + TOY["step_h"]))
    return best


def reward(date: float) -> float:
    """Barde's reward exp((TimeMax c - date) / (TimeMax c - TimeMin))."""
    top = TOY["time_max"] * TOY["c"]
    return math.exp((top - date) / (top - TOY["time_min"]))


@pytest.mark.slow
def test_full_search_finds_the_brute_force_best_of_each_first_heading():
    """With more iterations than the toy's tree has nodes, the best reward below each root heading is the reward of
    the earliest arrival over every heading sequence starting with it; the headings that may not be sailed are never
    tried."""
    hdg, w, okh, open_, tables, params, polar = toy_inputs(cp=50.0)
    rng = np.random.SeedSequence(3).generate_state(2, dtype=np.uint64)
    visits, wins, best = search(np.array([*TOY["start"], 0.0]), 20_000, hdg, w, okh, open_, tables, params, rng)
    assert set(np.flatnonzero(visits)) == {3, 5}  # 135 and 225 deg
    for a in (3, 5):
        h = hdg[a]
        v = _speed(polar, h)
        lon1, lat1 = geodesy.destination_point(*TOY["start"], h, v * TOY["step_h"] * KM_PER_NM)
        date = brute_force(polar, float(lon1), float(lat1), TOY["step_h"])
        assert math.isfinite(date)
        assert best[a] == pytest.approx(reward(date), rel=1e-9)
    assert visits.sum() == 20_000 and np.all(wins[visits > 0] / visits[visits > 0] <= best[visits > 0] + 1e-12)


def test_the_search_is_reproducible_and_seeded():
    hdg, w, okh, open_, tables, params, _ = toy_inputs(cp=1.0 / math.sqrt(2.0))
    runs = []
    for seed in (0, 0, 1):
        rng = np.random.SeedSequence(seed).generate_state(2, dtype=np.uint64)
        runs.append(search(np.array([*TOY["start"], 0.0]), 300, hdg, w, okh, open_, tables, params, rng))
    assert all(np.array_equal(x, y) for x, y in zip(runs[0], runs[1], strict=True))
    assert not all(np.array_equal(x, y) for x, y in zip(runs[0], runs[2], strict=True))


#: The short course of tests/test_planners.py (a failure patch across the great circle, apf 0.5).
SMALL = {
    "route": {"start": [-12.0, 45.0], "finish": [-14.0, 43.0], "departure": "2018-06-01T00:00:00Z"},
    "grid": {"layout": "square", "n_ranks": 5, "n_nodes": 7, "samples_per_arc": 4},
    "weather": {
        "kind": "uniform",
        "tws_kn": 15.0,
        "twd_deg": 0.0,
        "hs_m": 1.0,
        "patch": [{"lon": [-13.4, -12.6], "lat": [43.6, 44.4], "hs_m": 4.5}],
    },
    "failure": {"model": "dickson2018", "apf": 0.5},
    "avoid": {"land": False},
}
FAST = {"iterations": 60, "step_h": 6.0, "rollout_h": 24.0, "lattice_deg": 0.1}


def small(seed: int = 0, **mcts: object) -> object:
    return scenario_from_mapping({**SMALL, "planner": {"kind": "mcts", "seed": seed, "mcts": {**FAST, **mcts}}})


def test_perturbed_weather_with_no_spread_is_the_forecast_and_seeds_reproduce():
    forecast = plan(small(weather="forecast"))
    still = plan(small(weather="perturbed", sigma_scale=0.0))
    assert forecast.reached and forecast.stats["weather"] == "forecast" and still.stats["weather"] == "perturbed"
    assert np.array_equal(forecast.lon_deg, still.lon_deg) and np.array_equal(forecast.elapsed_h, still.elapsed_h)
    a, b = plan(small(weather="perturbed")), plan(small(weather="perturbed"))
    assert np.array_equal(a.lon_deg, b.lon_deg) and np.array_equal(a.elapsed_h, b.elapsed_h)
    ev = evaluate.evaluate_track(small(), a.points())
    assert np.allclose(ev.elapsed_h, a.elapsed_h, rtol=1e-12, atol=1e-9) and ev.max_failure_probability <= 0.5


def test_weather_and_engine_settings_are_checked():
    s = parse_planner({"mcts": {"weather": "perturbed", "sigma_scale": 0.5}}).mcts
    assert (s.weather, s.sigma_scale, s.engine) == ("perturbed", 0.5, "lattice")
    assert parse_planner({}).mcts.weather == "auto"
    for table, message in (
        (
            {"weather": "noisy"},
            r"\[planner.mcts\].weather must be one of \['auto', 'forecast', 'members', 'perturbed'\]",
        ),
        ({"engine": "gpu"}, r"\[planner.mcts\].engine must be one of \['lattice', 'python'\]"),
        ({"sigma_scale": -1.0}, r"\[planner.mcts\].sigma_scale must be a number in \[0, 100\]"),
        ({"engine": "python", "weather": "perturbed"}, "needs engine = 'lattice'"),
    ):
        with pytest.raises(ScenarioError, match=message):
            parse_planner({"mcts": table})
    with pytest.raises(ScenarioError, match="weather = 'members' needs ensemble members"):
        plan(small(weather="members"))


@pytest.mark.slow
@pytest.mark.parametrize("weather", ["forecast", "perturbed"])
def test_lattice_search_respects_land_zones_and_apf(weather, tmp_path):
    """A course past Guadeloupe through a zone, with a coastal margin and a failure patch (tests/test_planners.py's
    ISLAND): the sailed track stays off land, out of the zone and within apf, densified."""
    zone = {
        "type": "Feature",
        "properties": {"name": "box"},
        "geometry": {
            "type": "Polygon",
            "coordinates": [[[-62.2, 15.8], [-62.0, 15.8], [-62.0, 16.1], [-62.2, 16.1], [-62.2, 15.8]]],
        },
    }
    (tmp_path / "z.geojson").write_text(json.dumps({"type": "FeatureCollection", "features": [zone]}))
    table = {
        "route": {"start": [-62.4, 16.25], "finish": [-60.6, 16.25], "departure": "2018-06-01T00:00:00Z"},
        "grid": {"n_ranks": 8, "half_width_km": 80.0, "aspect": 2.0},
        "weather": {
            "kind": "uniform",
            "tws_kn": 15.0,
            "twd_deg": 0.0,
            "hs_m": 1.0,
            "patch": [{"lon": [-61.2, -61.0], "lat": [16.45, 16.75], "hs_m": 4.5}],
        },
        "failure": {"model": "dickson2018", "apf": 0.5},
        "avoid": {"land": True, "margin_km": 5.0, "zones": ["z.geojson"]},
        "planner": {"kind": "mcts", "mcts": {"iterations": 200, "weather": weather, "lattice_deg": 0.05}},
    }
    sc = scenario_from_mapping(table, base_dir=tmp_path)
    track = plan(sc)
    assert track.lon_deg.size > 5  # it sails (arriving here needs a longer look-ahead than 200 iterations give)
    x, y, _ = gc_densify(track.lon_deg[:-1], track.lat_deg[:-1], track.lon_deg[1:], track.lat_deg[1:], max_step_km=1.0)
    assert not points_on_land(x, y, margin_km=4.9).any()
    assert not shapely.contains_xy(shapely.box(-62.2, 15.8, -62.0, 16.1), x, y).any()
    ev = evaluate.evaluate_track(sc, track.points())
    assert ev.max_failure_probability <= 0.5 and ev.feasible


@pytest.mark.slow
def test_members_spread_is_the_perturbed_sigma_and_members_are_sampled():
    """Two uniform members, 14 and 16 kn from the north: "perturbed" draws about their mean, 15 kn from the north,
    with their sample standard deviation, sqrt(2) kn, on the north component and 0 on the east one; "members" keeps
    both; the planner sails either way and stays within apf."""
    from dataclasses import replace as dc_replace

    from pyroute_rel.planners.base import PlanningProblem
    from pyroute_rel.planners.mcts_lattice import build_lattice
    from pyroute_rel.weather.uniform import UniformWeather

    sc = small()
    base = PlanningProblem.of(sc)
    members = [UniformWeather(tws_kn=w, twd_deg=0.0, hs_m=1.0) for w in (14.0, 16.0)]
    pp = dc_replace(base, members=tuple(members))
    hdg = np.arange(8) * 45.0
    pert = build_lattice(pp, hdg, spacing_deg=0.2, slice_h=6.0, until_h=50.0, weather="perturbed")
    assert pert.u.shape[0] == 1 and np.allclose(pert.v, 15.0) and np.allclose(pert.u, 0.0, atol=1e-5)
    assert np.allclose(pert.sigma_v, math.sqrt(2.0)) and np.allclose(pert.sigma_u, 0.0, atol=1e-5)
    both = build_lattice(pp, hdg, spacing_deg=0.2, slice_h=6.0, until_h=50.0, weather="members")
    assert both.u.shape[0] == 2 and np.allclose(both.v[0], 14.0) and np.allclose(both.v[1], 16.0)
    for mode in ("members", "perturbed"):
        s = dc_replace(sc.planner.mcts, weather=mode)
        track = MCTSPlanner(s).plan(pp)
        assert track.stats["weather"] == mode and track.lon_deg.size > 1
        ev = evaluate.evaluate_track(sc, track.points())
        assert ev.max_failure_probability <= 0.5 and np.allclose(ev.elapsed_h, track.elapsed_h, rtol=1e-12)


@pytest.mark.slow
def test_perturbed_weather_from_the_command_line(tmp_path, capsys):
    from pyroute_rel.cli import main

    lines = [
        "[route]",
        "start = [-12.0, 45.0]",
        "finish = [-13.0, 44.0]",
        'departure = "2018-06-01T00:00:00Z"',
        "[grid]",
        'layout = "square"',
        "n_ranks = 5",
        "n_nodes = 7",
        "[weather]",
        'kind = "uniform"',
        "tws_kn = 15.0",
        "twd_deg = 0.0",
        "[avoid]",
        "land = false",
        "[planner.mcts]",
        'weather = "perturbed"',
        "iterations = 50",
        "step_h = 6.0",
        "rollout_h = 24.0",
        "lattice_deg = 0.1",
    ]
    path = tmp_path / "s.toml"
    path.write_text("\n".join(lines) + "\n")
    assert main(["route", str(path), "--planner", "mcts", "--json", "--quiet", "--out", str(tmp_path / "m")]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["planner"] == "mcts" and out["reached"] and out["feasible"]
    assert out["planner_stats"]["weather"] == "perturbed" and out["planner_stats"]["engine"] == "lattice"
    path.write_text("\n".join([*lines[:-5], 'weather = "noisy"']) + "\n")
    assert main(["route", str(path), "--planner", "mcts", "--quiet", "--out", str(tmp_path / "n")]) == 2
    err = capsys.readouterr().err
    assert "[planner.mcts].weather must be one of" in err and "Traceback" not in err


@pytest.mark.slow
@pytest.mark.parametrize(
    "polar",
    [
        get_polar("maribot_vane"),
        # a first row above 0 deg (no-go below it), a first column above 0 kn (linear to 0 below it), a TWS axis
        # longer than SHORT_AXIS (its cell guessed from the spacing) and uneven steps
        Polar(
            "long",
            twa_deg=[30.0, 45.0, 60.0, 90.0, 120.0, 150.0, 170.0],
            tws_kn=np.concatenate([[3.0], 4.5 + 1.5 * np.arange(24)]),
            speed_kn=np.add.outer(np.linspace(1.0, 3.0, 7), np.sqrt(np.arange(25.0))),
        ),
    ],
    ids=["maribot_vane", "long"],
)
@pytest.mark.parametrize("beyond", ["clamp", "forbid"])
def test_the_search_sails_at_the_dp_polar_speeds(polar, beyond):
    """The speeds the compiled search sails at equal the DP's compiled lookup and numpy's boat_speed_kn, bit for bit,
    on every node of the table, next to them, between them, below the first row and column, beyond the last, at 0
    and 180 deg, 0 kn and NaN."""

    def around(axis, low, high):
        mid = (axis[1:] + axis[:-1]) / 2.0
        return np.concatenate(
            [axis, np.nextafter(axis, -np.inf), np.nextafter(axis, np.inf), mid, [low, high, axis[-1] + 7.3, np.nan]]
        )

    twa = np.clip(around(polar.twa_deg, 0.0, 180.0), 0.0, 180.0)
    tws = np.maximum(around(polar.tws_kn, 0.0, 60.0), 0.0)
    a, w = (x.ravel() for x in np.meshgrid(twa, tws, indexing="ij"))
    tabs = polar_tables(polar)
    kernel = sailing_speeds(a, w, tabs, beyond == "forbid")
    shared = np.array([speed_kn(x, y, *tabs, beyond == "forbid") for x, y in zip(a, w, strict=True)])
    np.testing.assert_array_equal(kernel, shared)
    np.testing.assert_array_equal(kernel, boat_speed_kn(polar, a, w, beyond=beyond))
    assert np.isnan(kernel).any() and (kernel == 0.0).any() and (kernel > 0.0).any()


def test_a_search_in_chunks_is_the_search_in_one_and_reports_its_progress(monkeypatch):
    """Issue 34: a decision of many iterations showed nothing until it ended. The search now runs in chunks and
    reports each; the chunks change nothing (the same tree, the same random streams afterwards)."""
    import pyroute_rel._kernels.mcts as kernel

    hdg, w, okh, open_, tables, params, _ = toy_inputs(cp=1.0 / math.sqrt(2.0))
    root = np.array([*TOY["start"], 0.0])
    whole_rng = np.random.SeedSequence(5).generate_state(2, dtype=np.uint64)
    whole = search(root, 1000, hdg, w, okh, open_, tables, params, whole_rng)
    monkeypatch.setattr(kernel, "CHUNK", 300)
    rng = np.random.SeedSequence(5).generate_state(2, dtype=np.uint64)
    reported: list[int] = []
    chunked = search(root, 1000, hdg, w, okh, open_, tables, params, rng, reported.append)
    assert reported == [300, 300, 300, 100]
    assert all(np.array_equal(x, y) for x, y in zip(whole, chunked, strict=True)) and np.array_equal(rng, whole_rng)


@pytest.mark.parametrize("engine", ["lattice", "python"])
def test_the_progress_bar_counts_iterations_within_each_decision(engine, monkeypatch):
    """The bar moves during a decision, not only between decisions: its updates add up to iterations x decisions,
    with more updates than decisions."""
    import pyroute_rel._kernels.mcts as kernel
    import pyroute_rel.planners.mcts as planner

    updates: list[int] = []

    class Bar:
        def update(self, n: int = 1) -> None:
            updates.append(n)

        def close(self) -> None:
            pass

    monkeypatch.setattr(planner, "progress_bar", lambda *a, **k: Bar())
    monkeypatch.setattr(kernel, "CHUNK", 25)
    monkeypatch.setattr(planner, "PROGRESS_EVERY", 25)
    track = plan(small(engine=engine), progress=True)
    decisions = track.stats["decisions"]
    assert decisions >= 1 and sum(updates) == FAST["iterations"] * decisions
    assert len([n for n in updates if n]) == 3 * decisions  # 60 iterations: 25 + 25 + 10 each decision


def test_a_search_tree_beyond_the_memory_budget_is_refused_before_any_work(monkeypatch):
    """10^7 iterations a decision need about 1.7 GB of tree: refused in one line within the budget, before the
    lattice is built."""
    from pyroute_rel.errors import MemoryBudgetError
    from pyroute_rel.planners.mcts import tree_estimate
    from pyroute_rel.resources import resident_bytes

    need = tree_estimate(10_000_000, 16).parts["search tree"]
    assert 1.5e9 < need < 2e9  # 20 int64/float64 values a node, 10^7 + 2 nodes (and the path)
    # 1 GiB beyond what the process holds (a route of the small grid fits; the tree does not)
    monkeypatch.setenv("PYROUTE_REL_MAX_MEMORY", str(resident_bytes() + 1024**3))
    with pytest.raises(
        MemoryBudgetError, match=r"this MCTS search needs about .* \(10000000 iterations, 16 headings\)"
    ):
        plan(small(iterations=10_000_000, headings=16))
