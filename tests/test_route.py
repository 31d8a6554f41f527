"""The Route result: typed per-leg conditions, the JSON summary, the objects it knows, its forbidden arcs."""

from __future__ import annotations

import json
from dataclasses import fields

import numpy as np
import pytest

from pyroute_rel.routing.cost import REASONS
from pyroute_rel.routing.route import LEG_FIELDS, ForbiddenArcs, Legs, Route
from pyroute_rel.routing.solve import forward_dp
from pyroute_rel.scenario import scenario_from_mapping
from pyroute_rel.settings import settings_context

#: The paper's control course on a small grid, with its two patches and the dickson2018 model; apf 0.5 forbids
#: the arcs through the patches (criteria WH and WD).
CONTROL = {
    "route": {"start": [-12.0, 45.0], "finish": [-60.0, 17.5], "prune": False},
    "grid": {"n_ranks": 24, "aspect": 3.0, "half_width_km": 700.0},
    "weather": {
        "kind": "uniform",
        "tws_kn": 15.0,
        "twd_deg": 0.0,
        "hs_m": 1.0,
        "wave_dir_deg": 0.0,
        "patch": [
            {"name": "Area 2", "lon": [-45.0, -35.0], "lat": [28.0, 38.0], "hs_m": 4.0},
            {"name": "Area 1", "lon": [-43.0, -37.0], "lat": [30.0, 36.0], "wave_dir_deg": 240.0},
        ],
    },
    "failure": {"model": "dickson2018", "apf": 0.5},
    "avoid": {"land": False},  # the arcs' own costs only (obstacles: tests/test_avoid_routing.py)
}


def control(**route: object) -> Route:
    return scenario_from_mapping({**CONTROL, "route": {**CONTROL["route"], **route}}).route()


@pytest.fixture(scope="module")
def routed() -> Route:
    return control()


def test_legs_are_typed_arrays_also_read_by_name(routed: Route) -> None:
    legs = routed.legs
    assert isinstance(legs, Legs)
    n = routed.lon_deg.size - 1
    assert legs.n_legs == n
    assert sorted(legs) == sorted(LEG_FIELDS) and len(legs) == len(LEG_FIELDS)
    for name in LEG_FIELDS:
        assert legs[name] is vars(legs)[name] and legs[name].shape == (n,) and legs[name].dtype == float
    with pytest.raises(KeyError):
        legs["speed"]
    # the legs add up to the voyage: waits and sailing times to the elapsed time, distances to the distance
    assert float(np.sum(legs.wait_h + legs.time_h)) == pytest.approx(routed.voyage_time_h, rel=1e-12)
    np.testing.assert_allclose(np.diff(routed.elapsed_h), legs.wait_h + legs.time_h, rtol=1e-12)
    assert float(legs.distance_nm.sum()) == routed.distance_nm
    np.testing.assert_allclose(legs.sog_kn, legs.distance_nm / legs.time_h, rtol=1e-12)
    assert routed.max_failure_probability == float(legs.p_f.max()) <= 0.5


def test_legs_refuse_arrays_of_different_lengths() -> None:
    values = {f.name: np.zeros(3) for f in fields(Legs)}
    with pytest.raises(ValueError, match="Legs.time_h must be a 1-D array of 3 values"):
        Legs(**{**values, "time_h": np.zeros(2)})


def test_summary_is_json_of_plain_values_and_the_objects_are_attributes(routed: Route) -> None:
    summary = routed.summary()
    text = json.dumps(summary)  # plain JSON: no object leaks into it
    assert "_object" not in text
    assert list(summary) == [
        "voyage_time_h",
        "distance_nm",
        "departure",
        "arrival",
        "grid",
        "arcs",
        "max_failure_probability",
        "voyage_failure_probability",
        "exposure_by_criterion_h",
        "manoeuvres",
        "apf",
        "failure_model",
        "failure_exposure_h",
        "polar",
        "samples_per_arc",
        "scenario",
        "land",
        "track",
    ]
    assert summary["failure_model"] == "dickson2018" and summary["apf"] == 0.5
    assert len(summary["track"]) == routed.lon_deg.size
    # what the map needs is typed and not in the JSON
    assert routed.weather is routed.problem.weather and routed.weather.steady
    assert routed.failure is not None and routed.failure.name == "dickson2018"
    assert routed.zones == () and routed.course_legs == () and routed.grid_track is None
    assert routed.grids == (routed.grid,)


