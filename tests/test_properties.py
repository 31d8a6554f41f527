"""Property tests of the router (issue 7): optimality, invariances, consistent times, and NaN never read as calm.

References are independent of the code under test where it matters: path times are recomputed leg by leg with
:func:`~pyroute_rel.routing.solve.path_costs` (no DP), distances and sample points come from ``pyproj.Geod`` on the same
sphere, and "inside a NaN box" is decided by the test's own comparison of coordinates.

Examples are bounded and derandomised (deterministic CI); ``PYROUTE_FUZZ_EXAMPLES=N`` runs N random ones.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from pyproj import Geod
from test_solve import SamplesOnly  # the WeatherSource protocol around a sample()-only test source

from pyroute_rel import geodesy
from pyroute_rel.boat.polar import Polar
from pyroute_rel.errors import NoFeasibleRouteError
from pyroute_rel.routing.grid import Grid, make_grid
from pyroute_rel.routing.route import route_on_grid
from pyroute_rel.routing.solve import RoutingProblem, forward_dp, path_costs
from pyroute_rel.weather import Conditions, Patch, UniformWeather

DEP = np.datetime64("2018-06-01T00:00:00")
SPHERE = Geod(a=geodesy.EARTH_RADIUS_KM * 1000.0, b=geodesy.EARTH_RADIUS_KM * 1000.0)
_SCALE = int(os.environ.get("PYROUTE_FUZZ_EXAMPLES", "0"))


def prop_settings(n: int) -> settings:
    return settings(max_examples=_SCALE or n, derandomize=not _SCALE, deadline=None, database=None)


# ---------------------------------------------------------------------------------------------------------
# Strategies: polars, weather, grids, paths


@st.composite
def polars(draw: st.DrawFn, *, positive: bool = False) -> Polar:
    """A random valid polar: TWA rows on a 5-deg lattice in [0, 180], TWS columns on a 1-kn lattice in [0, 40].

    With ``positive`` every speed is > 0 and the table spans TWA 0-180 and TWS 0-40, so no arc is forbidden by
    the polar (the NaN tests need the NaN to be the only reason).
    """
    twa = sorted(draw(st.lists(st.integers(0, 36), min_size=2, max_size=6, unique=True)))
    tws = sorted(draw(st.lists(st.integers(0, 40), min_size=2, max_size=5, unique=True)))
    if positive:
        twa = sorted({0, *twa, 36})
        tws = sorted({0, *tws, 40})
    speed = st.floats(0.2, 12.0) if positive else st.one_of(st.just(0.0), st.floats(0.1, 12.0))
    rows = draw(st.lists(st.lists(speed, min_size=len(tws), max_size=len(tws)), min_size=len(twa), max_size=len(twa)))
    return Polar(name="fuzz", twa_deg=np.array(twa, float) * 5.0, tws_kn=np.array(tws, float), speed_kn=np.array(rows))


_TWS = st.floats(0.0, 40.0)
_TWD = st.floats(0.0, 359.99)


@st.composite
def patches(
    draw: st.DrawFn, *, lon: tuple[float, float] = (-75.0, 0.0), lat: tuple[float, float] = (5.0, 55.0)
) -> Patch:
    lo0 = draw(st.floats(lon[0], lon[1] - 0.5))
    la0 = draw(st.floats(lat[0], lat[1] - 0.5))
    lo1 = draw(st.floats(lo0 + 0.5, lon[1]))
    la1 = draw(st.floats(la0 + 0.5, lat[1]))
    names = draw(st.sampled_from([("tws_kn",), ("twd_deg",), ("tws_kn", "twd_deg")]))
    values = {name: draw(_TWS if name == "tws_kn" else _TWD) for name in names}
    return Patch(lon=(lo0, lo1), lat=(la0, la1), values=values)


@st.composite
def grids(draw: st.DrawFn, *, max_ranks: int = 4, max_nodes: int = 4) -> Grid:
    start = (draw(st.floats(-30.0, -5.0)), draw(st.floats(35.0, 50.0)))
    finish = (draw(st.floats(-65.0, -40.0)), draw(st.floats(10.0, 25.0)))
    return make_grid(
        start,
        finish,
        n_ranks=draw(st.integers(1, max_ranks)),
        n_nodes=draw(st.integers(1, max_nodes)),
        spacing_km=draw(st.floats(30.0, 400.0)),
        max_deviation_deg=draw(st.none() | st.floats(20.0, 80.0)),
    )


def draw_path(draw: st.DrawFn, grid: Grid) -> list[int] | None:
    """A node sequence along existing arcs (start arc, banded inner arcs, finish arc), or None."""
    nodes = [draw(st.sampled_from(np.flatnonzero(grid.start_valid).tolist()))]
    for _ in range(grid.n_ranks - 1):
        lo, hi = max(0, nodes[-1] - grid.band), min(grid.n_nodes - 1, nodes[-1] + grid.band)
        nodes.append(draw(st.integers(lo, hi)))
    return nodes if grid.finish_valid[nodes[-1]] else None


def is_graph_path(grid: Grid, nodes: list[int]) -> bool:
    """Independent check that consecutive nodes are joined by an arc of the grid's pattern."""
    if not grid.start_valid[nodes[0]] or not grid.finish_valid[nodes[-1]]:
        return False
    for a, b in zip(nodes[:-1], nodes[1:], strict=True):
        cols = np.flatnonzero((grid.src_index[b] == a) & grid.arc_valid[b])
        if cols.size == 0:
            return False
    return True


