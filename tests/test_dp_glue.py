"""The forward DP over time-varying gridded weather without repeated work (issue 19: the 52 DPs of the ensemble).

The cost kernel keeps each arc geometry's sample points located on the weather grid (``Settings.locate_cache``) and
reuses them for every source on the same grid: the members of one file are routed on one grid, so a process locates
the points once. The reference is the kernel locating them every time (the switch off): costs and DP results must be
the same to the bit. A cache keyed wrongly (two grids of equal shape but other axes, or another memory layout) would
sample the wrong cells: the costs would differ from the reference, so these tests fail.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import pyroute_rel.routing.cost as cost_module
from pyroute_rel.boat.polar import get_polar
from pyroute_rel.reliability.failure import load_failure_model
from pyroute_rel.routing.cost import REASONS, arc_geometry, deferred_costs, geometry_costs
from pyroute_rel.routing.grid import make_grid
from pyroute_rel.routing.solve import RoutingProblem, forward_dp
from pyroute_rel.settings import settings_context
from pyroute_rel.weather import GriddedWeather, WeatherField
from pyroute_rel.weather.gridded import stack_members

DEP = np.datetime64("2018-06-01T00:00:00")
POLAR = get_polar("maribot_vane")
MODEL = load_failure_model("dickson2018")


def weather(seed: int, *, lon0: float = -26.0, waves: bool = True, period: bool = False) -> GriddedWeather:
    """Wind (and waves) on a 1 deg grid from ``lon0``, every 6 h over 8 days, random from ``seed``."""
    rng = np.random.default_rng(seed)
    lon, lat = lon0 + np.arange(19.0), np.arange(35.0, 49.01, 1.0)
    time = DEP.astype("datetime64[ns]") + np.arange(33) * np.timedelta64(6, "h")
    shape = (time.size, lat.size, lon.size)
    values = {"wind_u_ms": rng.uniform(-9.0, 9.0, shape), "wind_v_ms": rng.uniform(-9.0, 9.0, shape)}
    if waves:
        values["hs_m"] = np.clip(rng.normal(3.5, 1.5, shape), 0.0, None)
        values["wave_dir_deg"] = rng.uniform(0.0, 360.0, shape)
    if period:
        values["wave_period_s"] = rng.uniform(4.0, 12.0, shape)
    return GriddedWeather(
        [WeatherField(k, v.astype(np.float32), lon, lat, time, source="test", variable=k) for k, v in values.items()]
    )


def arcs(seed: int = 0, shape: tuple[int, int] = (12, 7), samples: int = 3):  # type: ignore[no-untyped-def]
    """Random arcs inside the grids (some leaving the shifted one) and departures."""
    rng = np.random.default_rng(seed)
    lon0, lat0 = rng.uniform(-20.0, -12.0, shape), rng.uniform(39.0, 45.0, shape)
    lon1, lat1 = lon0 + rng.uniform(-1.5, 1.5, shape), lat0 + rng.uniform(-1.5, 1.5, shape)
    return arc_geometry(lon0, lat0, lon1, lat1, samples=samples), rng.uniform(0.0, 60.0, shape)


def costs(geom, t0, w, **kw):  # type: ignore[no-untyped-def]
    return geometry_costs(geom, t0, departure=DEP, weather=w, polar=POLAR, failure=MODEL, apf=0.5, **kw)


def assert_same_costs(a, b) -> None:  # type: ignore[no-untyped-def]
    for name in ("time_h", "p_f", "reason"):
        x, y = getattr(a, name), getattr(b, name)
        assert x.dtype == y.dtype
        np.testing.assert_array_equal(x, y)
    np.testing.assert_array_equal(a.bits(), b.bits())


def uncached(geom, t0, w, **kw):  # type: ignore[no-untyped-def]
    with settings_context(locate_cache=False):
        return costs(geom, t0, w, **kw)


class Located:
    """The sample points of arc geometries the sources locate (``GriddedWeather.prepare``; the judgement of arcs on
    the pieces they cross locates other points, not counted)."""

    def __init__(self) -> None:
        self.calls: list[object] = []

    def __call__(self, *geoms) -> int:  # type: ignore[no-untyped-def]
        """How many times points of these geometries (or of parts of them) were located."""
        return sum(any(np.shares_memory(a, g.lon_deg) for g in geoms) for a in self.calls)


@pytest.fixture
def located(monkeypatch: pytest.MonkeyPatch) -> Located:
    seen = Located()
    real = GriddedWeather.prepare

    def counting(self, lon_deg, lat_deg):  # type: ignore[no-untyped-def]
        seen.calls.append(lon_deg)
        return real(self, lon_deg, lat_deg)

    monkeypatch.setattr(GriddedWeather, "prepare", counting)
    return seen


def test_two_sources_on_one_grid_locate_the_points_once(located: Located) -> None:
    geom, t0 = arcs()
    w1, w2 = weather(1), weather(2)
    first = costs(geom, t0, w1)
    assert located(geom) == 1
    second = costs(geom, t0, w2)
    again = costs(geom, t0, w1)
    assert located(geom) == 1  # hits: the second source and the first again
    assert_same_costs(second, uncached(geom, t0, w2))
    assert_same_costs(first, uncached(geom, t0, w1))
    assert_same_costs(again, first)
    assert located(geom) == 3  # the switch off: located every time
    assert not np.array_equal(first.time_h, second.time_h)  # the two sources differ


@pytest.mark.parametrize(
    "other",
    [
        {"lon0": -25.5},  # the same shape, other longitudes
        {"waves": False},  # the same axes, fewer fields: another memory layout
        {"period": True},  # more fields
    ],
)
def test_another_grid_locates_the_points_again(located: Located, other: dict[str, object]) -> None:
    geom, t0 = arcs(1)
    w1, w3 = weather(1), weather(3, **other)  # type: ignore[arg-type]
    costs(geom, t0, w1)
    shifted = costs(geom, t0, w3)
    assert located(geom) == 2  # a miss
    assert_same_costs(shifted, uncached(geom, t0, w3))
    # with the points located on the first grid the costs would differ (the test can fail)
    wrong = w1.prepare(geom.lon_deg, geom.lat_deg)
    assert w3.reuse(wrong) is None
    assert w1.reuse(wrong) is wrong


def test_another_geometry_locates_its_points(located: Located) -> None:
    geom, t0 = arcs(2)
    w = weather(1)
    costs(geom, t0, w)
    twin = arc_geometry(geom.lon_deg, geom.lat_deg, geom.lon_deg + 0.1, geom.lat_deg)  # other points, samples 1
    costs(twin, np.zeros(twin.shape), w)
    assert located(geom) == 1 and located(twin) == 1


def test_the_points_kept_per_geometry_are_bounded(located: Located) -> None:
    geom, t0 = arcs(3)
    grids = [weather(k, lon0=-26.0 + 0.25 * k) for k in range(cost_module.LOCATED_PER_GEOMETRY + 1)]
    for w in grids:
        costs(geom, t0, w)
    assert located(geom) == len(grids)
    for w in grids[1:]:  # the most recent ones are kept
        costs(geom, t0, w)
    assert located(geom) == len(grids)
    costs(geom, t0, grids[0])  # the oldest was dropped
    assert located(geom) == len(grids) + 1


def test_member_stack_points_are_not_reused_by_a_member() -> None:
    w1, w2 = weather(1), weather(2)
    stack = stack_members([w1, w2])
    assert stack is not None
    lon, lat = np.full((2, 3), -15.0), np.full((2, 3), 40.0)
    points = stack.prepare(lon, lat, [0, 1])  # cell indices into both members' data
    assert w1.reuse(points) is None and w2.reuse(points) is None
    assert w2.reuse(w1.prepare(lon, lat)) is not None


def test_split_between_threads_the_parts_keep_their_points(located: Located, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    monkeypatch.setattr(cost_module, "PARALLEL_MIN_MARCHED", 1)
    geom, t0 = arcs(4, shape=(9, 5))
    w1, w2 = weather(1), weather(2)
    one = costs(geom, t0, w1, workers=1)
    assert located(geom) == 1
    two = costs(geom, t0, w2, workers=2)
    assert located(geom) == 3  # the two parts are new geometries: each located once
    assert_same_costs(costs(geom, t0, w1, workers=2), one)
    assert located(geom) == 3  # and kept
    assert_same_costs(two, uncached(geom, t0, w2, workers=1))


def test_deferred_costs_are_the_same_with_and_without_the_cache() -> None:
    geom, t0 = arcs(5)
    w1, w2 = weather(1), weather(2)
    kw = dict(departure=DEP, polar=POLAR, failure=MODEL, apf=0.2)
    deferred_costs(geom, t0, weather=w1, **kw)
    got, pending = deferred_costs(geom, t0, weather=w2, **kw)
    with settings_context(locate_cache=False):
        want, pending_want = deferred_costs(geom, t0, weather=w2, **kw)
    assert_same_costs(got, want)
    assert (pending is None) == (pending_want is None)
    if pending is not None:
        np.testing.assert_array_equal(pending.index, pending_want.index)


def dp(grid, w, apf: float):  # type: ignore[no-untyped-def]
    problem = RoutingProblem(departure=DEP, weather=w, polar=POLAR, failure=MODEL, apf=apf, samples=2)
    return forward_dp(grid, problem)


@pytest.mark.parametrize("apf", [1.0, 0.95])  # 0.95: some arcs judged on the pieces they cross (lazily)
def test_dp_over_members_is_the_same_with_and_without_the_cache(located: Located, apf: float) -> None:
    grid = make_grid((-13.0, 44.0), (-17.0, 41.0), n_ranks=6, n_nodes=7, spacing_km=30.0)
    members = [weather(k) for k in range(3)]
    got = [dp(grid, w, apf) for w in members]
    geoms = list(grid.cache.geometry.values())
    assert located(*geoms) == len(geoms)  # once per rank
    with settings_context(locate_cache=False):
        want = [dp(grid, w, apf) for w in members]
    if apf == 1.0:  # every member reaches the finish: each rank costed once per member
        assert all(np.isfinite(r.finish_h) for r in got)
        assert located(*geoms) == 4 * len(geoms)
    for a, b in zip(got, want, strict=True):
        np.testing.assert_array_equal(a.arrival_h, b.arrival_h)
        np.testing.assert_array_equal(a.back, b.back)
        assert (a.finish_h, a.finish_back, a.dead_rank) == (b.finish_h, b.finish_back, b.dead_rank)
        assert (a.arcs_evaluated, a.arcs_forbidden, a.forbidden_by_reason) == (
            b.arcs_evaluated,
            b.arcs_forbidden,
            b.forbidden_by_reason,
        )


@settings(max_examples=15, derandomize=True, deadline=None, database=None)
@given(st.integers(0, 2**31), st.integers(1, 4), st.floats(-26.5, -25.5), st.sampled_from([0.0, 0.2, 1.0]))
def test_costs_reusing_points_equal_costs_locating_them(seed: int, samples: int, lon0: float, apf: float) -> None:
    geom, t0 = arcs(seed, shape=(4, 3), samples=samples)
    w1, w2 = weather(seed % 7, lon0=lon0), weather(seed % 5 + 7, lon0=lon0)
    for w in (w1, w2):
        got = geometry_costs(geom, t0, departure=DEP, weather=w, polar=POLAR, failure=MODEL, apf=apf)
        with settings_context(locate_cache=False):
            want = geometry_costs(geom, t0, departure=DEP, weather=w, polar=POLAR, failure=MODEL, apf=apf)
        assert_same_costs(got, want)


# --- the compiled bookkeeping between the sampling calls (Settings.compiled_march) ----------------------------------


def numpy_path(geom, t0, **kw):  # type: ignore[no-untyped-def]
    with settings_context(compiled_march=False):
        return geometry_costs(geom, t0, **kw)


def assert_same_fired(a, b) -> None:  # type: ignore[no-untyped-def]
    assert (a.fired_bits is None) == (b.fired_bits is None)
    if a.fired_bits is not None:
        assert a.fired_bits.dtype == b.fired_bits.dtype
        np.testing.assert_array_equal(a.fired_bits, b.fired_bits)


@st.composite
def nan_weather(draw: st.DrawFn) -> GriddedWeather:
    """Wind and waves (and a period) with NaN islands and calm spots; Hs about the 4 m criterion."""
    seed = draw(st.integers(0, 2**31))
    rng = np.random.default_rng(seed)
    lon, lat = np.arange(-26.0, -6.9, 1.0), np.arange(35.0, 49.01, 1.0)
    time = DEP.astype("datetime64[ns]") + np.arange(33) * np.timedelta64(6, "h")
    shape = (time.size, lat.size, lon.size)
    values = {
        "wind_u_ms": rng.uniform(-12.0, 12.0, shape) * (rng.random(shape) > 0.05),  # some calm
        "wind_v_ms": rng.uniform(-12.0, 12.0, shape),
        "hs_m": np.clip(rng.normal(4.0, 1.5, shape), 0.0, None),
        "wave_dir_deg": rng.uniform(0.0, 360.0, shape),
        "wave_period_s": rng.uniform(3.0, 14.0, shape),
    }
    for name in draw(st.sets(st.sampled_from(sorted(values)), max_size=3)):
        v = values[name]
        v[rng.random(shape) < 0.03] = np.nan
    return GriddedWeather(
        [WeatherField(k, v.astype(np.float32), lon, lat, time, source="t", variable=k) for k, v in values.items()]
    )


@pytest.mark.slow
@settings(max_examples=15, derandomize=True, deadline=None, database=None)
@given(
    nan_weather(),
    st.integers(0, 2**31),
    st.integers(1, 4),
    st.sampled_from([None, "dickson2018", "wind_wave_multistate"]),
    st.sampled_from([0.0, 0.2, 0.5, 0.95, 1.0]),
    st.sampled_from(["clamp", "forbid"]),
)
def test_compiled_bookkeeping_equals_the_numpy_path(
    w: GriddedWeather, seed: int, samples: int, model: str | None, apf: float, beyond: str
) -> None:
    geom, t0 = arcs(seed, shape=(6, 5), samples=samples)
    t0 = t0 * 2.0 + 150.0 * (np.arange(6) == 0)[:, None]  # a row leaving after the last time: NaN weather
    kw = dict(
        departure=DEP,
        weather=w,
        polar=POLAR,
        failure=None if model is None else load_failure_model(model),
        apf=apf,
        beyond=beyond,
    )
    for exact in (True, False):
        got = geometry_costs(geom, t0, exact_p_f=exact, **kw)
        want = numpy_path(geom, t0, exact_p_f=exact, **kw)
        assert_same_costs(got, want)
        assert_same_fired(got, want)


@pytest.mark.slow
def test_compiled_bookkeeping_covers_every_flag() -> None:
    """The property test's cases reach every reason, NaN p_f and criteria fired (else it could pass vacuously)."""
    rng = np.random.default_rng(7)
    lon, lat = np.arange(-26.0, -6.9, 1.0), np.arange(35.0, 49.01, 1.0)
    time = DEP.astype("datetime64[ns]") + np.arange(33) * np.timedelta64(6, "h")
    shape = (time.size, lat.size, lon.size)
    hs = np.clip(rng.normal(3.0, 1.5, shape), 0.0, None)
    hs[rng.random(shape) < 0.005] = np.nan
    u = rng.uniform(-12.0, 12.0, shape) * (rng.random(shape) > 0.01)
    v = rng.uniform(-12.0, 12.0, shape) * (u != 0.0)
    u[:, 5:9, 6:10] = v[:, 5:9, 6:10] = 0.0  # a calm box: no speed
    fields = {"wind_u_ms": u, "wind_v_ms": v, "hs_m": hs, "wave_dir_deg": rng.uniform(0.0, 360.0, shape)}
    w = GriddedWeather(
        [WeatherField(k, v.astype(np.float32), lon, lat, time, source="t", variable=k) for k, v in fields.items()]
    )
    geom, t0 = arcs(11, shape=(40, 8), samples=3)
    t0 = t0 + 150.0 * (np.arange(40) < 3)[:, None]
    got = geometry_costs(geom, t0, departure=DEP, weather=w, polar=POLAR, failure=MODEL, apf=0.95, exact_p_f=False)
    want = numpy_path(geom, t0, departure=DEP, weather=w, polar=POLAR, failure=MODEL, apf=0.95, exact_p_f=False)
    assert_same_costs(got, want)
    assert_same_fired(got, want)
    for flag in ("polar", "weather", "failure"):
        assert (got.reason & REASONS[flag]).any(), flag
    assert np.isnan(got.p_f).any() and np.isfinite(got.time_h).any() and got.fired_bits is not None