def _check_forbidden(route: Route, arcs: ForbiddenArcs) -> None:
    """Every arc listed is forbidden at its own departure time, and every other arc from a reached node is allowed,
    recomputed independently arc by arc (``RoutingProblem.costs``: the arc's own geometry, not the grid's cache)."""
    grid, problem, dp = route.grid, route.problem, route.dp
    listed = set(zip(arcs.rank.tolist(), arcs.dst.tolist(), arcs.src.tolist(), strict=True))
    assert len(listed) == len(arcs)
    n_checked = 0
    for k in range(grid.n_ranks + 1):
        lon0, lat0, lon1, lat1, src, valid = grid.arcs(k)
        t_prev = np.zeros(grid.start_points[0].size) if k == 0 else dp.arrival_h[k - 1]
        shape = src.shape
        for j, c in zip(*np.nonzero(valid & np.isfinite(t_prev[src])), strict=True):
            t0 = float(t_prev[src[j, c]])
            pts = [float(np.broadcast_to(a, shape)[j, c]) for a in (lon0, lat0, lon1, lat1)]
            cost = problem.costs(*pts, t0)
            forbidden = int(cost.reason) != 0
            assert forbidden == ((k, j, int(src[j, c])) in listed), (k, j, c)
            if forbidden:
                n_checked += 1
                i = np.flatnonzero((arcs.rank == k) & (arcs.dst == j) & (arcs.src == src[j, c]))[0]
                assert arcs.reason[i] == "+".join(n for n, b in REASONS.items() if int(cost.reason) & b)
                assert arcs.departure_h[i] == t0
                assert [arcs.from_lon_deg[i], arcs.from_lat_deg[i], arcs.to_lon_deg[i], arcs.to_lat_deg[i]] == pts
                assert arcs.p_f[i] == pytest.approx(float(cost.p_f), nan_ok=True)
                if arcs.reason[i] == "failure":  # (with missing weather p_f is NaN)
                    assert float(cost.p_f) > problem.apf
    assert n_checked == len(arcs)


def test_forbidden_arcs_are_those_forbidden_at_their_own_departure(routed: Route) -> None:
    arcs = routed.forbidden_arcs()
    assert isinstance(arcs, ForbiddenArcs) and len(arcs) > 0
    # without pruning the DP costs every arc from reached nodes: the same arcs, counts and criteria
    assert len(arcs) == routed.dp.arcs_forbidden
    for name, n in routed.dp.forbidden_by_reason.items():
        assert sum(name in r.split("+") for r in arcs.reason) == n
    for name, n in routed.dp.forbidden_by_criterion.items():
        assert sum(name in c.split("; ") for c in arcs.criteria) == n
    assert set(arcs.reason) == {"failure"}
    assert routed.failure is not None
    names = [c.describe() for c in routed.failure.criteria]
    assert all(c and set(c.split("; ")) <= set(names) for c in arcs.criteria)
    _check_forbidden(routed, arcs)
    # the forbidden arcs touch the patches (Area 2 spans 45-35 W, 28-38 N)
    assert np.all(np.maximum(arcs.from_lon_deg, arcs.to_lon_deg) >= -45.5)
    assert np.all(np.minimum(arcs.from_lon_deg, arcs.to_lon_deg) <= -34.5)
    expected = routed.departure + np.round(arcs.departure_h * 3600.0).astype("timedelta64[s]")
    np.testing.assert_array_equal(arcs.departure, expected)
    table = arcs.as_dict()
    assert list(table) == [f.name for f in fields(ForbiddenArcs)] and all(v.size == len(arcs) for v in table.values())
    assert np.all(arcs.leg == 0)


def test_forbidden_arcs_cover_each_leg_of_a_course_through_waypoints() -> None:
    route = control(waypoints=[[-35.0, 38.0]])
    assert len(route.course_legs) == 2 and route.grids == tuple(r.grid for r in route.course_legs)
    arcs = route.forbidden_arcs()
    per_leg = [r.forbidden_arcs() for r in route.course_legs]
    assert len(arcs) == sum(len(a) for a in per_leg) == route.dp.arcs_forbidden
    for i, (leg, a) in enumerate(zip(route.course_legs, per_leg, strict=True)):
        mine = arcs.leg == i
        np.testing.assert_array_equal(arcs.rank[mine], a.rank)
        np.testing.assert_array_equal(arcs.departure[mine], a.departure)
        offset = (leg.departure - route.departure) / np.timedelta64(1, "s") / 3600.0
        np.testing.assert_allclose(arcs.departure_h[mine], a.departure_h + offset, rtol=0, atol=1e-9)
        _check_forbidden(leg, a)
    assert {0, 1} <= set(arcs.leg.tolist())


def test_no_forbidden_arcs_without_a_failure_model() -> None:
    route = scenario_from_mapping({**CONTROL, "failure": {"model": "none"}}).route()
    arcs = route.forbidden_arcs()
    assert len(arcs) == 0 and arcs.reason.shape == (0,) and arcs.departure.dtype == np.dtype("datetime64[s]")


