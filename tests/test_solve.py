"""The forward DP is exact on its graph: networkx, brute force, and independent leg recomputation."""

from __future__ import annotations

import itertools
from dataclasses import dataclass, replace
from typing import Any

import networkx as nx
import numpy as np
import pytest
from pyproj import Geod

from pyroute_rel import geodesy
from pyroute_rel.boat.polar import Polar, boat_speed_kn, get_polar
from pyroute_rel.errors import NoFeasibleRouteError, ScenarioError
from pyroute_rel.reliability.failure import load_failure_model
from pyroute_rel.routing.cost import arc_costs
from pyroute_rel.routing.grid import FINISH, START, make_grid
from pyroute_rel.routing.route import route_on_grid
from pyroute_rel.routing.solve import RoutingProblem, forward_dp, path_costs
from pyroute_rel.times import hours_after
from pyroute_rel.weather import FIELDS, Conditions, Patch, UniformWeather, WeatherBase

DEP = np.datetime64("2018-06-01T00:00:00")
START_PT, FINISH_PT = (-12.0, 45.0), (-60.0, 17.5)
SPHERE = Geod(a=geodesy.EARTH_RADIUS_KM * 1000.0, b=geodesy.EARTH_RADIUS_KM * 1000.0)


def random_polar(rng: np.random.Generator) -> Polar:
    twa = np.array([0.0, 30.0, 45.0, 60.0, 90.0, 120.0, 150.0, 180.0])
    tws = np.array([0.0, 6.0, 12.0, 20.0, 30.0])
    speed = rng.uniform(0.5, 8.0, (twa.size, tws.size))
    speed[0] = 0.0
    speed[:, 0] = 0.0
    return Polar(name="random", twa_deg=twa, tws_kn=tws, speed_kn=speed)


def random_weather(rng: np.random.Generator) -> UniformWeather:
    patches = tuple(
        Patch(
            lon=(lo, lo + rng.uniform(3, 10)),
            lat=(la, la + rng.uniform(3, 10)),
            values={"tws_kn": float(rng.uniform(2, 25)), "twd_deg": float(rng.uniform(0, 360))},
        )
        for lo, la in zip(rng.uniform(-55, -20, 3), rng.uniform(20, 40, 3), strict=True)
    )
    return UniformWeather(tws_kn=float(rng.uniform(5, 20)), twd_deg=float(rng.uniform(0, 360)), patches=patches)


def weights_by_rank(grid, problem) -> list[np.ndarray]:
    """Every arc's cost from the cost function directly (static weather: independent of departure time)."""
    out = []
    for k in range(grid.n_ranks + 1):
        lon0, lat0, lon1, lat1, _, valid = grid.arcs(k)
        c = arc_costs(
            lon0,
            lat0,
            lon1,
            lat1,
            0.0,
            departure=DEP,
            weather=problem.weather,
            polar=problem.polar,
            failure=problem.failure,
            apf=problem.apf,
            samples=problem.samples,
        )
        out.append(np.where(valid, c.time_h, np.inf))
    return out


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("shape,dev", [((5, 5), None), ((7, 6), None), ((9, 9), 60.0), ((12, 11), 40.0)])
def test_dp_equals_networkx_dijkstra(seed: int, shape: tuple[int, int], dev: float | None) -> None:
    rng = np.random.default_rng(seed)
    grid = make_grid(
        START_PT,
        FINISH_PT,
        n_ranks=shape[0],
        n_nodes=shape[1],
        max_deviation_deg=dev,
        spacing_km=float(rng.uniform(40, 200)),
    )
    problem = RoutingProblem(
        departure=DEP, weather=random_weather(rng), polar=random_polar(rng), samples=int(rng.integers(1, 4))
    )
    result = forward_dp(grid, problem)
    g = grid.to_networkx(weights_by_rank(grid, problem))
    try:
        ref = nx.shortest_path_length(g, START, FINISH, weight="weight")
    except nx.NetworkXNoPath:
        ref = np.inf
    assert result.finish_h == pytest.approx(ref, rel=1e-12)
    if np.isfinite(ref):
        route = route_on_grid(grid, problem)
        assert route.voyage_time_h == pytest.approx(ref, rel=1e-9)


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(4))
def test_dp_equals_brute_force_on_tiny_grids(seed: int) -> None:
    rng = np.random.default_rng(100 + seed)
    grid = make_grid(START_PT, FINISH_PT, n_ranks=4, n_nodes=4, spacing_km=float(rng.uniform(100, 400)))
    problem = RoutingProblem(departure=DEP, weather=random_weather(rng), polar=random_polar(rng), samples=2)
    best = np.inf
    for path in itertools.product(range(grid.n_nodes), repeat=grid.n_ranks):
        elapsed, _ = path_costs(grid, problem, list(path))
        best = min(best, elapsed[-1])
    assert forward_dp(grid, problem).finish_h == pytest.approx(best, rel=1e-12)


