"""Arc cost (Algorithm 1): analytical cases for currents, wave speed loss, missing weather and the apf rule."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pyproj import Geod  # at import: pyproj loaded after cfgrib/ecCodes cannot find its database (a warning)

from pyroute_rel import geodesy
from pyroute_rel.boat.polar import Polar, get_polar
from pyroute_rel.reliability.failure import load_failure_model
from pyroute_rel.routing.cost import REASONS, WaveLoss, arc_costs, arc_geometry
from pyroute_rel.units import KN_PER_MS
from pyroute_rel.weather import UniformWeather
from pyroute_rel.weather.io.readers import weather_from_dataset

DEP = np.datetime64("2018-06-01T00:00")
# a flat polar: 5 kn at every TWA from 30 deg and every TWS from 4 kn (so speed does not depend on heading)
FLAT = Polar(
    name="flat",
    twa_deg=np.array([0.0, 29.9, 30.0, 180.0]),
    tws_kn=np.array([0.0, 4.0, 40.0]),
    speed_kn=np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 5.0, 5.0], [0.0, 5.0, 5.0]]),
)
EAST = (0.0, 0.0, 1.0, 0.0)  # one degree of the equator, course 090
DIST_NM = float(geodesy.distance_nm(*EAST))


def cost(weather, polar=FLAT, **kw):
    return arc_costs(*EAST, 0.0, departure=DEP, weather=weather, polar=polar, **kw)


def test_no_current_is_distance_over_polar_speed() -> None:
    c = cost(UniformWeather(tws_kn=12.0, twd_deg=0.0))
    assert float(c.time_h) == pytest.approx(DIST_NM / 5.0, rel=1e-12)
    assert int(c.reason) == 0 and float(c.p_f) == 0.0


@pytest.mark.parametrize("u_ms", [0.5, -0.5, 1.5])
def test_current_along_the_course_adds_to_speed(u_ms: float) -> None:
    c = cost(UniformWeather(tws_kn=12.0, twd_deg=0.0, current_u_ms=u_ms))
    assert float(c.time_h) == pytest.approx(DIST_NM / (5.0 + u_ms * KN_PER_MS), rel=1e-9)


@pytest.mark.parametrize("v_ms", [0.5, -1.0, 2.0])
def test_cross_current_needs_a_crab_angle(v_ms: float) -> None:
    # the boat heads into the cross current so that its track stays on the arc: sog = sqrt(5^2 - c^2)
    c_kn = v_ms * KN_PER_MS
    c = cost(UniformWeather(tws_kn=12.0, twd_deg=0.0, current_v_ms=v_ms))
    assert float(c.time_h) == pytest.approx(DIST_NM / np.sqrt(25.0 - c_kn**2), rel=1e-9)


def test_current_too_strong_forbids_the_arc() -> None:
    cross = cost(UniformWeather(tws_kn=12.0, twd_deg=0.0, current_v_ms=3.0))  # 5.8 kn across > 5 kn
    head = cost(UniformWeather(tws_kn=12.0, twd_deg=0.0, current_u_ms=-3.0))  # 5.8 kn on the nose
    for c in (cross, head):
        assert np.isinf(c.time_h) and int(c.reason) & REASONS["current"]


def test_wave_speed_loss_scales_speed() -> None:
    loss = WaveLoss(hs_m=(0.0, 2.0, 6.0), factor=(1.0, 0.8, 0.2))
    c = cost(UniformWeather(tws_kn=12.0, twd_deg=0.0, hs_m=4.0), wave_loss=loss)
    assert float(c.time_h) == pytest.approx(DIST_NM / (5.0 * 0.5), rel=1e-12)  # factor 0.8 -> 0.2 halfway: 0.5
    with pytest.raises(ValueError, match="start at 0"):
        WaveLoss(hs_m=(1.0, 2.0), factor=(1.0, 0.5))


def test_missing_weather_is_forbidden_never_calm() -> None:
    class NaNWind(UniformWeather):
        def sample(self, lon_deg, lat_deg, time):
            c = super().sample(lon_deg, lat_deg, time)
            c.tws_kn[...] = np.nan
            return c

    c = cost(NaNWind(tws_kn=12.0, twd_deg=0.0))
    assert np.isinf(c.time_h) and int(c.reason) & REASONS["weather"]


def test_apf_rule_is_p_f_greater_than_apf() -> None:
    # dickson2018, Table 1: 4 m waves alone (from the north, beam seas on an eastward course) -> p_f = 0.9
    model = load_failure_model("dickson2018")
    w = UniformWeather(tws_kn=12.0, twd_deg=0.0, hs_m=4.0, wave_dir_deg=0.0)
    polar = get_polar("maribot_vane")
    at = cost(w, polar=polar, failure=model, apf=0.9)
    below = cost(w, polar=polar, failure=model, apf=0.89)
    assert float(at.p_f) == pytest.approx(0.9) and np.isfinite(at.time_h) and int(at.reason) == 0
    assert np.isinf(below.time_h) and int(below.reason) == REASONS["failure"]
    # head seas too (waves from 090 on a 090 course): both criteria, p_f = 1.0, forbidden below apf 1
    both = cost(
        UniformWeather(tws_kn=12.0, twd_deg=0.0, hs_m=4.0, wave_dir_deg=90.0), polar=polar, failure=model, apf=0.95
    )
    assert float(both.p_f) == pytest.approx(1.0) and np.isinf(both.time_h)
    assert np.isfinite(cost(w, polar=polar, failure=model, apf=1.0).time_h)


def test_arc_p_f_is_the_worst_along_it_whatever_the_samples() -> None:
    from pyroute_rel.weather import Patch

    model = load_failure_model("dickson2018")
    # 4 m waves on the eastern quarter of the arc only: one sample of four sees them, and the midpoint alone
    # misses them, but the arc is judged on every piece it crosses (pyroute_rel.reliability.crossings)
    w = UniformWeather(
        tws_kn=12.0, twd_deg=0.0, hs_m=1.0, patches=(Patch(lon=(0.75, 2.0), lat=(-1.0, 1.0), values={"hs_m": 4.0}),)
    )
    assert float(cost(w, failure=model, samples=4).p_f) == pytest.approx(0.9)
    assert float(cost(w, failure=model, samples=1).p_f) == pytest.approx(0.9)


def test_wave_speed_loss_from_a_scenario() -> None:
    from pyroute_rel.errors import ScenarioError
    from pyroute_rel.scenario import scenario_from_mapping

    base = {
        "route": {"start": [-12.0, 45.0], "finish": [-20.0, 40.0]},
        "weather": {"kind": "uniform", "tws_kn": 15.0, "twd_deg": 0.0, "hs_m": 2.0},
    }
    sc = scenario_from_mapping({**base, "boat": {"wave_speed_loss": [[0.0, 1.0], [4.0, 0.6]]}})
    assert sc.wave_loss is not None and float(sc.wave_loss.factor(2.0)) == pytest.approx(0.8)
    with pytest.raises(ScenarioError, match=r"\[boat\].wave_speed_loss"):
        scenario_from_mapping({**base, "boat": {"wave_speed_loss": [[0.0, 1.0], [4.0, 1.5]]}})


@pytest.mark.slow
def test_forbidden_arcs_record_which_criteria_fired() -> None:
    from pyroute_rel.scenario import load_scenario

    sc = load_scenario("examples/microtransat_control.toml").with_options(n_ranks=40, land=False)
    strict = sc.with_options(apf=0.95).route()
    n_fail = strict.dp.forbidden_by_reason["failure"]
    assert n_fail > 0
    # Table 1: p_f > 0.95 only when both criteria fire, so every failure-forbidden arc has both
    assert strict.dp.forbidden_by_criterion == {"WH: hs_m >= 4 m": n_fail, "WD: awd_deg < 60 deg": n_fail}
    # at apf 0.5 one criterion is enough: each forbidden arc has at least one, and the counts add up to at least it
    loose = sc.with_options(apf=0.5).route()
    counts = loose.dp.forbidden_by_criterion
    n = loose.dp.forbidden_by_reason["failure"]
    assert max(counts.values()) <= n <= sum(counts.values())
    assert loose.summary()["arcs"]["forbidden_by_criterion"] == counts


def _varying_field():
    import xarray as xr

    lon = np.arange(-40.0, -19.9, 0.5)
    lat = np.arange(20.0, 40.1, 0.5)
    time = np.datetime64("2018-06-01T00") + np.arange(48) * np.timedelta64(1, "h")
    t, la, lo = np.meshgrid(np.arange(48.0), lat, lon, indexing="ij")
    speed = 6.0 + 3.0 * np.sin(t / 7.0 + lo / 5.0)
    frm = np.radians(40.0 * np.sin(t / 11.0 + la / 4.0))
    hs = 2.5 + 2.0 * np.cos(la / 3.0 + t / 9.0)  # in [0.5, 4.5] m: plausible (a negative height is refused)
    hs[:, 10:12, 20:23] = np.nan  # an island: arcs next to it are forbidden as missing weather
    dims = ("time", "latitude", "longitude")
    ds = xr.Dataset(
        {
            "u10": (dims, -speed * np.sin(frm)),
            "v10": (dims, -speed * np.cos(frm)),
            "swh": (dims, hs),
            "mwd": (dims, np.degrees(frm) % 360.0),
        },
        coords={"time": time, "latitude": lat, "longitude": lon},
    )
    return weather_from_dataset(ds)


def test_threads_split_a_block_without_changing_a_number() -> None:
    from pyroute_rel.routing.cost import PARALLEL_MIN_ARCS, arc_geometry, geometry_costs

    rng = np.random.default_rng(3)
    n_dst, width = 120, 90
    assert n_dst * width >= PARALLEL_MIN_ARCS  # precondition: the block is big enough to be split
    lon0, lat0 = rng.uniform(-39, -21, (1, width)), rng.uniform(21, 39, (1, width))
    lon1, lat1 = rng.uniform(-39, -21, (n_dst, 1)), rng.uniform(21, 39, (n_dst, 1))
    geom = arc_geometry(lon0, lat0, lon1, lat1, samples=3)
    t0 = rng.uniform(0.0, 20.0, (n_dst, width))
    kw = dict(
        departure=np.datetime64("2018-06-01T00:00"),
        weather=_varying_field(),
        polar=get_polar("maribot_vane"),
        failure=load_failure_model("dickson2018"),
        apf=0.5,
    )
    one = geometry_costs(geom, t0, workers=1, **kw)
    three = geometry_costs(geom, t0, workers=3, **kw)
    assert (one.reason & REASONS["failure"]).any() and (one.reason & REASONS["weather"]).any()
    assert np.isfinite(one.time_h).any()
    for name in ("time_h", "p_f", "reason", "fired_bits"):
        np.testing.assert_array_equal(getattr(three, name), getattr(one, name), err_msg=name)


@pytest.mark.parametrize("value", ["0", "two", "-1"])
def test_thread_count_from_the_environment_is_checked(monkeypatch, value) -> None:
    from pyroute_rel.resources import default_workers

    monkeypatch.setenv("PYROUTE_REL_THREADS", value)
    with pytest.raises(ValueError, match="PYROUTE_REL_THREADS must be a whole number >= 1"):
        default_workers()
    monkeypatch.setenv("PYROUTE_REL_THREADS", "3")
    assert default_workers() == 3


@pytest.mark.parametrize("samples", [1, 2, 3, 4, 5])
def test_arc_sample_points_and_courses_match_pyproj_on_the_sphere(samples) -> None:
    """Sample k of an arc lies (k + 0.5) / samples of the way along the great circle, its course is the azimuth
    to the arc's end there, and the sub-segments add up to the arc (pyproj's geodesics on a sphere of the same
    radius, an independent implementation; powers of two take the halving path, others slerp)."""
    rng = np.random.default_rng(samples)
    lon0, lon1 = rng.uniform(-180, 180, (2, 500))
    lat0, lat1 = rng.uniform(-80, 80, (2, 500))
    geo = arc_geometry(lon0, lat0, lon1, lat1, samples=samples)
    radius_m = geodesy.EARTH_RADIUS_KM * 1000.0
    g = Geod(a=radius_m, b=radius_m)
    az, _, dist_m = g.inv(lon0, lat0, lon1, lat1)
    np.testing.assert_allclose(geo.seg_nm[:, 0] * samples * 1852.0, dist_m, rtol=1e-12, atol=1e-6)
    for k in range(samples):
        lon, lat, _ = g.fwd(lon0, lat0, az, dist_m * (k + 0.5) / samples)
        course, _, _ = g.inv(lon, lat, lon1, lat1)
        np.testing.assert_allclose((geo.lon_deg[:, k] - lon + 180.0) % 360.0 - 180.0, 0.0, atol=1e-9)
        np.testing.assert_allclose(geo.lat_deg[:, k], lat, atol=1e-9)
        np.testing.assert_allclose((geo.course_deg[:, k] - course + 180.0) % 360.0 - 180.0, 0.0, atol=1e-9)


def test_arc_geometry_in_threads_is_the_same() -> None:
    from pyroute_rel.routing.cost import PARALLEL_MIN_ARCS, geometry_from_xyz

    rng = np.random.default_rng(5)
    a = geodesy.to_xyz(rng.uniform(-60, -10, (1, 150)), rng.uniform(10, 50, (1, 150)))
    b = geodesy.to_xyz(rng.uniform(-60, -10, (90, 1)), rng.uniform(10, 50, (90, 1)))
    assert 90 * 150 * 2 >= PARALLEL_MIN_ARCS
    one = geometry_from_xyz(a, b, samples=2, workers=1)
    three = geometry_from_xyz(a, b, samples=2, workers=3)
    for name in ("lon_deg", "lat_deg", "course_deg", "seg_nm"):
        np.testing.assert_array_equal(getattr(three, name), getattr(one, name), err_msg=name)
    assert one.lon_deg.shape == (90, 150, 2)


# a polar whose table starts above 0 kn and above 0 deg, so the light-air and no-go rules both apply
_OFFSET_POLAR = Polar(
    "offset",
    twa_deg=[35.0, 60.0, 90.0, 130.0, 165.0],
    tws_kn=[3.0, 8.0, 14.0, 22.0],
    speed_kn=[
        [0.5, 1.5, 2.5, 3.0],
        [1.0, 2.5, 3.5, 4.0],
        [1.2, 3.0, 4.2, 4.8],
        [1.0, 2.8, 4.0, 4.6],
        [0.6, 2.0, 3.2, 3.9],
    ],
)


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    polar_name=st.sampled_from(["maribot_vane", "offset"]),
    beyond=st.sampled_from(["clamp", "forbid"]),
)
def test_compiled_wind_kernel_is_bit_identical_to_numpy(seed, polar_name, beyond) -> None:
    """The compiled TWA, polar speed and sub-segment times (gridded weather, wind only) are exactly the numpy
    kernel's: inside and outside the polar table, on its nodes, in calm and missing wind."""
    from pyroute_rel._kernels.cost import sail_wind
    from pyroute_rel.boat.polar import boat_speed_kn
    from pyroute_rel.routing.cost import _sample_costs
    from pyroute_rel.weather import Conditions

    polar = _OFFSET_POLAR if polar_name == "offset" else get_polar(polar_name)
    rng = np.random.default_rng(seed)
    n = 4000
    tws = np.concatenate([rng.uniform(0.0, 30.0, n), rng.choice(polar.tws_kn, n), [0.0, np.nan, np.inf, 1e-9]])
    course = rng.uniform(0.0, 360.0, tws.size)
    twa_on_nodes = (course + rng.choice([-1.0, 1.0], tws.size) * rng.choice(polar.twa_deg, tws.size)) % 360.0
    twd = np.where(rng.random(tws.size) < 0.3, twa_on_nodes, rng.uniform(0.0, 360.0, tws.size))
    twd[rng.random(tws.size) < 0.01] = np.nan
    seg = rng.uniform(0.0, 40.0, tws.size)
    nan = np.full(tws.size, np.nan)
    cond = Conditions(
        tws_kn=tws,
        twd_deg=twd,
        hs_m=nan,
        wave_dir_deg=nan,
        wave_period_s=nan,
        current_u_ms=np.zeros(tws.size),
        current_v_ms=np.zeros(tws.size),
    )
    with np.errstate(invalid="ignore"):
        expected = _sample_costs(cond, course, seg, polar, None, 1.0, beyond)[0]
    twa, speed, dt = sail_wind(tws, twd, course, seg, polar, beyond=beyond)
    assert np.isinf(expected).any() and np.isfinite(expected).any()
    np.testing.assert_array_equal(dt, expected)
    np.testing.assert_array_equal(twa, geodesy.angle_diff_deg(twd, course))
    np.testing.assert_array_equal(speed, boat_speed_kn(polar, twa, tws, beyond=beyond))


