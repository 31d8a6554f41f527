"""Tacks and gybes as state of the exact DP (issue 21): brute force, networkx on the enlarged graph, zero penalties
equal the plain DP, bounds against the plain route re-timed, counts recomputed from the track's wind angles."""

from __future__ import annotations

import csv
import io
import itertools
import json
from dataclasses import replace
from pathlib import Path

import networkx as nx
import numpy as np
import pytest

from pyroute_rel.boat.manoeuvre import GYBE, PORT, STARBOARD, TACK, ManoeuvrePenalties, track_manoeuvres
from pyroute_rel.errors import ScenarioError
from pyroute_rel.routing.cost import arc_costs, arc_geometry
from pyroute_rel.routing.grid import make_grid
from pyroute_rel.routing.route import route_on_grid
from pyroute_rel.routing.solve import RoutingProblem, forward_dp, leg_manoeuvres
from pyroute_rel.scenario import load_scenario, scenario_from_mapping
from pyroute_rel.viz.maps import plot_route
from tests.test_cli import run
from tests.test_solve import DEP, FINISH_PT, START_PT, random_polar, random_weather

#: Tagliaferri (2015): a tack costs about 30 s at 5 m/s (9.72 kn) of wind and 20 s at 10 m/s (19.44 kn).
TAGLIAFERRI = [[9.72, 30.0], [19.44, 20.0]]


def big_penalties(rng: np.random.Generator) -> ManoeuvrePenalties:
    """Penalties of hours, so that they change the route on coarse test grids."""
    return ManoeuvrePenalties(
        tack_s=[[0.0, float(rng.uniform(0, 4e4))], [25.0, float(rng.uniform(0, 4e4))]],
        gybe_s=[[5.0, float(rng.uniform(0, 4e4))], [20.0, float(rng.uniform(0, 4e4))]],
    )


def instance(seed: int, n_ranks: int, n_nodes: int, **kw: object) -> tuple[object, RoutingProblem]:
    rng = np.random.default_rng(seed)
    grid = make_grid(START_PT, FINISH_PT, n_ranks=n_ranks, n_nodes=n_nodes, spacing_km=float(rng.uniform(60, 200)))
    problem = RoutingProblem(
        departure=DEP,
        weather=random_weather(rng),
        polar=random_polar(rng),
        samples=int(rng.integers(1, 3)),
        manoeuvres=big_penalties(rng),
        **kw,  # type: ignore[arg-type]
    )
    return grid, problem