class SamplesOnly(WeatherBase):
    """The rest of the WeatherSource protocol for a test source that only knows how to ``sample``: not steady,
    every field defined, no current; ``prepare``/``sample_at`` sample the same points at the asked times."""

    steady = False
    time_steps = None
    fields = frozenset(FIELDS)
    max_current_ms = 0.0

    def prepare(self, lon_deg: Any, lat_deg: Any) -> Any:
        return np.broadcast_arrays(np.asarray(lon_deg, float), np.asarray(lat_deg, float))

    def sample_at(self, prepared: Any, departure: Any, *, offset_h: Any = None, fields: Any = None) -> Conditions:
        time = departure if offset_h is None else hours_after(departure, offset_h)
        return self.sample(prepared[0], prepared[1], time)  # type: ignore[attr-defined]

    def check_coverage(self, *args: Any) -> None:
        return None


@dataclass(frozen=True)
class VeeringWind(SamplesOnly):
    """Wind that veers slowly with time (a time-varying source; FIFO holds for slow change)."""

    steady = False
    time_steps = None

    def sample(self, lon_deg, lat_deg, time) -> Conditions:
        lon, lat, t = np.broadcast_arrays(
            np.asarray(lon_deg, float), np.asarray(lat_deg, float), (np.asarray(time) - DEP) / np.timedelta64(1, "h")
        )
        z = np.zeros(lon.shape)
        return Conditions(
            tws_kn=12.0 + 2.0 * np.sin(t / 400.0),
            twd_deg=(10.0 * t / 100.0) % 360.0,
            hs_m=z + 1.0,
            wave_dir_deg=z,
            wave_period_s=z * np.nan,
            current_u_ms=z,
            current_v_ms=z,
        )

    def check_coverage(self, *args) -> None:
        return None


@pytest.mark.slow
def test_time_dependent_dp_equals_brute_force_when_fifo() -> None:
    grid = make_grid(START_PT, FINISH_PT, n_ranks=4, n_nodes=4, spacing_km=150.0)
    problem = RoutingProblem(departure=DEP, weather=VeeringWind(), polar=get_polar("maribot_vane"), samples=2)
    # premise: FIFO holds on every arc (leaving later never arrives earlier), checked on a time grid
    t = np.linspace(0.0, 1500.0, 151)
    for k in range(grid.n_ranks + 1):
        lon0, lat0, lon1, lat1, _, valid = grid.arcs(k)
        arrive = np.stack([tt + problem.costs(lon0, lat0, lon1, lat1, tt).time_h for tt in t])
        assert np.all(np.diff(arrive[:, valid], axis=0) > 0)
    best = min(
        path_costs(grid, problem, list(p))[0][-1] for p in itertools.product(range(grid.n_nodes), repeat=grid.n_ranks)
    )
    result = forward_dp(grid, problem)
    assert result.finish_h == pytest.approx(best, rel=1e-9)
    # and the weather really changes the answer: the same wind frozen at departure routes differently
    frozen = UniformWeather(tws_kn=12.0, twd_deg=0.0, hs_m=1.0)
    assert (
        abs(
            forward_dp(grid, RoutingProblem(departure=DEP, weather=frozen, polar=problem.polar, samples=2)).finish_h
            - best
        )
        > 1.0
    )


