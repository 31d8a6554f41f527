"""Other planners on the DP's problem (issue 22): MCTS-UCT, tabular Q-learning and a DQN, against the exact DP.

References: the DP (exact on its graph, itself tested against networkx and brute force in test_solve.py), networkx's
Dijkstra on the grid of cells, scikit-learn's ``MLPRegressor.predict`` for the saved network's forward pass, the
evaluator's re-timing (:func:`pyroute_rel.analysis.evaluate.evaluate_track`), GSHHG land (``points_on_land``) and
shapely for the zones on densified tracks, and closed forms for the track similarity.
"""

from __future__ import annotations

import csv
import json
from dataclasses import replace

import networkx as nx
import numpy as np
import pytest
import shapely

from pyroute_rel import scenario_from_mapping
from pyroute_rel.analysis.similarity import track_similarity
from pyroute_rel.cli.planners import PLANNER_FILES
from pyroute_rel.errors import ScenarioError
from pyroute_rel.geodesy import gc_densify
from pyroute_rel.obstacles.land import points_on_land
from pyroute_rel.planners.base import PlannedTrack, Planner, PlanningProblem
from pyroute_rel.planners.mcts import MCTSPlanner
from pyroute_rel.planners.plan import get_planner, plan
from pyroute_rel.planners.qlearning import QLearningPlanner, cell_states, graph_states, shortest_time
from pyroute_rel.planners.settings import (
    PLANNERS,
    DQNSettings,
    MCTSSettings,
    QLearningSettings,
    episodes_for,
    parse_planner,
)

sklearn = pytest.importorskip("sklearn")
evaluate = pytest.importorskip("pyroute_rel.analysis.evaluate")

#: A short course in the control weather with a patch of 4.5 m waves across the great circle: at apf 0.5 the
#: failure model forbids it and the best route goes round.
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


def small(**planner: object) -> object:
    return scenario_from_mapping({**SMALL, "planner": planner})


def test_published_defaults_and_refusals():
    s = parse_planner({})
    assert s.kind == "dp" and s.seed == 0
    m = s.mcts  # Barde (2023)
    assert (m.iterations, m.headings, m.step_h, m.nogo_min_deg, m.nogo_max_deg, m.reward_c) == (
        15_000,
        8,
        1.0,
        35.0,
        160.0,
        1.001,
    )
    assert m.exploration == pytest.approx(1.0 / np.sqrt(2.0), rel=1e-15)
    q = s.qlearning  # Jing et al. (2021)
    assert (q.alpha, q.gamma, q.epsilon, q.cell_nm, q.cells_across) == (0.6, 0.9, 0.2, 10.0, 10)
    assert q.episodes == 0 and episodes_for(q, 100) == 3000  # sized from the graph, at least the published 3000
    assert s.dqn.turn_deg == 22.5 and s.dqn.nogo_min_deg == 45.0  # Mannocci & Bologna: pi/8, 45 deg
    for raw, words in (
        ({"kind": "astar"}, "[planner].kind must be one of"),
        ({"mcts": {"iteration": 5}}, "[planner.mcts]: unknown key 'iteration'"),
        ({"qlearning": {"alpha": 0.0}}, "[planner.qlearning].alpha must be a number in (0, 1]"),
        ({"qlearning": {"space": "hex"}}, "[planner.qlearning].space must be one of"),
        ({"dqn": {"hidden": []}}, "[planner.dqn].hidden must be a list"),
        ({"mcts": {"nogo_min_deg": 170.0}}, "nogo_min_deg must be below nogo_max_deg"),
        ({"extra": 1}, "[planner]: unknown key 'extra'"),
    ):
        with pytest.raises(ScenarioError, match=None) as info:
            parse_planner(raw)
        assert words in str(info.value)
    with pytest.raises(ScenarioError, match=r"\[planner\]"):
        scenario_from_mapping({**SMALL, "planner": {"kind": 5}})