# ---------------------------------------------------------------------------------------------------------
# 1. The DP is optimal: no path of the grid is faster


@pytest.mark.slow
@prop_settings(60)
@given(data=st.data())
def test_dp_is_no_slower_than_any_path(data: st.DataObject) -> None:
    grid = data.draw(grids())
    weather = UniformWeather(
        tws_kn=data.draw(_TWS), twd_deg=data.draw(_TWD), patches=tuple(data.draw(st.lists(patches(), max_size=3)))
    )
    problem = RoutingProblem(
        departure=DEP, weather=weather, polar=data.draw(polars()), samples=data.draw(st.integers(1, 3))
    )
    result = forward_dp(grid, problem)
    best = result.finish_h
    for _ in range(6):
        nodes = draw_path(data.draw, grid)
        if nodes is None:
            continue
        assert is_graph_path(grid, nodes)
        t_path = path_costs(grid, problem, nodes)[0][-1]
        assert best <= t_path * (1.0 + 1e-12), (best, t_path, nodes)
    if np.isfinite(best):  # and the DP's own path, recomputed leg by leg, takes exactly that time
        assert is_graph_path(grid, result.path().tolist())
        assert path_costs(grid, problem, result.path())[0][-1] == pytest.approx(best, rel=1e-12)


# ---------------------------------------------------------------------------------------------------------
# 2. Invariances of the weather description


def _dp_key(grid: Grid, weather: UniformWeather, polar: Polar, samples: int) -> tuple[float, bytes]:
    res = forward_dp(grid, RoutingProblem(departure=DEP, weather=weather, polar=polar, samples=samples))
    return res.finish_h, res.arrival_h.tobytes()