def test_route_legs_recomputed_independently_sum_to_voyage_time() -> None:
    """Each leg from its end points with pyproj (distance, midpoint, heading) and the polar's table."""
    polar = get_polar("maribot_vane")
    w = UniformWeather(
        tws_kn=15.0,
        twd_deg=0.0,
        hs_m=1.0,
        patches=(Patch(lon=(-45.0, -35.0), lat=(28.0, 38.0), values={"tws_kn": 6.0}),),
    )
    grid = make_grid(START_PT, FINISH_PT, n_ranks=30, n_nodes=31)
    route = route_on_grid(grid, RoutingProblem(departure=DEP, weather=w, polar=polar))
    total = 0.0
    for i in range(len(route.lon_deg) - 1):
        lo0, la0, lo1, la1 = route.lon_deg[i], route.lat_deg[i], route.lon_deg[i + 1], route.lat_deg[i + 1]
        _, _, d_m = SPHERE.inv(lo0, la0, lo1, la1)
        ((mlo, mla),) = SPHERE.npts(lo0, la0, lo1, la1, 1)
        heading, _, _ = SPHERE.inv(mlo, mla, lo1, la1)
        inside = -45.0 <= mlo <= -35.0 and 28.0 <= mla <= 38.0
        tws = 6.0 if inside else 15.0
        twa = abs((0.0 - heading + 180.0) % 360.0 - 180.0)
        speed = float(boat_speed_kn(polar, twa, tws))
        total += d_m / 1852.0 / speed
        assert route.legs["time_h"][i] == pytest.approx(d_m / 1852.0 / speed, rel=1e-9)
    assert route.voyage_time_h == pytest.approx(total, rel=1e-9)
    assert route.elapsed_h[-1] == pytest.approx(route.dp.finish_h, rel=1e-12)
    assert route.time[-1] == route.arrival


def test_infinite_arcs_are_never_chosen_and_infeasible_is_explained() -> None:
    polar = get_polar("maribot_vane")
    # a wall of calm (no boat speed) across the whole grid between 29 and 33 N; arcs are sampled densely
    # enough (8 samples) that none can hop over it
    wall = Patch(lon=(-80.0, 10.0), lat=(29.0, 33.0), values={"tws_kn": 0.0})
    grid = make_grid(START_PT, FINISH_PT, n_ranks=20, n_nodes=9)
    problem = RoutingProblem(
        departure=DEP, weather=UniformWeather(tws_kn=15.0, twd_deg=0.0, patches=(wall,)), polar=polar, samples=8
    )
    with pytest.raises(NoFeasibleRouteError, match=r"front died at rank \d+ of 20.*no boat speed in the polar"):
        route_on_grid(grid, problem)
    # a partial wall with a gap: the route goes through the gap, never through a zero-speed arc
    left = Patch(lon=(-80.0, -36.0), lat=(29.0, 33.0), values={"tws_kn": 0.0})
    problem = RoutingProblem(
        departure=DEP, weather=UniformWeather(tws_kn=15.0, twd_deg=0.0, patches=(left,)), polar=polar, samples=8
    )
    route = route_on_grid(grid, problem)
    assert np.all(np.isfinite(route.legs["time_h"]))
    frac = (np.arange(8) + 0.5) / 8
    mlon, mlat = geodesy.intermediate_point(
        route.lon_deg[:-1, None], route.lat_deg[:-1, None], route.lon_deg[1:, None], route.lat_deg[1:, None], frac
    )
    assert not np.any(left.contains(mlon, mlat))


@dataclass(frozen=True)
class PassingStorm(SamplesOnly):
    """A band of 6 m seas (the ``dickson2018`` criterion WH fires: p_f 0.9) across the whole course between 39 and
    41 N until ``clears_h`` after departure; 15 kn from the north and 1 m seas from the north everywhere else and
    later. At apf 0.5 the band forbids every arc through it while it lasts, and waiting inside the arc would be in
    it: only a wait at a node gets through."""

    clears_h: float = 130.0
    steady = False

    @property
    def time_steps(self) -> np.ndarray:
        """The conditions change once, when the storm clears."""
        return np.array([DEP + np.timedelta64(int(self.clears_h * 3600), "s")], dtype="datetime64[ns]")

    def sample(self, lon_deg, lat_deg, time) -> Conditions:
        lon, lat, t = np.broadcast_arrays(
            np.asarray(lon_deg, float), np.asarray(lat_deg, float), (np.asarray(time) - DEP) / np.timedelta64(1, "h")
        )
        z = np.zeros(lon.shape)
        storm = (lat >= 39.0) & (lat <= 41.0) & (t < self.clears_h)
        return Conditions(
            tws_kn=z + 15.0,
            twd_deg=z,
            hs_m=np.where(storm, 6.0, 1.0),
            wave_dir_deg=z,
            wave_period_s=z * np.nan,
            current_u_ms=z,
            current_v_ms=z,
        )

    def check_coverage(self, *args) -> None:
        return None