@pytest.mark.parametrize("shape", [(7, 5, 4), (3, 1), (6,)])
def test_compiled_wind_kernel_per_arc_lengths_equal_broadcast_ones(shape) -> None:
    """Sub-segment lengths given once per arc (shape (..., 1), passed to the kernel without a copy) give the
    numbers of the same lengths broadcast to every sample, and non-contiguous or read-only inputs those of
    contiguous copies."""
    from pyroute_rel._kernels.cost import sail_wind

    polar = get_polar("maribot_vane")
    rng = np.random.default_rng(7)
    tws = rng.uniform(0.0, 30.0, shape)
    twd = rng.uniform(0.0, 360.0, shape)
    course = rng.uniform(0.0, 360.0, (2,) + shape)[1]  # a view of a bigger array
    seg = rng.uniform(0.0, 40.0, shape[:-1] + (1,))
    full = np.ascontiguousarray(np.broadcast_to(seg, shape))
    got = sail_wind(tws, np.broadcast_to(twd, shape), course, seg, polar)
    want = sail_wind(tws.copy(), twd.copy(), np.ascontiguousarray(course), full, polar)
    for g, w in zip(got, want, strict=True):
        assert g.shape == shape
        np.testing.assert_array_equal(g, w)
    # and the numpy kernel's times with the broadcast lengths
    from pyroute_rel.routing.cost import _sample_costs
    from pyroute_rel.weather import Conditions

    nan, zero = np.full(shape, np.nan), np.zeros(shape)
    cond = Conditions(
        tws_kn=tws, twd_deg=twd, hs_m=nan, wave_dir_deg=nan, wave_period_s=nan, current_u_ms=zero, current_v_ms=zero
    )
    np.testing.assert_array_equal(got[2], _sample_costs(cond, course, full, polar, None, 1.0, "clamp")[0])