@pytest.mark.slow
@prop_settings(40)
@given(data=st.data())
def test_dp_invariant_under_patch_order_and_far_patches(data: st.DataObject) -> None:
    grid = data.draw(grids())
    polar = data.draw(polars())
    samples = data.draw(st.integers(1, 3))
    # non-overlapping patches: one per 15-deg longitude slot, in a random order
    slots = data.draw(st.lists(st.integers(0, 4), min_size=2, max_size=5, unique=True))
    boxes = [data.draw(patches(lon=(-75.0 + 15.0 * s, -60.0 + 15.0 * s - 0.01))) for s in slots]
    base = UniformWeather(tws_kn=data.draw(_TWS), twd_deg=data.draw(_TWD), patches=tuple(boxes))
    ref = _dp_key(grid, base, polar, samples)
    order = data.draw(st.permutations(boxes))
    assert _dp_key(grid, replace(base, patches=tuple(order)), polar, samples) == ref
    # a patch entirely outside the grid (any values, even no wind): east of 0 deg, or south of every point of the
    # grid (great-circle arcs north of the equator reach their lowest latitude at an end point)
    lat_min = min(float(grid.lat_deg.min()), grid.start[1], grid.finish[1])
    assert float(grid.lon_deg.max()) < 0.0 and lat_min > 1.0  # premise of "outside"
    far = data.draw(
        st.one_of(
            patches(lon=(10.0, 179.0), lat=(-80.0, 80.0)), patches(lon=(-180.0, 180.0), lat=(-89.0, lat_min - 0.5))
        )
    )
    where = data.draw(st.integers(0, len(order)))
    more = (*order[:where], far, *order[where:])
    assert _dp_key(grid, replace(base, patches=more), polar, samples) == ref


# ---------------------------------------------------------------------------------------------------------
# 3. Route times are consistent


@dataclass(frozen=True)
class VeeringWind(SamplesOnly):
    """A time-varying source (not steady): wind veering and strengthening slowly with time."""

    tws0: float
    steady = False
    time_steps = None

    def sample(self, lon_deg: Any, lat_deg: Any, time: Any) -> Conditions:
        lon, lat, t = np.broadcast_arrays(
            np.asarray(lon_deg, float), np.asarray(lat_deg, float), (np.asarray(time) - DEP) / np.timedelta64(1, "h")
        )
        z = np.zeros(lon.shape)
        return Conditions(
            tws_kn=self.tws0 + 4.0 * np.sin(t / 300.0) ** 2,
            twd_deg=(0.1 * t + lat) % 360.0,
            hs_m=z + 1.0,
            wave_dir_deg=z,
            wave_period_s=z * np.nan,
            current_u_ms=z,
            current_v_ms=z,
        )

    def check_coverage(self, *args: Any) -> None:
        return None


@pytest.mark.slow
@prop_settings(40)
@given(data=st.data())
def test_route_times_are_consistent(data: st.DataObject) -> None:
    grid = data.draw(grids())
    steady = data.draw(st.booleans())
    weather = (
        UniformWeather(
            tws_kn=data.draw(st.floats(4.0, 30.0)),
            twd_deg=data.draw(_TWD),
            patches=tuple(data.draw(st.lists(patches(), max_size=2))),
        )
        if steady
        else VeeringWind(tws0=data.draw(st.floats(4.0, 20.0)))
    )
    step = data.draw(st.none() | st.sampled_from([0.5, 1.0, 3.0, 6.0]))
    max_wait = 0.0 if step is None else data.draw(st.sampled_from([0.0, step, 4 * step]))
    problem = RoutingProblem(
        departure=DEP,
        weather=weather,
        polar=data.draw(polars(positive=True)),
        samples=data.draw(st.integers(1, 3)),
        time_step_h=step,
        max_wait_h=max_wait,
    )
    route = route_on_grid(grid, problem)
    t, legs = route.elapsed_h, route.legs
    assert t[0] == 0.0 and np.all(np.diff(t) >= 0.0)
    assert route.voyage_time_h == t[-1] == pytest.approx(route.dp.finish_h, rel=1e-12)
    # each leg's time is its distance over its speed over ground, with the distance from pyproj
    _, _, d_m = SPHERE.inv(route.lon_deg[:-1], route.lat_deg[:-1], route.lon_deg[1:], route.lat_deg[1:])
    np.testing.assert_allclose(legs["distance_nm"], np.asarray(d_m) / 1852.0, rtol=1e-9)
    np.testing.assert_allclose(legs["time_h"], legs["distance_nm"] / legs["sog_kn"], rtol=1e-12)
    assert np.all(np.isfinite(legs["time_h"])) and np.all(legs["time_h"] > 0)
    start_sailing = t[:-1] + legs["wait_h"]
    if step is None:  # continuous time: legs follow each other without gaps
        np.testing.assert_allclose(np.diff(t), legs["wait_h"] + legs["time_h"], rtol=1e-12, atol=1e-9)
        assert np.all(legs["wait_h"] == 0.0)
    else:  # on the lattice: arrival is the first lattice time at or after the leg's end
        np.testing.assert_allclose(t / step, np.round(t / step), atol=1e-9)
        assert np.all(t[1:] >= start_sailing + legs["time_h"] - 1e-9)
        assert np.all(t[1:] < start_sailing + legs["time_h"] + step + 1e-9)
        assert np.all(legs["wait_h"] <= max_wait + 1e-12)