@pytest.mark.slow
def test_time_expanded_dp_waits_out_a_storm_and_matches_brute_force() -> None:
    grid = make_grid(START_PT, (-30.0, 30.0), n_ranks=2, n_nodes=3, spacing_km=60.0)
    polar = get_polar("maribot_vane")
    storm = {"failure": load_failure_model("dickson2018"), "apf": 0.5}
    plain = RoutingProblem(departure=DEP, weather=PassingStorm(), polar=polar, samples=2, **storm)
    # without waiting at a node the storm band forbids every arc when the craft gets there: no route
    with pytest.raises(NoFeasibleRouteError):
        route_on_grid(grid, plain)
    step, max_wait = 30.0, 90.0  # (waits of 0-90 h a node, 4^3 per path: the brute force stays small)
    waiting = RoutingProblem(
        departure=DEP,
        weather=PassingStorm(),
        polar=polar,
        samples=2,
        time_step_h=step,
        max_wait_h=max_wait,
        **storm,
    )
    route = route_on_grid(grid, waiting)
    assert route.legs["wait_h"].sum() > 0
    # the storm is crossed after it clears: no leg sails through the band before clears_h
    assert np.all(np.isfinite(route.legs["time_h"]))
    # brute force over every path and every wait (multiples of the step) at every node, same lattice rules
    n_w = int(max_wait / step) + 1
    best = np.inf
    for path in itertools.product(range(grid.n_nodes), repeat=grid.n_ranks):
        for waits in itertools.product(range(n_w), repeat=grid.n_ranks + 1):
            if best < np.inf and sum(waits) * step > best:
                continue
            elapsed, _ = path_costs(grid, waiting, list(path), np.array(waits) * step)
            best = min(best, elapsed[-1])
    assert route.voyage_time_h == pytest.approx(best, rel=1e-12)
    # times are on the lattice and legs chain: arrival = ceil(departure after wait + sailing time)
    assert np.allclose(route.elapsed_h / step, np.round(route.elapsed_h / step))


def test_waiting_never_helps_in_steady_weather() -> None:
    grid = make_grid(START_PT, FINISH_PT, n_ranks=6, n_nodes=5)
    w = UniformWeather(tws_kn=15.0, twd_deg=0.0)
    polar = get_polar("maribot_vane")
    lattice = RoutingProblem(departure=DEP, weather=w, polar=polar, time_step_h=1.0)
    waiting = RoutingProblem(departure=DEP, weather=w, polar=polar, time_step_h=1.0, max_wait_h=24.0)
    assert forward_dp(grid, waiting).finish_h == forward_dp(grid, lattice).finish_h
    assert np.all(forward_dp(grid, waiting).waits() == 0.0)


def _same_dp(grid, problem) -> tuple[int, int]:
    """forward_dp with and without pruning: the same arrivals, back-pointers and finish (the exact same route)."""
    full = forward_dp(grid, replace(problem, prune=False))
    pruned = forward_dp(grid, replace(problem, prune=True))
    np.testing.assert_array_equal(pruned.arrival_h, full.arrival_h)
    np.testing.assert_array_equal(pruned.back, full.back)
    assert pruned.finish_h == full.finish_h and pruned.finish_back == full.finish_back
    return pruned.arcs_evaluated, full.arcs_evaluated


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(8))
def test_pruning_finds_the_same_route_in_steady_weather(seed: int, monkeypatch) -> None:
    """Random polars (top speeds 0.5-8 kn), patched wind, with and without currents, square and banded grids."""
    monkeypatch.setattr("pyroute_rel.routing.solve.PRUNE_MIN_WIDTH", 0)  # prune these small grids too
    rng = np.random.default_rng(100 + seed)
    square = seed % 2 == 0
    grid = make_grid(
        START_PT,
        FINISH_PT,
        n_ranks=int(rng.integers(6, 14)),
        n_nodes=int(rng.integers(5, 13)),
        max_deviation_deg=None if square else 45.0,
        spacing_km=float(rng.uniform(40, 200)),
    )
    weather = random_weather(rng)
    if seed % 4 == 1:  # a current (east) the bound must include
        weather = UniformWeather(
            tws_kn=weather.tws_kn,
            twd_deg=weather.twd_deg,
            patches=weather.patches,
            current_u_ms=float(rng.uniform(-1.0, 1.0)),
            current_v_ms=float(rng.uniform(-1, 1)),
        )
    problem = RoutingProblem(departure=DEP, weather=weather, polar=random_polar(rng), samples=int(rng.integers(1, 4)))
    pruned, full = _same_dp(grid, problem)
    assert pruned <= full