@pytest.mark.parametrize("current", [(0.0, 0.0), (0.4, -0.3)])
@pytest.mark.parametrize("wave_loss", [None, WaveLoss(hs_m=(0.0, 2.0, 6.0), factor=(1.0, 0.9, 0.3))])
def test_gridded_uniform_field_costs_like_the_uniform_source(current, wave_loss) -> None:
    """A time-varying gridded file holding a uniform field gives the arc costs of UniformWeather (the march of
    pyroute_rel.boat.march over a field constant in time is the steady cost), with and without a current or wave
    loss."""
    import xarray as xr

    from pyroute_rel.routing.cost import geometry_costs

    tws_kn, twd, hs, wdir = 13.0, 70.0, 2.5, 250.0
    uniform = UniformWeather(
        tws_kn=tws_kn, twd_deg=twd, hs_m=hs, wave_dir_deg=wdir, current_u_ms=current[0], current_v_ms=current[1]
    )
    lon, lat = np.arange(-45.0, -14.0, 1.0), np.arange(20.0, 41.0, 1.0)
    time = np.datetime64("2018-06-01T00") + np.arange(0, 2000, 6) * np.timedelta64(1, "h")  # outlasts every arc
    ms = tws_kn / KN_PER_MS
    full = np.ones((time.size, lat.size, lon.size))
    dims = ("time", "latitude", "longitude")
    data = {
        "u10": (dims, -ms * np.sin(np.radians(twd)) * full),
        "v10": (dims, -ms * np.cos(np.radians(twd)) * full),
        "swh": (dims, hs * full),
        "mwd": (dims, wdir * full),
    }
    if current != (0.0, 0.0):
        data.update(uo=(dims, current[0] * full), vo=(dims, current[1] * full))
    gridded = weather_from_dataset(xr.Dataset(data, coords={"time": time, "latitude": lat, "longitude": lon}))
    rng = np.random.default_rng(11)
    geom = arc_geometry(
        rng.uniform(-40, -20, (1, 60)),
        rng.uniform(25, 35, (1, 60)),
        rng.uniform(-40, -20, (50, 1)),
        rng.uniform(25, 35, (50, 1)),
        samples=2,
    )
    t0 = rng.uniform(0.0, 30.0, (50, 60))
    kw = dict(
        departure=np.datetime64("2018-06-01T00:00"),
        polar=get_polar("maribot_vane"),
        failure=load_failure_model("dickson2018"),
        apf=0.5,
        wave_loss=wave_loss,
        workers=1,
    )
    got = geometry_costs(geom, t0, weather=gridded, **kw)
    ref = geometry_costs(geom, t0, weather=uniform, **kw)
    assert np.isfinite(ref.time_h).any() and (ref.reason != 0).any()  # both allowed and forbidden arcs
    # arcs sailed so slowly that the craft is still on them after the file's last time (1998 h) meet missing weather
    # there, as they should
    end_h = t0 + ref.time_h
    late = np.isfinite(ref.time_h) & (end_h > 1998.0 + 1e-6)
    assert np.all(got.reason[late] & REASONS["weather"])
    ok = ~np.isfinite(ref.time_h) | (end_h < 1998.0 - 1e-6)
    np.testing.assert_array_equal(got.reason[ok], ref.reason[ok])
    np.testing.assert_allclose(got.time_h[ok], ref.time_h[ok], rtol=1e-6)
    np.testing.assert_allclose(got.p_f[ok], ref.p_f[ok], atol=1e-9)


def test_arc_costs_refuses_samples_and_apf_it_cannot_use() -> None:
    from pyroute_rel.boat.polar import get_polar
    from pyroute_rel.errors import ScenarioError
    from pyroute_rel.routing.cost import arc_costs, arc_geometry
    from pyroute_rel.weather import UniformWeather

    kw = {
        "departure": np.datetime64("2018-06-01T00:00"),
        "weather": UniformWeather(tws_kn=12.0, twd_deg=0.0),
        "polar": get_polar("maribot_vane"),
    }
    with pytest.raises(ScenarioError, match=r"samples must be a whole number >= 1"):
        arc_costs(0.0, 0.0, 1.0, 0.0, 0.0, samples=0, **kw)  # was time inf with reason 0 ("ok")
    with pytest.raises(ScenarioError, match=r"samples must be a whole number >= 1"):
        arc_geometry(0.0, 0.0, 2.0, 0.0, samples=-1)  # was empty arrays and a negative length
    with pytest.raises(ScenarioError, match=r"apf must be a probability in \[0, 1\] \(got nan\)"):
        arc_costs(0.0, 0.0, 1.0, 0.0, 0.0, apf=float("nan"), **kw)