def test_a_pickled_geometry_leaves_its_located_points_behind() -> None:
    import pickle

    geom, t0 = arcs(6)
    w = weather(1)
    want = costs(geom, t0, w)
    back = pickle.loads(pickle.dumps(geom))
    assert len(pickle.dumps(geom)) == len(pickle.dumps(arcs(6)[0]))  # as a geometry never costed
    np.testing.assert_array_equal(back.lon_deg, geom.lon_deg)
    assert_same_costs(costs(back, t0, w), want)


@pytest.mark.slow
@settings(max_examples=10, derandomize=True, deadline=None, database=None)
@given(
    st.integers(0, 2**31),
    st.integers(1, 3),
    st.sampled_from([None, "dickson2018"]),
    st.floats(0.5, 6.0),
)
def test_compiled_march_adds_each_runs_wind_error_as_the_perturbed_source(
    seed: int, samples: int, model: str | None, sigma_ms: float
) -> None:
    """Monte Carlo's per-run wind error (:class:`~pyroute_rel.analysis.monte_carlo.PerturbedWind`) sailed by the
    compiled march gives the costs of the numpy march sampling the perturbed source (rows are runs)."""
    from pyroute_rel.analysis.monte_carlo import PerturbedWind
    from pyroute_rel.routing.cost import ArcGeometry

    rng = np.random.default_rng(seed)
    g, t0 = arcs(seed, shape=(6, 5), samples=samples)
    geom = ArcGeometry(g.lon_deg, g.lat_deg, g.course_deg, g.seg_nm)  # as Monte Carlo builds its legs: no end points
    east, north = rng.normal(0.0, sigma_ms, 6), rng.normal(0.0, sigma_ms, 6)
    w = PerturbedWind(weather(seed), east, north)
    kw = dict(departure=DEP, weather=w, polar=POLAR, failure=None if model is None else load_failure_model(model))
    got = geometry_costs(geom, t0, apf=0.5, **kw)
    want = numpy_path(geom, t0, apf=0.5, **kw)
    assert_same_costs(got, want)
    np.testing.assert_array_equal(got.marks_h, want.marks_h)
    # the error matters: without it the times differ
    plain = geometry_costs(geom, t0, apf=1.0, **{**kw, "weather": weather(seed)})
    again = geometry_costs(geom, t0, apf=1.0, **kw)
    both = np.isfinite(plain.time_h) & np.isfinite(again.time_h)
    assert both.any() and not np.array_equal(plain.time_h[both], again.time_h[both])