@pytest.mark.slow
def test_a_refined_route_reports_the_forbidden_arcs_of_the_grid_routed_on(routed: Route) -> None:
    refined = scenario_from_mapping({**CONTROL, "grid": {**CONTROL["grid"], "refine": 2}}).route()
    assert refined.grid_track is not None and refined.voyage_time_h <= refined.grid_track.voyage_time_h
    np.testing.assert_array_equal(refined.grid_track.lon_deg, routed.lon_deg)
    assert refined.grid is not routed.grid and refined.grid.n_nodes == routed.grid.n_nodes
    a, b = refined.forbidden_arcs(), routed.forbidden_arcs()
    for f in fields(ForbiddenArcs):
        np.testing.assert_array_equal(vars(a)[f.name], vars(b)[f.name])
    assert refined.summary()["refine"]["grid_voyage_time_h"] == routed.voyage_time_h


@pytest.mark.parametrize(
    "course",
    [
        {"time_step_h": 2.0, "max_wait_h": 6.0},  # waiting: forbidden at every departure tried
        {"finish_line": [[-60.0, 10.0], [-60.0, 25.0]]},  # the DP stops once nothing can beat the crossing
        {"start": None, "start_line": [[-16.0, 51.0], [-8.0, 45.0]]},  # arcs from every start point
    ],
)
def test_forbidden_arcs_agree_with_the_dp_on_every_course(course: dict[str, object]) -> None:
    route_table = {k: v for k, v in {**CONTROL["route"], **course}.items() if v is not None}
    route = scenario_from_mapping({**CONTROL, "route": route_table}).route()
    arcs = route.forbidden_arcs()
    assert len(arcs) == route.dp.arcs_forbidden > 0
    for name, n in route.dp.forbidden_by_criterion.items():
        assert sum(name in c.split("; ") for c in arcs.criteria) == n
    _check_forbidden(route, arcs)  # steady weather: forbidden after a wait as well as at the first departure


def test_forbidden_arcs_over_time_varying_weather_and_land() -> None:
    """Each arc is costed at its own departure time (a veering gridded wind with a NaN island, the paper's model);
    land forbids arcs under the obstacle reason."""
    from dataclasses import replace

    from test_cost import _varying_field

    from pyroute_rel.boat.polar import get_polar
    from pyroute_rel.obstacles.mask import Avoid, obstacle_mask
    from pyroute_rel.reliability.failure import load_failure_model
    from pyroute_rel.routing.grid import make_grid
    from pyroute_rel.routing.route import route_on_grid
    from pyroute_rel.routing.solve import RoutingProblem
    from pyroute_rel.weather import UniformWeather

    dep = np.datetime64("2018-06-01T00:00")
    grid = make_grid((-31.5, 28.5), (-30.0, 30.0), n_ranks=16, n_nodes=16, max_deviation_deg=None)
    problem = RoutingProblem(
        departure=dep,
        weather=_varying_field(),
        polar=get_polar("maribot_vane"),
        failure=load_failure_model("dickson2018"),
        apf=0.95,
        samples=2,
        prune=False,
    )
    route = route_on_grid(grid, problem)
    assert not route.weather.steady
    arcs = route.forbidden_arcs()
    # the map judges every arc on its pieces, as the DP does when it judges eagerly; the DP's own count covers the
    # arcs it judged (lazily: only those it would pick), never more
    with settings_context(lazy_pieces=False):
        eager = forward_dp(grid, problem)
    assert len(arcs) == eager.arcs_forbidden and {"failure", "weather"} <= set(arcs.reason)
    assert route.dp.arcs_forbidden <= eager.arcs_forbidden
    assert np.ptp(arcs.departure_h) > 1.0  # departures spread over the voyage
    _check_forbidden(route, arcs)
    caribbean = make_grid(
        (-57.0, 16.25), (-64.0, 16.25), n_ranks=20, n_nodes=15, max_deviation_deg=None, spacing_km=10.0
    )
    land = RoutingProblem(
        departure=dep,
        weather=UniformWeather(tws_kn=15.0, twd_deg=0.0),
        polar=get_polar("maribot_vane"),
        blocked=obstacle_mask(caribbean, Avoid(land=True)),
    )
    for prune in (False, True):  # the mask learns lazily in the DP; the table checks every arc
        on_land = route_on_grid(caribbean, replace(land, prune=prune))
        arcs = on_land.forbidden_arcs()
        assert set(arcs.reason) == {"obstacle"} and set(arcs.criteria) == {""}
        if prune:  # lazily, the DP tests only the arcs that could win: the table has at least those
            assert len(arcs) >= on_land.dp.forbidden_by_reason["obstacle"] > 0
        else:
            assert len(arcs) == on_land.dp.forbidden_by_reason["obstacle"] > 0