def test_pruning_finds_the_same_route_over_time_varying_gridded_weather_and_land(monkeypatch) -> None:
    """The paper's failure model over a veering gridded wind with a NaN island, and a land mask tested lazily: the
    same route, with far fewer arcs costed on the square grid."""
    monkeypatch.setattr("pyroute_rel.routing.solve.PRUNE_MIN_WIDTH", 0)  # prune these small grids too
    from test_cost import _varying_field

    from pyroute_rel.obstacles.mask import Avoid, obstacle_mask
    from pyroute_rel.reliability.failure import load_failure_model

    grid = make_grid((-31.5, 28.5), (-30.0, 30.0), n_ranks=16, n_nodes=16, max_deviation_deg=None)  # < 48 h
    problem = RoutingProblem(
        departure=DEP,
        weather=_varying_field(),
        polar=get_polar("maribot_vane"),
        failure=load_failure_model("dickson2018"),
        apf=0.95,
        samples=2,
    )
    first = forward_dp(grid, replace(problem, prune=False))
    assert np.isfinite(first.finish_h) and first.forbidden_by_reason["failure"] > 0  # premise: a route, and risk
    pruned, full = _same_dp(grid, problem)
    assert pruned < full / 2
    caribbean = make_grid(
        (-57.0, 16.25), (-64.0, 16.25), n_ranks=20, n_nodes=15, max_deviation_deg=None, spacing_km=10.0
    )
    land = RoutingProblem(
        departure=DEP,
        weather=UniformWeather(tws_kn=15.0, twd_deg=0.0),
        polar=get_polar("maribot_vane"),
        blocked=obstacle_mask(caribbean, Avoid(land=True)),
    )
    assert forward_dp(caribbean, replace(land, prune=False)).forbidden_by_reason["obstacle"] > 0  # land in the way
    _same_dp(caribbean, land)


@pytest.mark.parametrize(
    ("change", "match"),
    [
        ({"departure": None}, r"departure must be a UTC time .* \(got None\)"),  # routed with NaT times before
        ({"departure": np.datetime64("NaT")}, "departure must be a UTC time"),
        ({"departure": "garbage"}, "departure must be a UTC time"),
        ({"polar": "maribot_vane"}, r"RoutingProblem\.polar must be a Polar .* \(got str\)"),
        ({"weather": None}, r"RoutingProblem\.weather must be a weather source"),
        ({"blocked": 5}, r"RoutingProblem\.blocked must be an obstacle mask callback"),
    ],
)
def test_routing_problem_refuses_what_it_cannot_route(change, match) -> None:
    from pyroute_rel.errors import ScenarioError

    base = {"departure": DEP, "weather": UniformWeather(tws_kn=12.0, twd_deg=0.0), "polar": get_polar("maribot_vane")}
    with pytest.raises(ScenarioError, match=match):
        RoutingProblem(**{**base, **change})


@pytest.mark.parametrize(
    ("make", "match"),
    [
        (lambda: UniformWeather(tws_kn=-1.0, twd_deg=0.0), r"UniformWeather\.tws_kn must be in \[0, 200\]"),
        (lambda: UniformWeather(tws_kn=float("nan"), twd_deg=0.0), r"tws_kn must be in"),
        (lambda: UniformWeather(tws_kn="15", twd_deg=0.0), r"tws_kn must be a number"),
        (
            lambda: UniformWeather(tws_kn=15.0, twd_deg=0.0, patches=Patch((0, 1), (0, 1), {"hs_m": 4.0})),
            r"patches must be a sequence of Patch",
        ),
        (lambda: Patch((1.0, 0.0), (0.0, 1.0), {"hs_m": 4.0}), r"Patch\.lon must satisfy -180 <= min < max <= 180"),
        (lambda: Patch((0.0, 1.0), (0.0, 1.0), {"bogus": 4.0}), r"unknown field 'bogus'"),
        (lambda: Patch((0.0, 1.0), (0.0, 1.0), {"hs_m": -4.0}), r"hs_m must be in \[0, 30\]"),
    ],
)
def test_control_weather_constructors_validate(make, match) -> None:
    from pyroute_rel.errors import ScenarioError

    with pytest.raises(ScenarioError, match=match):
        make()
    assert UniformWeather(tws_kn=15.0, twd_deg=360.0).twd_deg == 0.0  # the documented [0, 360)