# ---------------------------------------------------------------------------------------------------------
# 4. NaN in the weather is never calm water


@dataclass(frozen=True)
class NaNBox(SamplesOnly):
    """A steady uniform field with ``nan_fields`` NaN inside a lon/lat box (closed) [deg]."""

    base: UniformWeather
    lon: tuple[float, float]
    lat: tuple[float, float]
    nan_fields: tuple[str, ...] = ("tws_kn",)
    steady = True
    time_steps = None

    @property
    def max_current_ms(self) -> float:  # type: ignore[override]
        return self.base.max_current_ms

    def inside(self, lon: Any, lat: Any) -> Any:
        return (lon >= self.lon[0]) & (lon <= self.lon[1]) & (lat >= self.lat[0]) & (lat <= self.lat[1])

    def sample(self, lon_deg: Any, lat_deg: Any, time: Any) -> Conditions:
        c = self.base.sample(lon_deg, lat_deg, time)
        lon, lat = np.broadcast_arrays(np.asarray(lon_deg, float), np.asarray(lat_deg, float))
        mask = np.broadcast_to(self.inside(lon, lat), c.tws_kn.shape)
        values = {name: getattr(c, name) for name in Conditions.__dataclass_fields__}
        for name in self.nan_fields:
            values[name] = np.where(mask, np.nan, values[name])
        return Conditions(**values)

    def check_coverage(self, *args: Any) -> None:
        return None


def longest_sub_segment_km(grid: Grid, samples: int) -> float:
    """Longest distance between consecutive weather samples along any arc, from pyproj."""
    longest = 0.0
    for k in range(grid.n_ranks + 1):
        lon0, lat0, lon1, lat1, _, valid = grid.arcs(k)
        a = [np.broadcast_to(x, valid.shape)[valid] for x in (lon0, lat0, lon1, lat1)]
        _, _, d_m = SPHERE.inv(*a)
        longest = max(longest, float(np.max(d_m)) / 1000.0 / samples)
    return longest


def sample_points(lon: Any, lat: Any, samples: int) -> tuple[np.ndarray, np.ndarray]:
    """Midpoints of ``samples`` equal sub-segments of each leg (pyproj: 2 samples - 1 inner points, odd ones)."""
    out_lon, out_lat = [], []
    for lo0, la0, lo1, la1 in zip(lon[:-1], lat[:-1], lon[1:], lat[1:], strict=True):
        pts = SPHERE.npts(lo0, la0, lo1, la1, 2 * samples - 1)
        mids = pts[0::2]
        out_lon += [p[0] for p in mids]
        out_lat += [p[1] for p in mids]
    return np.array(out_lon), np.array(out_lat)


NAN_FIELDS = st.sampled_from([("tws_kn",), ("twd_deg",), ("tws_kn", "twd_deg")])


@st.composite
def nan_setups(draw: st.DrawFn) -> tuple[Grid, UniformWeather, Polar, int, float, tuple[str, ...]]:
    grid = draw(grids(max_ranks=5, max_nodes=6))
    base = UniformWeather(tws_kn=draw(st.floats(4.0, 30.0)), twd_deg=draw(_TWD))
    samples = draw(st.integers(1, 4))
    lat_lo = min(grid.start[1], grid.finish[1])
    lat_hi = max(grid.start[1], grid.finish[1])
    centre = draw(st.floats(lat_lo + 0.25 * (lat_hi - lat_lo), lat_hi - 0.25 * (lat_hi - lat_lo)))
    return grid, base, draw(polars(positive=True)), samples, centre, draw(NAN_FIELDS)


