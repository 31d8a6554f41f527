"""Track refinement in corridor grids (pyroute_rel.refine): geometry, exactness, monotonicity, an analytic optimum,
constraints kept (arc deviation, land with a margin), and the scenario/CLI surface."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import networkx as nx
import numpy as np
import pytest
import shapely
from pyproj import Geod
from test_solve import DEP, FINISH_PT, START_PT, random_polar, random_weather, weights_by_rank

from pyroute_rel import geodesy
from pyroute_rel.boat.polar import Polar
from pyroute_rel.cli import main
from pyroute_rel.errors import GridError, ScenarioError
from pyroute_rel.obstacles import land as ob
from pyroute_rel.routing.grid import FINISH, START, make_grid
from pyroute_rel.routing.refine import CORRIDOR_NODES, corridor_grid, refine, track_offsets_km
from pyroute_rel.routing.solve import RoutingProblem, forward_dp, path_costs
from pyroute_rel.scenario import load_scenario, scenario_from_mapping
from pyroute_rel.weather import Patch, UniformWeather

CONTROL = Path(__file__).resolve().parents[1] / "examples" / "microtransat_control.toml"
SPHERE = Geod(a=geodesy.EARTH_RADIUS_KM * 1000.0, b=geodesy.EARTH_RADIUS_KM * 1000.0)


def constant_polar(speed_kn: float = 5.0) -> Polar:
    """The same speed at every wind angle and speed: the fastest route is the shortest, the great circle."""
    twa = np.array([0.0, 90.0, 180.0])
    tws = np.array([0.0, 40.0])
    return Polar(name="constant", twa_deg=twa, tws_kn=tws, speed_kn=np.full((3, 2), speed_kn))


def test_corridor_through_grid_columns_reproduces_the_grid_nodes() -> None:
    grid = make_grid(START_PT, FINISH_PT, n_ranks=12, n_nodes=9, spacing_km=60.0, max_deviation_deg=50.0)
    cols = np.array([4, 5, 5, 6, 5, 4, 3, 3, 4, 4, 5, 4])
    c = corridor_grid(grid, grid.offset_km[cols], half_width_km=2 * grid.spacing_km, n_nodes=5)
    np.testing.assert_allclose(c.lon_deg[:, 2], grid.lon_deg[np.arange(12), cols], rtol=0, atol=1e-12)
    np.testing.assert_allclose(c.lat_deg[:, 2], grid.lat_deg[np.arange(12), cols], rtol=0, atol=1e-12)
    # nodes lie on their rank line at the stated offsets: cross-track distance from the course's great circle
    xt = geodesy.cross_track_km(*START_PT, *FINISH_PT, c.lon_deg, c.lat_deg)
    np.testing.assert_allclose(np.abs(xt), np.abs(c.node_offsets_km()), rtol=1e-9, atol=1e-6)
    # arcs within the deviation limit: lateral step <= tan(50 deg) x rank spacing, and every such arc is there
    step = np.abs(c.node_offsets_km()[1:, :, None] - c.node_offsets_km()[:-1, None, :])
    limit = np.tan(np.radians(50.0)) * grid.rank_spacing_km
    assert np.array_equal(c.rank_valid, step <= limit + 1e-6 * grid.spacing_km)
    assert c.n_arcs == int(c.rank_valid.sum()) + int(c.start_valid.sum()) + int(c.finish_valid.sum())


@pytest.mark.parametrize("seed", range(4))
def test_dp_on_a_corridor_equals_networkx(seed: int) -> None:
    rng = np.random.default_rng(40 + seed)
    grid = make_grid(
        START_PT, FINISH_PT, n_ranks=8, n_nodes=9, spacing_km=80.0, max_deviation_deg=[None, 45.0][seed % 2]
    )
    centre = rng.uniform(-200.0, 200.0, grid.n_ranks)
    c = corridor_grid(grid, centre, half_width_km=float(rng.uniform(40, 160)), n_nodes=7)
    problem = RoutingProblem(departure=DEP, weather=random_weather(rng), polar=random_polar(rng), samples=2)
    res = forward_dp(c, problem)
    try:
        ref = nx.shortest_path_length(c.to_networkx(weights_by_rank(c, problem)), START, FINISH, weight="weight")
    except nx.NetworkXNoPath:
        ref = np.inf
    assert res.finish_h == pytest.approx(ref, rel=1e-12)


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(6))
def test_refinement_never_lengthens_and_its_legs_add_up(seed: int) -> None:
    rng = np.random.default_rng(seed)
    grid = make_grid(START_PT, FINISH_PT, n_ranks=15, n_nodes=41, spacing_km=25.0, max_deviation_deg=45.0)
    problem = RoutingProblem(departure=DEP, weather=random_weather(rng), polar=random_polar(rng), samples=2)
    res = forward_dp(grid, problem)
    if not np.isfinite(res.finish_h):
        pytest.skip("no feasible route in this random case")
    c_grid, c_problem, c_res, levels = refine(grid, problem, res, levels=3)
    times = [res.finish_h] + [lv.voyage_time_h for lv in levels]
    assert all(b <= a for a, b in zip(times[:-1], times[1:], strict=False))
    assert c_res.finish_h == min(times)
    # the refined track, recomputed leg by leg from its points, takes the DP's time
    elapsed, _ = path_costs(c_grid, c_problem, list(c_res.path()))
    assert elapsed[-1] == pytest.approx(c_res.finish_h, rel=1e-9)


def test_refinement_finds_the_great_circle_an_even_grid_misses() -> None:
    """Constant polar, uniform wind: the optimum is the great circle (distance / speed). With an even node count
    the square grid has no node on it; one refinement level puts the track on it (to rounding)."""
    grid = make_grid(START_PT, FINISH_PT, n_ranks=20, n_nodes=20)
    problem = RoutingProblem(
        departure=DEP, weather=UniformWeather(tws_kn=12.0, twd_deg=30.0), polar=constant_polar(5.0), samples=1
    )
    res = forward_dp(grid, problem)
    exact_h = SPHERE.inv(*START_PT, *FINISH_PT)[2] / 1852.0 / 5.0  # great-circle distance [nm] / 5 kn
    assert res.finish_h > exact_h * (1 + 1e-5)  # precondition: the grid's best is longer
    _, _, c_res, _ = refine(grid, problem, res, levels=2)
    assert c_res.finish_h == pytest.approx(exact_h, rel=1e-9)


def test_refinement_keeps_the_grid_deviation_limit() -> None:
    grid = make_grid(START_PT, FINISH_PT, n_ranks=30, n_nodes=61, spacing_km=20.0, max_deviation_deg=30.0)
    rng = np.random.default_rng(3)
    problem = RoutingProblem(departure=DEP, weather=random_weather(rng), polar=random_polar(rng), samples=2)
    c_grid, _, c_res, _ = refine(grid, problem, forward_dp(grid, problem), levels=3)
    off = c_grid.node_offsets_km()[np.arange(c_grid.n_ranks), c_res.path()]
    assert np.all(np.abs(np.diff(off)) <= np.tan(np.radians(30.0)) * grid.rank_spacing_km * (1 + 1e-9))


def test_a_level_that_would_lengthen_the_voyage_ends_the_refinement() -> None:
    grid = make_grid(START_PT, FINISH_PT, n_ranks=10, n_nodes=11)
    problem = RoutingProblem(
        departure=DEP, weather=UniformWeather(tws_kn=12.0, twd_deg=0.0), polar=constant_polar(5.0), samples=1
    )
    res = forward_dp(grid, problem)
    slow = replace(problem, polar=constant_polar(4.0))  # stands in for costs that are not FIFO
    c_grid, c_problem, c_res, levels = refine(grid, problem, res, levels=3, problem_for=lambda g: slow)
    assert c_grid is grid and c_problem is problem and c_res is res
    assert len(levels) == 1 and levels[0].voyage_time_h > res.finish_h


def test_bad_arguments_are_refused() -> None:
    grid = make_grid(START_PT, FINISH_PT, n_ranks=5, n_nodes=5)
    with pytest.raises(GridError, match="centre_km must be 5 finite offsets"):
        corridor_grid(grid, np.zeros(4), half_width_km=10.0)
    with pytest.raises(GridError, match="n_nodes must be an odd whole number"):
        corridor_grid(grid, np.zeros(5), half_width_km=10.0, n_nodes=4)
    with pytest.raises(GridError, match="half_width_km must be a positive"):
        corridor_grid(grid, np.zeros(5), half_width_km=0.0)
    problem = RoutingProblem(
        departure=DEP, weather=UniformWeather(tws_kn=12.0, twd_deg=0.0), polar=constant_polar(), samples=1
    )
    with pytest.raises(GridError, match="refine levels must be a whole number >= 1"):
        refine(grid, problem, forward_dp(grid, problem), levels=0)
    # None in place of the grid or the result raised AttributeError ('NoneType' object has no attribute ...).
    with pytest.raises(GridError, match="refine: grid must be a Grid"):
        refine(None, problem, forward_dp(grid, problem), levels=1)  # type: ignore[arg-type]
    with pytest.raises(GridError, match="refine: result must be a DPResult"):
        refine(grid, problem, None, levels=1)  # type: ignore[arg-type]


def test_track_offsets_follow_the_path() -> None:
    grid = make_grid(START_PT, FINISH_PT, n_ranks=6, n_nodes=7, spacing_km=50.0)
    problem = RoutingProblem(
        departure=DEP,
        weather=UniformWeather(tws_kn=12.0, twd_deg=0.0),
        polar=random_polar(np.random.default_rng(1)),
        samples=1,
    )
    res = forward_dp(grid, problem)
    np.testing.assert_array_equal(track_offsets_km(grid, res), grid.offset_km[res.path()])


# ------------------------------------------------------------------------------------------ through scenarios


@pytest.mark.slow
def test_refined_route_round_guadeloupe_keeps_its_margin_and_is_faster() -> None:
    sc = scenario_from_mapping(
        {
            "route": {"start": [-57.0, 16.25], "finish": [-64.0, 16.25]},
            "grid": {"n_ranks": 40, "aspect": 4.0, "half_width_km": 150.0},
            "weather": {"kind": "uniform", "tws_kn": 15.0, "twd_deg": 0.0},
            "avoid": {"land": True, "margin_km": 10.0},
        }
    )
    plain = sc.route()
    refined = replace(sc, refine=3).route()
    assert refined.voyage_time_h < plain.voyage_time_h
    info = refined.meta["refine"]
    assert info["grid_voyage_time_h"] == plain.voyage_time_h and len(info["levels"]) == 3
    assert refined.grid is not None and refined.grid.n_nodes == plain.grid.n_nodes  # the grid routed on
    # every refined leg keeps 10 km (less the documented 2.5 %) off GSHHG land grown by nothing: distances in a
    # local metric (lon scaled by cos(lat)) along legs densified every 0.5 km by PROJ
    land = ob.land_geometry((-66.0, 13.0, -55.0, 19.5))
    k = np.cos(np.radians(16.25))
    land_xy = shapely.transform(land, lambda xy: xy * (k, 1.0))
    for a, b, c, d in zip(
        refined.lon_deg[:-1], refined.lat_deg[:-1], refined.lon_deg[1:], refined.lat_deg[1:], strict=True
    ):
        n = int(np.ceil(SPHERE.inv(a, b, c, d)[2] / 500.0))
        pts = np.array([(a, b), *SPHERE.npts(a, b, c, d, n), (c, d)])
        dist_deg = land_xy.distance(shapely.LineString(pts * (k, 1.0)))
        assert dist_deg * geodesy.EARTH_RADIUS_KM * np.pi / 180.0 >= 10.0 * 0.975 - 0.2


def test_cli_refine_reports_levels(tmp_path, capsys) -> None:
    args = ["route", str(CONTROL), "--n-ranks", "40", "--no-land", "--quiet"]
    assert main([*args, "--json"]) == 0
    plain = json.loads(capsys.readouterr().out)
    assert main([*args, "--json", "--refine", "2"]) == 0
    got = json.loads(capsys.readouterr().out)
    assert got["voyage_time_h"] < plain["voyage_time_h"]
    assert got["refine"]["grid_voyage_time_h"] == pytest.approx(plain["voyage_time_h"], rel=1e-12)
    assert [lv["voyage_time_h"] for lv in got["refine"]["levels"]][-1] == pytest.approx(got["voyage_time_h"])
    assert got["grid"]["n_nodes"] == plain["grid"]["n_nodes"]
    assert main([*args, "--refine", "2"]) == 0
    assert "refined          " in capsys.readouterr().out
    assert main([*args, "--refine", "-1"]) != 0
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "--refine" in err and ">= 0" in err


def test_scenario_refine_key_is_validated(tmp_path) -> None:
    text = CONTROL.read_text().replace("[grid]", "[grid]\nrefine = 1.5", 1)
    assert "refine = 1.5" in text
    path = tmp_path / "s.toml"
    path.write_text(text)
    with pytest.raises(ScenarioError, match=r"s\.toml: \[grid\]\.refine must be a whole number \(got 1\.5\)"):
        load_scenario(path)
    path.write_text(text.replace("refine = 1.5", "refine = -1"))
    with pytest.raises(ScenarioError, match=r"\[grid\]\.refine must be .*>= 0"):
        load_scenario(path)
    assert CORRIDOR_NODES % 2 == 1  # the previous track is the corridor's middle node
    ok = tmp_path / "ok.toml"
    ok.write_text(text.replace("refine = 1.5", "refine = 2"))
    assert load_scenario(ok).refine == 2


@pytest.mark.slow
def test_refine_weather_patch_detour_is_found(tmp_path) -> None:
    """A forbidding patch on the course: refinement keeps the detour (no refined leg crosses the patch)."""
    patch = Patch(lon=(-40.0, -30.0), lat=(28.0, 38.0), values={"hs_m": 6.0})
    from pyroute_rel.reliability.failure import load_failure_model

    grid = make_grid(START_PT, FINISH_PT, n_ranks=30, n_nodes=61, spacing_km=25.0, max_deviation_deg=45.0)
    problem = RoutingProblem(
        departure=DEP,
        weather=UniformWeather(tws_kn=15.0, twd_deg=0.0, hs_m=1.0, patches=(patch,)),
        polar=constant_polar(5.0),
        samples=8,
        failure=load_failure_model("dickson2018"),
        apf=0.5,
    )
    res = forward_dp(grid, problem)
    c_grid, c_problem, c_res, _ = refine(grid, problem, res, levels=3)
    _, costs = path_costs(c_grid, c_problem, list(c_res.path()))
    assert np.all(costs.p_f <= 0.5)
    assert c_res.finish_h <= res.finish_h


@pytest.mark.slow
def test_refining_a_course_with_a_waypoint_refines_each_leg() -> None:
    sc = scenario_from_mapping(
        {
            "route": {"start": [-12.0, 45.0], "finish": [-60.0, 17.5], "waypoints": [[-35.0, 38.0]]},
            "grid": {"n_ranks": 40},
            "weather": {"kind": "uniform", "tws_kn": 15.0, "twd_deg": 0.0},
            "avoid": {"land": False},
        }
    )
    plain = sc.route()
    refined = replace(sc, refine=2).route()
    info = refined.meta["refine"]
    assert refined.voyage_time_h < plain.voyage_time_h
    # steady weather: each leg's grid time does not depend on when it starts, so the grid times add up to the plain
    assert info["grid_voyage_time_h"] == pytest.approx(plain.voyage_time_h, rel=1e-12)
    assert info["levels"][-1]["voyage_time_h"] == pytest.approx(refined.voyage_time_h, rel=1e-12)
    # the track still passes the mark
    mark = np.flatnonzero((np.abs(refined.lon_deg + 35.0) < 1e-9) & (np.abs(refined.lat_deg - 38.0) < 1e-9))
    assert mark.size == 1
    track = refined.grid_track
    np.testing.assert_array_equal(track.lon_deg, plain.lon_deg)
    assert track.voyage_time_h == info["grid_voyage_time_h"]


def test_refine_refuses_results_and_settings_that_cannot_work() -> None:
    grid = make_grid(START_PT, FINISH_PT, n_ranks=6, n_nodes=7, spacing_km=50.0)
    other = make_grid(START_PT, FINISH_PT, n_ranks=5, n_nodes=7, spacing_km=50.0)
    problem = RoutingProblem(
        departure=DEP, weather=UniformWeather(tws_kn=12.0, twd_deg=0.0), polar=constant_polar(), samples=1
    )
    res = forward_dp(grid, problem)
    with pytest.raises(GridError, match="odd whole number >= 3"):
        refine(grid, problem, res, levels=2, n_nodes=1)  # was ZeroDivisionError
    with pytest.raises(GridError, match="the DPResult of this grid"):
        refine(grid, problem, forward_dp(other, problem), levels=1)  # was IndexError
    with pytest.raises(GridError, match="reaches 6000 km"):
        corridor_grid(grid, np.zeros(6), half_width_km=6000.0)