def dp_nodes(sc: object) -> list[int]:
    return sc.route().nodes.tolist()  # type: ignore[attr-defined]


def test_qlearning_on_the_graph_finds_the_dp_route():
    """With gamma = 1 and enough episodes, the greedy route of tabular Q-learning on the rank digraph is the DP's
    (which goes round the patch); the history says after how many episodes it first was."""
    sc = small(kind="qlearning", qlearning={"gamma": 1.0, "episodes": 1500})
    ref = sc.route()
    assert ref.nodes.tolist() != [3] * 5  # the DP goes round the patch: the test is not the straight line
    track = QLearningPlanner().plan(PlanningProblem.of(sc), checkpoints=15)
    assert track.reached and track.stats["nodes"] == ref.nodes.tolist()
    assert track.voyage_time_h == pytest.approx(ref.voyage_time_h, rel=1e-12)
    hist = track.stats["history"]
    first = next(e for e, h in hist if h == pytest.approx(ref.voyage_time_h, rel=1e-12))
    assert 1 <= first <= 1500


@pytest.mark.slow
def test_qlearning_on_cells_finds_dijkstras_route():
    """Jing et al.'s grid of cells: Q-learning (gamma = 1) finds the route networkx's Dijkstra finds on the same
    weighted graph (edge time 2 d / (v_i + v_j))."""
    sc = small(
        kind="qlearning",
        qlearning={"space": "cells", "gamma": 1.0, "episodes": 2000, "cell_nm": 20.0, "cells_across": 5},
    )
    problem = PlanningProblem.of(sc)
    tab = cell_states(problem)
    g = nx.DiGraph()
    for s in range(tab.n_states):
        for a in range(tab.ptr[s], tab.ptr[s + 1]):
            if np.isfinite(tab.static_cost[a]):
                g.add_edge(s, int(tab.target[a]), weight=float(tab.static_cost[a]))
    ref = nx.dijkstra_path(g, tab.start, tab.goal)
    ref_h = nx.dijkstra_path_length(g, tab.start, tab.goal)
    assert shortest_time(tab) == pytest.approx(ref_h, rel=1e-12)
    track = QLearningPlanner().plan(problem)
    assert track.reached and track.stats["model_voyage_time_h"] == pytest.approx(ref_h, rel=1e-12)
    assert np.allclose(track.lon_deg, tab.lon_deg[ref]) and np.allclose(track.lat_deg, tab.lat_deg[ref])


def test_mcts_with_full_search_finds_the_dp_route():
    """On a tiny graph with more iterations per decision than the tree has nodes, MCTS-UCT on the DP's graph picks
    the DP's route."""
    sc = scenario_from_mapping(
        {
            **SMALL,
            "grid": {"layout": "square", "n_ranks": 3, "n_nodes": 5, "samples_per_arc": 4},
            "weather": {**SMALL["weather"], "patch": [{"lon": [-13.3, -12.7], "lat": [43.8, 44.2], "hs_m": 4.5}]},
            "planner": {"kind": "mcts", "mcts": {"graph": True, "iterations": 400, "final": "best"}},
        }
    )
    ref = sc.route()
    track = plan(sc)
    assert track.reached and track.stats["nodes"] == ref.nodes.tolist()
    assert track.voyage_time_h == pytest.approx(ref.voyage_time_h, rel=1e-12)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_no_planner_beats_the_dp_on_its_graph(seed):
    sc = small(seed=seed, qlearning={"episodes": 60}, mcts={"graph": True, "iterations": 20})
    best = sc.route().voyage_time_h
    for kind in ("qlearning", "mcts"):
        track = plan(sc, kind=kind)
        if track.reached:
            assert track.voyage_time_h >= best - 1e-9


TINY_LEARNERS = {
    "mcts": {"iterations": 8, "step_h": 6.0, "rollout_h": 12.0},
    "qlearning": {"episodes": 200, "gamma": 1.0},
    "dqn": {"episodes": 3, "step_h": 6.0, "hidden": [8], "batch": 8, "image_cells": 3, "target_every": 5},
}