@pytest.mark.slow
@settings(max_examples=4, derandomize=True, deadline=None, database=None)
@given(st.integers(0, 2**31), st.integers(1, 3), st.sampled_from([None, "dickson2018"]))
def test_compiled_march_applies_each_runs_speed_noise_as_the_numpy_march(
    seed: int, samples: int, model: str | None
) -> None:
    """Monte Carlo's noisy boat (:class:`~pyroute_rel.boat.march.SpeedNoise`, one gain and spread per row) at every
    step: the compiled march gives the numpy march's costs and marks bit for bit; the noise changes the times; and in
    weather that does not change along an arc or in time, the noisy time is the noiseless one over the noise's factor on
    the speed (``v / v'``, with the floor), by hand."""
    from pyroute_rel.boat.march import SpeedNoise

    rng = np.random.default_rng(seed)
    geom, t0 = arcs(seed, shape=(6, 5), samples=samples)
    gain, eta = rng.uniform(0.3, 1.4, (6, 1)), rng.normal(0.0, 2.0, (6, 1))
    noise = SpeedNoise(gain=np.broadcast_to(gain, (6, 5)), spread=np.broadcast_to(np.sqrt(0.2 * gain) * eta, (6, 5)))
    kw = dict(
        departure=DEP, weather=weather(seed), polar=POLAR, failure=None if model is None else load_failure_model(model)
    )
    got = geometry_costs(geom, t0, apf=0.5, speed_noise=noise, **kw)
    want = numpy_path(geom, t0, apf=0.5, speed_noise=noise, **kw)
    assert_same_costs(got, want)
    np.testing.assert_array_equal(got.marks_h, want.marks_h)
    plain = geometry_costs(geom, t0, apf=1.0, **kw)
    again = geometry_costs(geom, t0, apf=1.0, speed_noise=noise, **kw)
    both = np.isfinite(plain.time_h) & np.isfinite(again.time_h)
    assert both.any() and not np.allclose(plain.time_h[both], again.time_h[both])
    # uniform steady wind: one speed v along every arc, so the time is the noiseless one times v / v'
    from pyroute_rel.weather import UniformWeather

    still = UniformWeather(tws_kn=12.0, twd_deg=30.0)
    one = arcs(seed, shape=(6, 5), samples=samples)[0]
    one = type(one)(
        one.lon_deg[..., :1].repeat(samples, -1),
        one.lat_deg[..., :1].repeat(samples, -1),
        one.course_deg[..., :1].repeat(samples, -1),
        one.seg_nm,
    )
    base = geometry_costs(one, t0, departure=DEP, weather=still, polar=POLAR)
    noisy = geometry_costs(one, t0, departure=DEP, weather=still, polar=POLAR, speed_noise=noise)
    sails = np.isfinite(base.time_h)  # (an arc in irons stays forbidden)
    assert sails.any()
    np.testing.assert_array_equal(np.isfinite(noisy.time_h), sails)
    v = one.seg_nm[..., 0] * samples / base.time_h
    v_noisy = np.maximum(gain * v + np.sqrt(0.2 * gain) * eta * np.sqrt(v), 0.1 * v)
    np.testing.assert_allclose(noisy.time_h[sails], (base.time_h * v / v_noisy)[sails], rtol=1e-12)