def track_points(grid, start: int, nodes: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
    s_lon, s_lat = grid.start_points
    ranks = np.arange(len(nodes))
    lon = np.concatenate([[s_lon[start]], grid.lon_deg[ranks, list(nodes)], [grid.finish[0]]])
    lat = np.concatenate([[s_lat[start]], grid.lat_deg[ranks, list(nodes)], [grid.finish[1]]])
    return lon, lat


def independent_sides(problem: RoutingProblem, lon, lat, t0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Side (by the sine of the wind's bearing off the course), |TWA| and TWS of each leg at its first sample."""
    return arc_sides(problem, lon[:-1], lat[:-1], lon[1:], lat[1:])


def arc_sides(problem: RoutingProblem, lon0, lat0, lon1, lat1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    g = arc_geometry(lon0, lat0, lon1, lat1, samples=problem.samples)
    cond = problem.weather.sample(g.lon_deg[..., 0], g.lat_deg[..., 0], DEP)
    rel = np.radians(cond.twd_deg - g.course_deg[..., 0])
    side = np.where(np.sin(rel) > 0, STARBOARD, PORT)
    twa = np.degrees(np.arccos(np.clip(np.cos(rel), -1, 1)))
    return side, twa, cond.tws_kn


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(5))
def test_dp_equals_brute_force_with_penalties(seed: int) -> None:
    """Every path of a small grid timed leg after leg with the penalties of its own changes of side: the DP's voyage
    is the smallest, and its track is one of the fastest."""
    grid, problem = instance(seed, 3, 4)
    res = forward_dp(grid, problem)
    best, best_paths = np.inf, []
    for nodes in itertools.product(range(grid.n_nodes), repeat=grid.n_ranks):
        lon, lat = track_points(grid, 0, nodes)
        c = arc_costs(lon[:-1], lat[:-1], lon[1:], lat[1:], 0.0, departure=DEP, weather=problem.weather,
                      polar=problem.polar, samples=problem.samples)  # fmt: skip
        side, twa, tws = independent_sides(problem, lon, lat, 0.0)
        kind = np.where(side[1:] != side[:-1], np.where(twa[1:] < 90.0, TACK, GYBE), 0)
        pen = problem.manoeuvres.penalty_h(kind, tws[1:])
        t = float(np.sum(c.time_h) + np.sum(pen))
        if t < best * (1 - 1e-12):
            best, best_paths = t, [nodes]
        elif t <= best * (1 + 1e-12):
            best_paths.append(nodes)
    assert res.finish_h == pytest.approx(best, rel=1e-12)
    if np.isfinite(best):
        assert tuple(res.path()) in best_paths
        route = route_on_grid(grid, problem)
        assert route.voyage_time_h == pytest.approx(best, rel=1e-12)


def enlarged_graph(grid, problem: RoutingProblem) -> nx.DiGraph:
    """(node, side) labels as graph nodes; an arc from a label costs its time plus the penalty of a change of side."""
    g = nx.DiGraph()
    for k in range(grid.n_ranks + 1):
        lon0, lat0, lon1, lat1, src, valid = grid.arcs(k)
        shape = src.shape
        a = [np.broadcast_to(x, shape).ravel() for x in (lon0, lat0, lon1, lat1)]
        c = arc_costs(*a, 0.0, departure=DEP, weather=problem.weather, polar=problem.polar, samples=problem.samples)
        side, twa, tws = arc_sides(problem, *a)
        change = problem.manoeuvres.penalty_h(np.where(twa < 90.0, TACK, GYBE), tws)
        dst = np.broadcast_to(np.arange(shape[0])[:, None], shape).ravel()
        for n, (i, j) in enumerate(zip(src.ravel(), dst, strict=True)):
            if not valid.ravel()[n] or not np.isfinite(c.time_h[n]):
                continue
            head = ("finish",) if k == grid.n_ranks else (k, int(j), int(side[n]))
            if k == 0:
                g.add_edge(("start",), head, weight=float(c.time_h[n]))
                continue
            for s in (PORT, STARBOARD):
                w = float(c.time_h[n]) + (float(change[n]) if s != side[n] else 0.0)
                g.add_edge((k - 1, int(i), s), head, weight=w)
    return g


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("shape", [(5, 5), (7, 9)])
def test_dp_equals_networkx_on_the_enlarged_graph(seed: int, shape: tuple[int, int]) -> None:
    grid, problem = instance(seed, *shape)
    res = forward_dp(grid, problem)
    try:
        ref = nx.shortest_path_length(enlarged_graph(grid, problem), ("start",), ("finish",), weight="weight")
    except nx.NetworkXNoPath:
        ref = np.inf
    assert res.finish_h == pytest.approx(ref, rel=1e-12)


@pytest.mark.parametrize("seed", range(6))
def test_zero_penalties_equal_the_plain_dp(seed: int, monkeypatch: pytest.MonkeyPatch) -> None:
    """The (node, side) DP with zero penalties (forced on) finds today's voyage time and track exactly."""
    grid, problem = instance(seed, 6, 7)
    plain = forward_dp(grid, replace(problem, manoeuvres=None))
    monkeypatch.setattr(ManoeuvrePenalties, "active", property(lambda self: True))
    zero = replace(problem, manoeuvres=ManoeuvrePenalties())
    assert zero.sides
    labelled = forward_dp(grid, zero)
    assert labelled.labels is not None
    assert labelled.finish_h == plain.finish_h
    np.testing.assert_array_equal(labelled.arrival_h, plain.arrival_h)
    if np.isfinite(plain.finish_h):
        np.testing.assert_array_equal(labelled.path(), plain.path())


@pytest.mark.parametrize("seed", range(6))
def test_penalties_bounded_by_free_and_by_the_free_route_retimed(seed: int) -> None:
    grid, problem = instance(seed, 8, 9)
    free = forward_dp(grid, replace(problem, manoeuvres=None))
    if not np.isfinite(free.finish_h):
        pytest.skip("no route on this instance")
    res = forward_dp(grid, problem)
    lon, lat = free.points(grid)
    retimed, _, man = leg_manoeuvres(problem, lon, lat)
    assert free.finish_h <= res.finish_h <= retimed[-1] * (1 + 1e-12)
    assert retimed[-1] == pytest.approx(free.finish_h + man.penalty_h.sum(), rel=1e-12)


@pytest.mark.parametrize("seed", range(4))
def test_counts_recompute_from_the_tracks_wind_angles(seed: int) -> None:
    grid, problem = instance(seed, 8, 9)
    route = route_on_grid(grid, problem)
    side, twa, tws = independent_sides(problem, route.lon_deg, route.lat_deg, 0.0)
    change = side[1:] != side[:-1]
    assert route.manoeuvres is not None
    np.testing.assert_array_equal(route.manoeuvres.side, side)
    np.testing.assert_array_equal(route.dp.path_sides(), side)  # the DP's labels are the track's sides
    assert route.manoeuvres.tacks == int(np.sum(change & (twa[1:] < 90.0)))
    assert route.manoeuvres.gybes == int(np.sum(change & (twa[1:] >= 90.0)))
    assert route.voyage_time_h == pytest.approx(route.dp.finish_h, rel=1e-12)
    assert route.summary()["manoeuvres"]["penalty_h"] == pytest.approx(route.manoeuvres.penalty_h.sum())


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(3))
def test_time_expanded_dp_with_waiting_equals_brute_force(seed: int) -> None:
    """On the time lattice (arrivals rounded up), waiting allowed: in steady weather a wait never helps, so the DP
    equals the best path timed leg after leg on the lattice."""
    grid, problem = instance(seed, 3, 4, time_step_h=0.5, max_wait_h=1.0)
    res = forward_dp(grid, problem)
    best = min(
        leg_manoeuvres(problem, *track_points(grid, 0, nodes))[0][-1]
        for nodes in itertools.product(range(grid.n_nodes), repeat=grid.n_ranks)
    )
    assert res.finish_h == pytest.approx(best, rel=1e-12)
    if np.isfinite(best):
        assert route_on_grid(grid, problem).voyage_time_h == pytest.approx(best, rel=1e-12)


def beat(extra: dict[str, object]) -> object:
    return scenario_from_mapping(
        {
            "route": {"start": [-12.0, 45.0], "finish": [-16.0, 48.0], **extra},
            "grid": {"n_ranks": 12},
            "boat": {"tack_penalty_s": [[0.0, 7200.0]], "gybe_penalty_s": [[0.0, 7200.0]]},
            "weather": {"kind": "uniform", "tws_kn": 15.0, "twd_deg": 320.0},
            "avoid": {"land": False},
        }
    )


def test_waypoint_legs_carry_the_side_over() -> None:
    sc = beat({"waypoints": [[-14.0, 46.6]]})
    route = sc.route()
    first, second = route.course_legs
    assert first.problem.initial_side is None
    assert second.problem.initial_side == int(first.manoeuvres.side[-1])
    # the second leg's first manoeuvre is counted against the first leg's last side
    joined = track_manoeuvres(route.manoeuvres.side, route.legs.twa_deg, route.legs.tws_kn, None)
    assert joined.tacks + joined.gybes == route.manoeuvres.tacks + route.manoeuvres.gybes
    assert route.voyage_time_h == pytest.approx(first.voyage_time_h + second.voyage_time_h, rel=1e-12)


@pytest.mark.slow
def test_a_beat_tacks_less_with_a_penalty_and_refinement_keeps_it() -> None:
    """The control course on a beat (wind from 250 deg): free to tack, the track zig-zags between grid nodes; an hour
    per tack removes the zig-zags, costs less than the tacks it removes would, and refinement keeps the labels."""
    sc = scenario_from_mapping(
        {
            "route": {"start": [-12.0, 45.0], "finish": [-60.0, 17.5]},
            "grid": {"n_ranks": 40},
            "boat": {"tack_penalty_s": [[0.0, 3600.0]], "gybe_penalty_s": [[0.0, 3600.0]]},
            "weather": {"kind": "uniform", "tws_kn": 15.0, "twd_deg": 250.0},
            "avoid": {"land": False},
        }
    )
    free = replace(sc, manoeuvres=None).route()
    paid = sc.route()
    assert free.manoeuvres.tacks > paid.manoeuvres.tacks >= 1
    assert free.voyage_time_h < paid.voyage_time_h < free.voyage_time_h + free.manoeuvres.tacks * 1.0
    refined = replace(sc, refine=1).route()
    assert refined.voyage_time_h <= paid.voyage_time_h
    assert refined.summary()["manoeuvres"]["penalty_h"] == pytest.approx(refined.manoeuvres.tacks * 1.0)


@pytest.mark.parametrize(
    "table,match",
    [
        ("x", "list of \\[tws_kn, seconds\\] pairs"),
        ([[10.0]], "list of \\[tws_kn, seconds\\] pairs"),
        ([[10.0, -1.0]], "penalties must be in"),
        ([[10.0, 5.0], [5.0, 5.0]], "increase"),
        ([[10.0, float("nan")]], "finite numbers"),
        ([[True, 5.0]], "finite numbers"),
    ],
)
def test_bad_penalty_tables_are_one_line_errors(table: object, match: str) -> None:
    with pytest.raises(ScenarioError, match=r"\[boat\]\.tack_penalty_s.*" + match):
        scenario_from_mapping(
            {
                "route": {"start": [-12.0, 45.0], "finish": [-16.0, 48.0]},
                "boat": {"tack_penalty_s": table},
                "weather": {"kind": "uniform", "tws_kn": 15.0, "twd_deg": 320.0},
            }
        )


def test_tagliaferri_table_interpolates() -> None:
    p = ManoeuvrePenalties(tack_s=TAGLIAFERRI)
    # 30 s at 5 m/s, 20 s at 10 m/s, linear between, constant beyond
    got = p.penalty_h([TACK] * 4, [5.0, 9.72, 14.58, 40.0]) * 3600.0
    np.testing.assert_allclose(got, [30.0, 30.0, 25.0, 20.0], rtol=1e-12)
    assert not ManoeuvrePenalties().active and p.active


@pytest.mark.slow
def test_cli_summary_json_csv_and_map_report_the_manoeuvres(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The CLI's line, ``--json``'s ``manoeuvres``, the CSV columns and the map's markers all count the same
    manoeuvres, those of the route's legs; a bad table is a one-line error, exit 2."""
    scenario = tmp_path / "beat.toml"
    scenario.write_text(
        "[route]\nstart = [-12.0, 45.0]\nfinish = [-30.0, 35.0]\n[grid]\nn_ranks = 30\n[boat]\n"
        "tack_penalty_s = [[9.72, 30.0], [19.44, 20.0]]\ngybe_penalty_s = [[0.0, 40.0]]\n"
        '[weather]\nkind = "uniform"\ntws_kn = 15.0\ntwd_deg = 250.0\n[avoid]\nland = false\n',
        encoding="utf-8",
    )
    code, out, _ = run(["route", str(scenario), "--quiet", "--json", "--out", str(tmp_path / "out")], capsys)
    assert code == 0
    m = json.loads(out)["manoeuvres"]
    rows = list(csv.DictReader(io.StringIO((tmp_path / "out" / "route.csv").read_text(encoding="utf-8"))))
    kinds = [r["leg_manoeuvre"] for r in rows[:-1]]
    assert m["tacks"] == kinds.count("tack") and m["gybes"] == kinds.count("gybe") and m["tacks"] >= 1
    assert m["penalty_h"] == pytest.approx(sum(float(r["leg_manoeuvre_h"]) for r in rows[:-1]), rel=1e-5)
    assert {r["leg_side"] for r in rows[:-1]} <= {"port", "starboard"} and rows[-1]["leg_side"] == ""
    code, out, _ = run(["route", str(scenario), "--quiet"], capsys)
    assert f"manoeuvres       {m['tacks']} tacks, {m['gybes']} gybes, costing {m['penalty_h'] * 3600:.0f} s" in out
    sc = load_scenario(scenario)
    fig = plot_route(sc.route())
    marks = [ln for ln in fig.axes[0].get_lines() if str(ln.get_label()).startswith("tacks (")]
    assert len(marks) == 1 and len(marks[0].get_xdata()) == m["tacks"]
    scenario.write_text(scenario.read_text(encoding="utf-8").replace("[[0.0, 40.0]]", "[[0.0, -40.0]]"))
    code, _, err = run(["route", str(scenario), "--quiet"], capsys)
    assert code == 2 and "gybe_penalty_s" in err and len(err.strip().splitlines()) == 1