SLOW_MCTS = [pytest.param(k, marks=pytest.mark.slow) if k == "mcts" else k for k in PLANNERS]


@pytest.mark.parametrize("kind", SLOW_MCTS)
def test_reported_voyage_is_the_evaluators_retiming(kind):
    """Every planner's own times are the evaluator's re-timing of its track, to rounding."""
    sc = small(**TINY_LEARNERS)
    track = plan(sc, kind=kind)
    assert isinstance(get_planner(kind), Planner) and isinstance(track, PlannedTrack)
    ev = evaluate.evaluate_track(sc, track.points())
    assert np.allclose(ev.elapsed_h, track.elapsed_h, rtol=1e-12, atol=1e-9)
    assert ev.feasible


@pytest.mark.parametrize("kind", [k for k in SLOW_MCTS if k != "dp"])
def test_fixed_seeds_reproduce(kind):
    sc = small(**TINY_LEARNERS)
    a, b = plan(sc, kind=kind), plan(sc, kind=kind)
    assert np.array_equal(a.lon_deg, b.lon_deg) and np.array_equal(a.elapsed_h, b.elapsed_h)


#: A course from west of Guadeloupe to its east, through a zone, with a coastal margin and a failure patch.
ISLAND = {
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
    "avoid": {"land": True, "margin_km": 5.0},
}


@pytest.mark.slow
@pytest.mark.parametrize("kind", PLANNERS)
def test_planners_respect_land_zones_and_apf(kind, tmp_path):
    zone = {
        "type": "Feature",
        "properties": {"name": "box"},
        "geometry": {
            "type": "Polygon",
            "coordinates": [[[-62.2, 15.8], [-62.0, 15.8], [-62.0, 16.1], [-62.2, 16.1], [-62.2, 15.8]]],
        },
    }
    (tmp_path / "z.geojson").write_text(json.dumps({"type": "FeatureCollection", "features": [zone]}))
    table = {**ISLAND, "avoid": {**ISLAND["avoid"], "zones": ["z.geojson"]}, "planner": TINY_LEARNERS}
    sc = scenario_from_mapping(table, base_dir=tmp_path)
    track = plan(sc, kind=kind)
    x, y, _ = gc_densify(track.lon_deg[:-1], track.lat_deg[:-1], track.lon_deg[1:], track.lat_deg[1:], max_step_km=1.0)
    assert not points_on_land(x, y, margin_km=4.9).any()
    assert not shapely.contains_xy(shapely.box(-62.2, 15.8, -62.0, 16.1), x, y).any()
    ev = evaluate.evaluate_track(sc, track.points())
    assert ev.max_failure_probability <= 0.5 and ev.feasible


def test_dqn_saves_and_reads_its_network(tmp_path):
    from pyroute_rel.planners.dqn import QNetwork, _new_learner

    sc = scenario_from_mapping(
        {**SMALL, "planner": {"dqn": {**TINY_LEARNERS["dqn"], "model": "q.npz"}}}, base_dir=tmp_path
    )
    first = plan(sc, kind="dqn")
    assert (tmp_path / "q.npz").is_file() and not first.stats["loaded"]
    again = plan(sc, kind="dqn")
    assert again.stats["loaded"] and np.array_equal(again.lon_deg, first.lon_deg)
    other = replace(sc, planner=replace(sc.planner, dqn=replace(sc.planner.dqn, hidden=(4,))))
    assert not plan(other, kind="dqn").stats["loaded"]  # other settings: trained afresh
    # the numpy forward pass of the saved weights is scikit-learn's predict
    s = DQNSettings(hidden=(7, 5))
    learner = _new_learner(s, 6, np.random.default_rng(0), 0)
    x = np.random.default_rng(1).normal(size=(10, 6))
    learner.mlp.partial_fit(x, np.random.default_rng(2).normal(size=(10, 3)))
    assert np.allclose(QNetwork.of(learner.mlp)(x), learner.mlp.predict(x), rtol=1e-12, atol=1e-12)