class BreezeCore:
    """A third party's weather source: a steady breeze from the north-east, reported as time-varying so that the
    router takes its prepared-sampling path; the six members every source writes, nothing else."""

    steady = False
    time_steps = None
    fields = frozenset({"tws_kn", "twd_deg"})
    max_current_ms = 0.0

    def sample(self, lon_deg: Any, lat_deg: Any, time: Any) -> Conditions:
        lon, lat, _ = np.broadcast_arrays(np.asarray(lon_deg, float), np.asarray(lat_deg, float), np.asarray(time))
        nan = np.full(lon.shape, np.nan)
        zero = np.zeros(lon.shape)
        return Conditions(
            tws_kn=zero + 14.0,
            twd_deg=zero + 45.0,
            hs_m=nan,
            wave_dir_deg=nan,
            wave_period_s=nan,
            current_u_ms=zero,
            current_v_ms=zero,
        )

    def check_coverage(self, lon_range: Any, lat_range: Any, time_range: Any) -> None:
        return None


class Breeze(WeatherBase, BreezeCore):
    """The breeze with the protocol's capabilities at their defaults (:class:`~pyroute_rel.weather.WeatherBase`:
    prepared sampling by ``sample``, no boundaries, ...)."""


def test_a_source_implementing_only_the_protocol_routes_like_the_built_in_one() -> None:
    from pyroute_rel.obstacles.mask import Avoid, ObstacleMask
    from pyroute_rel.routing.solve import ArcMask
    from pyroute_rel.weather import WeatherSource

    assert isinstance(Breeze(), WeatherSource) and not isinstance(BreezeCore(), WeatherSource)
    with pytest.raises(
        ScenarioError,
        match=r"\(got BreezeCore, which lacks prepare, sample_at, boundaries, .*: subclass "
        r"pyroute_rel.weather.WeatherBase\)$",
    ):
        RoutingProblem(departure=DEP, weather=BreezeCore(), polar=get_polar("maribot_vane"))
    grid = make_grid(START_PT, FINISH_PT, n_ranks=5, n_nodes=5, spacing_km=150.0)
    polar = get_polar("maribot_vane")
    mine = route_on_grid(grid, RoutingProblem(departure=DEP, weather=Breeze(), polar=polar, samples=3))
    same = UniformWeather(tws_kn=14.0, twd_deg=45.0)
    ref = route_on_grid(grid, RoutingProblem(departure=DEP, weather=same, polar=polar, samples=3))
    np.testing.assert_array_equal(mine.dp.path(), ref.dp.path())
    assert mine.voyage_time_h == pytest.approx(ref.voyage_time_h, rel=1e-12)
    # the built-in sources and the obstacle mask satisfy the protocols the solver states
    assert isinstance(same, WeatherSource) and isinstance(_varying_weather(), WeatherSource)
    assert isinstance(ObstacleMask(grid, Avoid(land=False, zones=())), ArcMask)


def _varying_weather() -> Any:
    from test_cost import _varying_field

    return _varying_field()


def test_uniform_prepared_sampling_gives_what_sample_gives() -> None:
    w = UniformWeather(
        tws_kn=12.0, twd_deg=30.0, hs_m=2.0, patches=(Patch((-20.0, -10.0), (40.0, 50.0), {"hs_m": 5.0}),)
    )
    lon, lat = np.array([[-15.0, -5.0], [-12.0, -30.0]]), np.array([45.0, 44.0])
    direct = w.sample(lon, lat, DEP)
    for at in (w.sample_at(w.prepare(lon, lat), DEP), w.sample_at(w.prepare(lon, lat), DEP, offset_h=np.ones((2, 2)))):
        for name in FIELDS:
            np.testing.assert_array_equal(getattr(at, name), getattr(direct, name))