@pytest.mark.slow
@settings(max_examples=8, derandomize=True, deadline=None, database=None)
@given(st.integers(0, 2**31), st.integers(1, 3), st.sampled_from([None, "dickson2018"]))
def test_compiled_march_sails_rows_in_stacked_members_as_the_numpy_march(
    seed: int, samples: int, model: str | None
) -> None:
    """Rows of a query answered by different members of an ensemble, stacked (how ``sail_in_members`` sails every
    track in every member): the compiled march reads each row in its member's data and gives the numpy march's
    costs, each row those of its member alone."""
    from pyroute_rel.analysis.evaluate import _MemberRows
    from pyroute_rel.routing.cost import ArcGeometry

    members = [weather(seed + m) for m in range(3)]
    g, t0 = arcs(seed, shape=(6, 5), samples=samples)
    flat = [a.reshape(30, -1) for a in (g.lon_deg, g.lat_deg, g.course_deg)]
    geom = ArcGeometry(*flat, g.seg_nm.reshape(30, 1))
    t0 = t0.reshape(30)
    of = np.repeat(np.arange(3), 10)  # rows 0-9 in member 0, 10-19 in member 1, ...
    rows = _MemberRows(members, np.array([0, 10, 20, 30]), (stack_members(members), of))
    kw = dict(departure=DEP, polar=POLAR, failure=None if model is None else load_failure_model(model), apf=0.5)
    import pyroute_rel._kernels.march as march_compiled

    calls = []
    with pytest.MonkeyPatch.context() as mp:  # the compiled march does sail them
        kernel = march_compiled.march_gridded
        mp.setattr(march_compiled, "march_gridded", lambda *a, **k: calls.append(1) or kernel(*a, **k))
        got = geometry_costs(geom, t0, weather=rows, **kw)
    assert calls
    want = numpy_path(geom, t0, weather=rows, **kw)
    assert_same_costs(got, want)
    np.testing.assert_array_equal(got.marks_h, want.marks_h)
    for m in range(3):  # and each row is its member's own
        part = slice(10 * m, 10 * (m + 1))
        one = ArcGeometry(*(a[part] for a in flat), geom.seg_nm[part])
        alone = geometry_costs(one, t0[part], weather=members[m], **kw)
        np.testing.assert_array_equal(got.time_h[part], alone.time_h)