def test_dqn_model_file_stays_in_the_scenario_folder_and_is_never_another_file(tmp_path):
    """Issue 34: ``model = "../../elsewhere/x.npz"`` wrote outside the scenario folder, and an unrelated ``.npz`` of
    the user's was replaced. A name leaving the folder is refused; a file that is not a model this planner saved
    (another program's arrays, text, pickled objects) is refused and left as it was."""
    from pyroute_rel.errors import ScenarioError

    folder = tmp_path / "scenario"
    folder.mkdir()

    def planned(model: str):
        sc = scenario_from_mapping(
            {**SMALL, "planner": {"dqn": {**TINY_LEARNERS["dqn"], "model": model}}}, base_dir=folder
        )
        return plan(sc, kind="dqn")

    for name in ("../x.npz", "../../elsewhere/x.npz", str(tmp_path / "abs.npz"), "."):
        with pytest.raises(
            ScenarioError, match=r"\[planner\.dqn\]\.model must name a file inside the scenario's folder"
        ):
            planned(name)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scenario"]
    np.savez(folder / "theirs.npz", data=np.arange(5))
    (folder / "text.npz").write_text("not a model")
    np.savez(folder / "pickled.npz", settings=np.array([{"a": 1}], dtype=object))
    np.save(folder / "one.npy", np.arange(3))
    (folder / "one.npy").rename(folder / "one.npz")  # one array, not an archive
    for name in ("theirs.npz", "text.npz", "pickled.npz", "one.npz"):
        before = (folder / name).read_bytes()
        with pytest.raises(ScenarioError, match=r"is not a DQN model this planner saved .*it is never replaced"):
            planned(name)
        assert (folder / name).read_bytes() == before


def test_track_similarity_closed_forms():
    # a track one degree north of the equator's 0-10 E leg (parallel, so every point is 60.04 nm off)
    lon = np.linspace(0.0, 10.0, 11)
    s = track_similarity([0.0, 10.0], [0.0, 0.0], lon, np.ones(11), step_km=1.0)
    arc_nm = np.radians(1.0) * 6371.0088 / 1.852
    assert s.max_cross_track_nm == pytest.approx(arc_nm, rel=1e-3)  # the parallel bows off the great circle
    assert s.mean_cross_track_nm == pytest.approx(arc_nm, rel=2e-3)
    same = track_similarity(lon, np.zeros(11), [0.0, 10.0], [0.0, 0.0])
    assert same.max_cross_track_nm < 1e-6 and same.hausdorff_nm < 1e-6
    t0 = np.datetime64("2018-06-01T00:00:00")
    d = track_similarity([0, 1], [0, 0], [0, 1], [0, 0], arrival_a=t0, arrival_b=t0 + np.timedelta64(90, "m"))
    assert d.arrival_difference_h == 1.5