@pytest.mark.slow
@prop_settings(30)
@given(setup=nan_setups())
def test_nan_band_across_the_grid_blocks_every_route(setup: Any) -> None:
    grid, base, polar, samples, centre, fields = setup
    # every path runs from the start's latitude to the finish's, so it crosses the band's centre latitude at some
    # point, which lies within half a sub-segment of a sample point: a band that wide always holds a sample
    half = longest_sub_segment_km(grid, samples) / 2.0 / (math.pi * geodesy.EARTH_RADIUS_KM / 180.0) + 0.01
    assume(centre - half > min(grid.start[1], grid.finish[1]) and centre + half < max(grid.start[1], grid.finish[1]))
    clean = RoutingProblem(departure=DEP, weather=base, polar=polar, samples=samples)
    assert np.isfinite(forward_dp(grid, clean).finish_h)  # premise: feasible without the NaN band
    problem = replace(
        clean, weather=NaNBox(base, lon=(-180.0, 180.0), lat=(centre - half, centre + half), nan_fields=fields)
    )
    result = forward_dp(grid, problem)
    assert not np.isfinite(result.finish_h)
    # the only arcs forbidden are forbidden for missing weather (the polar is positive everywhere)
    assert result.forbidden_by_reason["weather"] > 0
    assert all(n == 0 for name, n in result.forbidden_by_reason.items() if name != "weather")
    with pytest.raises(NoFeasibleRouteError, match="missing weather data"):
        route_on_grid(grid, problem)


def test_front_dying_at_the_finish_still_names_the_reason() -> None:
    """The nodes still reachable on the last rank have no arc to the finish (banded grid): the message must say
    what cut the others off (it said only 'no arc into it starts from a reachable node'; fixed in 2e654ee)."""
    grid = make_grid((-5.0, 35.0), (-40.0, 15.0), n_ranks=3, n_nodes=5, spacing_km=250.0, max_deviation_deg=20.0)
    polar = Polar("flat", twa_deg=[0.0, 180.0], tws_kn=[0.0, 40.0], speed_kn=[[1.0, 5.0], [1.0, 5.0]])
    weather = NaNBox(UniformWeather(tws_kn=10.0, twd_deg=0.0), lon=(-180.0, 180.0), lat=(19.5, 24.5))
    problem = RoutingProblem(departure=DEP, weather=weather, polar=polar, samples=2)
    assert forward_dp(grid, problem).forbidden_by_reason["weather"] > 0  # premise: NaN arcs were met
    with pytest.raises(NoFeasibleRouteError, match="missing weather data"):
        route_on_grid(grid, problem)


@pytest.mark.slow
@prop_settings(40)
@given(setup=nan_setups(), data=st.data())
def test_nan_box_partly_across_is_avoided(setup: Any, data: st.DataObject) -> None:
    grid, base, polar, samples, centre, fields = setup
    half = data.draw(st.floats(0.2, 3.0))
    # the box covers the band's latitudes on one side of a random longitude only
    cut = data.draw(st.floats(float(grid.lon_deg.min()), float(grid.lon_deg.max())))
    lon = (-180.0, cut) if data.draw(st.booleans()) else (cut, 180.0)
    weather = NaNBox(base, lon=lon, lat=(centre - half, centre + half), nan_fields=fields)
    problem = RoutingProblem(departure=DEP, weather=weather, polar=polar, samples=samples)
    result = forward_dp(grid, problem)
    assume(np.isfinite(result.finish_h) and result.forbidden_by_reason["weather"] > 0)  # a route, and the box bit
    route = route_on_grid(grid, problem)
    lon_s, lat_s = sample_points(route.lon_deg, route.lat_deg, samples)
    shrunk = NaNBox(base, lon=(lon[0] + 1e-7, lon[1] - 1e-7), lat=(centre - half + 1e-7, centre + half - 1e-7))
    assert not np.any(shrunk.inside(lon_s, lat_s)), "the route samples weather inside the NaN box"
    assert np.all(np.isfinite(route.legs["time_h"]))
    # every leg reports conditions: at its midpoint, or (a hole there that its samples straddle) at a sample
    assert np.all(np.isfinite(route.legs["tws_kn"])) and np.all(np.isfinite(route.legs["twd_deg"]))