def test_rows_of_a_perturbed_source_stay_whole_when_blocks_are_split_between_threads(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """A block whose rows are runs (Monte Carlo's wind errors) is never split between threads (each part would get
    every run's errors); with all errors 0 the compiled march reads the wrapped source directly."""
    import pyroute_rel._kernels.march as march_compiled
    from pyroute_rel.analysis.monte_carlo import PerturbedWind
    from pyroute_rel.routing.cost import ArcGeometry

    monkeypatch.setattr(cost_module, "PARALLEL_MIN_MARCHED", 1)
    g, t0 = arcs(3, shape=(6, 5), samples=2)
    geom = ArcGeometry(g.lon_deg, g.lat_deg, g.course_deg, g.seg_nm)
    w = PerturbedWind(weather(3), np.linspace(-3.0, 3.0, 6), np.linspace(2.0, -2.0, 6))
    kw = dict(departure=DEP, weather=w, polar=POLAR, failure=MODEL, apf=0.5)
    assert_same_costs(geometry_costs(geom, t0, workers=2, **kw), geometry_costs(geom, t0, workers=1, **kw))
    calls = []
    kernel = march_compiled.march_gridded
    monkeypatch.setattr(march_compiled, "march_gridded", lambda *a, **k: calls.append(1) or kernel(*a, **k))
    still = PerturbedWind(weather(3), np.zeros(6), np.zeros(6))
    got = geometry_costs(geom, t0, workers=1, **{**kw, "weather": still})
    assert calls  # compiled
    assert_same_costs(got, geometry_costs(geom, t0, workers=1, **{**kw, "weather": weather(3)}))