@pytest.mark.slow
def test_planner_and_compare_commands(tmp_path, capsys):
    from pyroute_rel.cli import main

    lines = [
        "[route]",
        "start = [-12.0, 45.0]",
        "finish = [-14.0, 43.0]",
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
        "[planner]",
        'kind = "qlearning"',
        "[planner.qlearning]",
        "episodes = 100",
    ]
    path = tmp_path / "s.toml"
    path.write_text("\n".join(lines) + "\n")
    assert main(["route", str(path), "--json", "--quiet", "--out", str(tmp_path / "q")]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["planner"] == "qlearning" and out["reached"] and out["feasible"]
    assert out["voyage_time_h"] == pytest.approx(out["planner_voyage_time_h"], rel=1e-12)
    assert sorted(p.name for p in (tmp_path / "q").iterdir()) == sorted(PLANNER_FILES)
    assert main(["route", str(path), "--planner", "dp", "--json", "--quiet", "--out", str(tmp_path / "dp")]) == 0
    dp = json.loads(capsys.readouterr().out)
    assert "planner" not in dp
    code = main(["compare", str(tmp_path / "dp" / "route.csv"), str(tmp_path / "q" / "route.csv"), "--json"])
    assert code == 0
    cmp = json.loads(capsys.readouterr().out)
    assert cmp["max_cross_track_nm"] >= cmp["mean_cross_track_nm"] >= 0.0
    assert main(["compare", str(tmp_path / "nope.csv"), str(tmp_path / "q" / "route.csv")]) == 2
    assert "error" in capsys.readouterr().err


@pytest.mark.parametrize("kind", ["qlearning", pytest.param("dqn", marks=pytest.mark.slow)])
def test_planner_outputs_are_the_evaluators_track(kind, tmp_path, capsys):
    """``route --planner X --out DIR`` writes what a DP route writes, from the evaluator's re-timing of the track:
    the GPX reads back as the track and its times, the CSV's times are the evaluator's."""
    from pyroute_rel.analysis.evaluate import read_track
    from pyroute_rel.cli import main
    from pyroute_rel.times import iso_utc

    table = {**SMALL, "planner": {**TINY_LEARNERS, "kind": kind}}
    (tmp_path / "s.toml").write_text(_toml(table))
    sc = scenario_from_mapping(table)
    planned = plan(sc)
    ev = evaluate.evaluate_track(sc, planned.points())  # the same seed: the same track
    arrives = planned.reached and ev.feasible  # else the files are written and the exit code says it did not
    assert main(["route", str(tmp_path / "s.toml"), "--quiet", "--out", str(tmp_path / "o")]) == (0 if arrives else 2)
    assert "route.gpx" in capsys.readouterr().out
    assert sorted(p.name for p in (tmp_path / "o").iterdir()) == sorted(PLANNER_FILES)
    gpx = read_track(tmp_path / "o" / "route.gpx")
    assert np.allclose(gpx.lon_deg, ev.track[:, 0], atol=1e-6) and np.allclose(gpx.lat_deg, ev.track[:, 1], atol=1e-6)
    assert [iso_utc(t) for t in gpx.time] == [iso_utc(t) for t in ev.time]
    with open(tmp_path / "o" / "route.csv", encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["time_utc"] for r in rows] == [iso_utc(t) for t in ev.time]
    assert np.allclose([float(r["elapsed_h"]) for r in rows], ev.elapsed_h, rtol=0, atol=1e-6)
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert summary["planner"] == kind and summary["voyage_time_h"] == pytest.approx(ev.voyage_time_h, rel=1e-12)
    geo = json.loads((tmp_path / "o" / "route.geojson").read_text())
    assert len(geo["features"]) >= 1


@pytest.mark.slow
def test_planner_out_into_a_dp_routes_folder_leaves_no_dp_file(tmp_path, capsys):
    """A planner's files written over a DP route's: the DP's forbidden.geojson (arcs the DP found forbidden, which
    says nothing of the planner's track) is removed, not left beside the planner's route."""
    from pyroute_rel.cli import main
    from pyroute_rel.outputs import OUTPUT_FILES

    table = {**SMALL, "planner": {**TINY_LEARNERS, "kind": "qlearning"}}
    (tmp_path / "s.toml").write_text(_toml(table))
    out = tmp_path / "o"
    assert main(["route", str(tmp_path / "s.toml"), "--planner", "dp", "--quiet", "--out", str(out)]) == 0
    assert sorted(p.name for p in out.iterdir()) == sorted(OUTPUT_FILES)
    assert main(["route", str(tmp_path / "s.toml"), "--quiet", "--out", str(out)]) == 0
    capsys.readouterr()
    assert sorted(p.name for p in out.iterdir()) == sorted(PLANNER_FILES)
    assert json.loads((out / "summary.json").read_text())["planner"] == "qlearning"


@pytest.mark.slow
def test_planner_summary_is_strict_json(tmp_path, capsys):
    """A learner that does not reach the finish has model_voyage_time_h inf: printed and written as null."""
    from pathlib import Path

    from pyroute_rel.cli import main

    def refuse(constant):
        raise AssertionError(f"not JSON: {constant}")

    control = Path(__file__).resolve().parents[1] / "examples" / "microtransat_control.toml"
    text = control.read_text() + '\n[planner]\nkind = "qlearning"\n[planner.qlearning]\nepisodes = 1\n'
    (tmp_path / "s.toml").write_text(text)
    args = ["route", str(tmp_path / "s.toml"), "--n-ranks", "12", "--quiet", "--json", "--out", str(tmp_path / "o")]
    assert main(args) == 2  # did not reach the finish: the no-route code, after the JSON and the files
    printed = json.loads(capsys.readouterr().out, parse_constant=refuse)
    assert json.loads((tmp_path / "o" / "summary.json").read_text(), parse_constant=refuse)["planner"] == "qlearning"
    stats = printed["planner_stats"]
    assert not printed["reached"] and stats["model_voyage_time_h"] is None


def _toml(table: dict) -> str:
    """A scenario table as TOML (the few value types SMALL and TINY_LEARNERS use)."""

    def value(v: object) -> str:
        return json.dumps(v) if not isinstance(v, bool) else str(v).lower()

    lines: list[str] = []

    def put(name: str, t: dict) -> None:
        plain = {
            k: v
            for k, v in t.items()
            if not isinstance(v, dict) and not (isinstance(v, list) and v and isinstance(v[0], dict))
        }
        lines.append(f"[{name}]")
        lines.extend(f"{k} = {value(v)}" for k, v in plain.items())
        for k, v in t.items():
            if isinstance(v, dict):
                put(f"{name}.{k}", v)
            elif isinstance(v, list) and v and isinstance(v[0], dict):
                for item in v:
                    lines.append(f"[[{name}.{k}]]")
                    lines.extend(f"{kk} = {value(vv)}" for kk, vv in item.items())

    for name, t in table.items():
        put(name, t)
    return "\n".join(lines) + "\n"


def test_planning_problem_refuses_what_only_the_dp_routes():
    sc = scenario_from_mapping({**SMALL, "route": {**SMALL["route"], "waypoints": [[-13.0, 44.0]]}})
    for kind in ("mcts", "qlearning", "dqn"):
        with pytest.raises(ScenarioError, match="routes from \\[route\\].start to \\[route\\].finish only"):
            plan(sc, kind=kind)


def test_graph_states_are_the_dp_graph():
    """The tabular problem on the graph has one action per arc of the grid, costed as the DP costs it."""
    sc = small()
    problem = PlanningProblem.of(sc)
    tab = graph_states(problem)
    assert tab.target.size == problem.grid.n_arcs
    g = problem.grid.to_networkx()
    assert tab.n_states == g.number_of_nodes()
    assert QLearningSettings().space == "graph" and MCTSSettings().final == "visits"
    # scipy's Dijkstra on the table's costs is the DP's voyage (the DP is exact on its graph)
    assert shortest_time(tab) == pytest.approx(sc.route().voyage_time_h, rel=1e-12)
    _ = MCTSPlanner


def _veering_problem(**qlearning: object) -> PlanningProblem:
    """SMALL's course in a wind that veers from north to east over two days and freshens (gridded, time-varying)."""
    from pyroute_rel.weather import GriddedWeather, WeatherField

    t0 = np.datetime64("2018-06-01T00:00", "ns")
    times = t0 + np.arange(9) * np.timedelta64(6, "h")
    lon, lat = np.arange(-16.0, -9.9, 1.0), np.arange(41.0, 47.1, 1.0)
    frac = np.linspace(0.0, 1.0, times.size)[:, None, None] * np.ones((1, lat.size, lon.size))
    speed = 5.0 + 5.0 * frac  # [m/s]
    from_deg = 90.0 * frac  # north, then east
    u = -speed * np.sin(np.radians(from_deg))
    v = -speed * np.cos(np.radians(from_deg))
    w = GriddedWeather(
        [
            WeatherField(n, x.astype(np.float32), lon, lat, times, source="test", variable=n)
            for n, x in (("wind_u_ms", u), ("wind_v_ms", v))
        ]
    )
    sc = scenario_from_mapping({**SMALL, "failure": {}, "weather": {"kind": "uniform", "tws_kn": 10.0, "twd_deg": 0.0}})
    base = PlanningProblem.of(sc)
    settings = replace(base.settings, qlearning=QLearningSettings(gamma=1.0, **qlearning))  # type: ignore[arg-type]
    return PlanningProblem(sc, base.grid, replace(base.problem, weather=w), settings)


def test_qlearning_in_time_varying_weather_sails_its_route_exactly():
    """Costing passes: the track's times are its exact sailing (the DP's arc costs leg after leg), its voyage the
    fastest pass's, and no faster than the DP on the same graph (exact there)."""
    from pyroute_rel.routing.route import route_on_grid

    problem = _veering_problem(episodes=400, time_passes=2)
    assert not problem.problem.weather.steady
    track = QLearningPlanner().plan(problem)
    exact, ok = problem.retime(track.lon_deg, track.lat_deg)
    assert ok and track.reached and np.allclose(track.elapsed_h, exact, rtol=1e-12)
    assert track.stats["time_costing"] == "passes" and len(track.stats["pass_voyage_times_h"]) == 2
    assert track.voyage_time_h == pytest.approx(min(track.stats["pass_voyage_times_h"]), rel=1e-12)
    dp = route_on_grid(problem.grid, problem.problem)
    assert track.voyage_time_h >= dp.voyage_time_h - 1e-9


def test_cost_lattice_buckets_cost_at_the_bucket_middle():
    """``time_costing = "buckets"``: a state's times at t are its actions costed at the middle of t's bucket, those
    after the horizon are forbidden."""
    from pyroute_rel.planners.qlearning import CostLattice

    problem = _veering_problem(time_costing="buckets", time_bucket_h=4.0)
    tab = graph_states(problem)
    lat = CostLattice(tab, 4.0, 40.0)
    for s, t in ((0, 0.3), (9, 13.9), (9, 12.0), (20, 33.0)):
        acts = np.arange(tab.ptr[s], tab.ptr[s + 1])
        expect = problem.problem.costs(*_arc_ends(problem, tab, acts), (t // 4.0 + 0.5) * 4.0).time_h
        assert np.array_equal(lat.times(s, t), expect)
    assert np.isinf(lat.times(9, 41.0)).all()
    assert lat.fills == 3  # (the start, bucket 0), (the nodes of rank 1, bucket 3), (those of rank 2, bucket 8)


def _arc_ends(problem: PlanningProblem, tab: object, acts: np.ndarray) -> tuple[np.ndarray, ...]:
    """The end points of the tabular problem's actions (the start, the nodes and the finish)."""
    src = np.repeat(np.arange(tab.n_states), np.diff(tab.ptr))[acts]  # type: ignore[attr-defined]
    dst = tab.target[acts]  # type: ignore[attr-defined]
    return tab.lon_deg[src], tab.lat_deg[src], tab.lon_deg[dst], tab.lat_deg[dst]  # type: ignore[attr-defined]


@pytest.mark.slow
def test_qlearnings_default_reaches_the_finish_on_the_control_course():
    """The published 3000 episodes leave the greedy route 413 nm short on the control course's default graph; the
    default (two episodes per state) reaches the finish, and no faster than the DP (exact on the same graph)."""
    from pathlib import Path

    from pyroute_rel.scenario import load_scenario

    sc = load_scenario(Path(__file__).resolve().parents[1] / "examples" / "microtransat_control.toml")
    track = plan(sc, kind="qlearning")
    assert track.reached and track.stats["episodes"] == 2 * track.stats["states"]
    assert track.voyage_time_h >= sc.route().voyage_time_h - 1e-9  # the DP is exact on the same graph