def test_nan_current_is_reported_as_missing_weather() -> None:
    """NaN currents forbid the arcs (not calm water) as missing weather (was 'current too strong', fixed in 73a9571)."""
    grid = make_grid((-12.0, 45.0), (-40.0, 20.0), n_ranks=3, n_nodes=3)
    base = UniformWeather(tws_kn=15.0, twd_deg=0.0)
    polar = Polar("flat", twa_deg=[0.0, 180.0], tws_kn=[0.0, 40.0], speed_kn=[[1.0, 5.0], [1.0, 5.0]])
    weather = NaNBox(base, lon=(-180.0, 180.0), lat=(-90.0, 90.0), nan_fields=("current_u_ms", "current_v_ms"))
    with pytest.raises(NoFeasibleRouteError, match="missing weather data"):
        route_on_grid(grid, RoutingProblem(departure=DEP, weather=weather, polar=polar))


def test_tiny_boat_speed_without_current_is_an_infinite_time() -> None:
    """Was a RuntimeWarning (overflow in seg_nm / sog) at a boat speed of ~1e-308 kn (fixed in 73a9571)."""
    from pyroute_rel.routing.cost import arc_costs

    polar = Polar("light", twa_deg=[0.0, 180.0], tws_kn=[1.0, 20.0], speed_kn=[[2.0, 6.0], [2.0, 6.0]])
    c = arc_costs(
        -10.0, 40.0, -12.0, 38.0, 0.0, departure=DEP, polar=polar, weather=UniformWeather(tws_kn=1e-308, twd_deg=0.0)
    )
    # 1e-308 kn of wind: 2e-308 kn of boat speed (linear below the first column), so the ~150 nm take longer
    # than any float: an infinite time
    assert float(c.time_h) == np.inf


def test_tiny_boat_speed_with_current_is_forbidden_without_warnings() -> None:
    """Was a RuntimeWarning (overflow in ratio**2) under a current (fixed in 2e654ee)."""
    from pyroute_rel.routing.cost import arc_costs

    polar = Polar("light", twa_deg=[0.0, 180.0], tws_kn=[1.0, 20.0], speed_kn=[[2.0, 6.0], [2.0, 6.0]])
    weather = UniformWeather(tws_kn=1e-300, twd_deg=0.0, current_u_ms=-3.0)
    c = arc_costs(-10.0, 40.0, -12.0, 38.0, 0.0, departure=DEP, polar=polar, weather=weather)
    # 2e-300 kn of boat speed against 5.8 kn of cross current: the course cannot be held
    assert float(c.time_h) == np.inf and c.reason != 0


def test_bug_subnormal_boat_speed_with_current_overflows_in_the_drift() -> None:
    from pyroute_rel.routing.cost import arc_costs

    polar = Polar("light", twa_deg=[0.0, 180.0], tws_kn=[1.0, 20.0], speed_kn=[[2.0, 6.0], [2.0, 6.0]])
    weather = UniformWeather(tws_kn=2.2250738585072014e-309, twd_deg=0.0, current_u_ms=-10.0)
    c = arc_costs(-30.0, 30.0, -32.0, 28.0, 0.0, departure=DEP, polar=polar, weather=weather)
    # no speed through the water to speak of (below the 0.01 kn minimum): the arc is forbidden
    assert float(c.time_h) == np.inf and c.reason != 0
