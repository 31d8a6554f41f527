"""GriddedWeather (pyroute_rel.weather.gridded): interpolation in space and time against hand-computed values,
prepared sampling, coverage, and the WeatherSource protocol.

Values are stored as float32: every value and weight below is a small binary fraction, so the hand-computed
bilinear and linear values are exact and compared exactly.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pyroute_rel.errors import WeatherCoverageError, WeatherError
from pyroute_rel.units import KN_PER_MS
from pyroute_rel.weather import FIELDS, GriddedWeather, WeatherField, WeatherSource

T0 = np.datetime64("2018-06-01T00:00", "ns")
HOUR = np.timedelta64(3600, "s")
LON = np.array([-20.0, -19.0, -18.0])
LAT = np.array([40.0, 41.0])
TIME = T0 + np.arange(3) * 6 * HOUR  # 00, 06, 12 UTC


def field(name: str, values: np.ndarray, *, time: np.ndarray | None = TIME) -> WeatherField:
    return WeatherField(name, np.asarray(values, dtype=np.float32), LON, LAT, time, source="test", variable=name)


def calm(*, time: np.ndarray | None = TIME) -> list[WeatherField]:
    nt = 1 if time is None else time.size
    zero = np.zeros((nt, LAT.size, LON.size))
    return [field("wind_u_ms", zero, time=time), field("wind_v_ms", zero, time=time)]


def test_bilinear_in_space() -> None:
    # hs [m] at (lat, lon): a plane would interpolate exactly anyhow; this one is not a plane
    hs = np.array([[1.0, 2.0, 4.0], [3.0, 8.0, 0.5]])[None]
    w = GriddedWeather([*calm(time=None), field("hs_m", hs, time=None)])
    # (lon -19.75, lat 40.5): a quarter of the way from -20 to -19, half way from 40 to 41
    expected = 0.75 * 0.5 * 1.0 + 0.25 * 0.5 * 2.0 + 0.75 * 0.5 * 3.0 + 0.25 * 0.5 * 8.0
    got = w.sample([-19.75, -18.5], [40.5, 40.25], T0).hs_m
    assert got[0] == expected
    assert got[1] == 0.5 * 0.75 * 2.0 + 0.5 * 0.75 * 4.0 + 0.5 * 0.25 * 8.0 + 0.5 * 0.25 * 0.5


def test_linear_in_time() -> None:
    hs = np.stack([np.full((2, 3), v) for v in (1.0, 3.0, 2.0)])
    w = GriddedWeather([*calm(), field("hs_m", hs)])
    times = T0 + np.array([0, 90, 360, 540, 720], dtype="timedelta64[m]")  # 0, 1.5, 6, 9, 12 h
    got = w.sample(-19.5, 40.5, times).hs_m
    np.testing.assert_array_equal(got, [1.0, 1.5, 3.0, 2.5, 2.0])
    # past the last time or before the first: NaN (no extrapolation)
    assert np.isnan(w.sample(-19.5, 40.5, [T0 - HOUR, TIME[-1] + HOUR]).hs_m).all()


def test_wind_speed_and_direction_from_components() -> None:
    nt = TIME.size
    u = np.full((nt, 2, 3), -3.0)
    v = np.full((nt, 2, 3), -4.0)  # blowing to the south-west, so from the north-east
    w = GriddedWeather([field("wind_u_ms", u), field("wind_v_ms", v)])
    c = w.sample(-19.2, 40.7, T0 + 2 * HOUR)
    assert float(c.tws_kn) == pytest.approx(5.0 * KN_PER_MS, rel=1e-15)
    assert float(c.twd_deg) == pytest.approx(math.degrees(math.atan2(3.0, 4.0)), abs=1e-12)
    # no waves in the data: NaN; no current: 0
    assert np.isnan(c.hs_m) and np.isnan(c.wave_dir_deg) and c.current_u_ms == 0.0 and c.current_v_ms == 0.0


def test_wave_direction_interpolates_across_north() -> None:
    d = np.array([[350.0, 10.0, 10.0], [350.0, 10.0, 10.0]])[None]
    w = GriddedWeather([*calm(time=None), field("wave_dir_deg", d, time=None), field("hs_m", d * 0 + 1, time=None)])
    got = float(w.sample(-19.5, 40.5, T0).wave_dir_deg)
    assert abs((got + 180.0) % 360.0 - 180.0) < 1e-5  # north, not 180


def test_prepared_sampling_equals_sample() -> None:
    rng = np.random.default_rng(3)
    nt = TIME.size
    fields = [
        field("wind_u_ms", rng.normal(0, 5, (nt, 2, 3))),
        field("wind_v_ms", rng.normal(0, 5, (nt, 2, 3))),
        field("hs_m", rng.uniform(0, 4, (nt, 2, 3))),
        field("current_u_ms", rng.normal(0, 0.3, (nt, 2, 3))),
        field("current_v_ms", rng.normal(0, 0.3, (nt, 2, 3))),
    ]
    w = GriddedWeather(fields)
    lon = rng.uniform(-20.5, -17.5, (4, 5))  # some outside: NaN either way
    lat = rng.uniform(39.8, 41.2, (4, 5))
    offset_h = rng.uniform(-1.0, 13.0, (4, 5))
    times = T0 + (offset_h * 3600e9).astype("timedelta64[ns]")
    direct = w.sample(lon, lat, times)
    points = w.prepare(lon, lat)
    same_times, offsets = w.sample_at(points, times), w.sample_at(points, T0, offset_h=offset_h)
    for name in FIELDS:
        np.testing.assert_array_equal(getattr(same_times, name), getattr(direct, name))
        # offsets [h] are not the nanosecond-rounded times: equal to rounding
        np.testing.assert_allclose(getattr(offsets, name), getattr(direct, name), rtol=1e-12, atol=1e-12)
    timing = w.sample_at(points, T0, offset_h=offset_h, fields=("tws_kn", "twd_deg"))
    np.testing.assert_array_equal(timing.tws_kn, w.sample_at(points, T0, offset_h=offset_h).tws_kn)
    assert np.isnan(timing.hs_m).all()  # not asked for: not interpolated
    other = GriddedWeather(fields)
    with pytest.raises(WeatherError, match="prepared for another weather source"):
        other.sample_at(points, T0)


def test_coverage_errors_name_what_is_missing() -> None:
    w = GriddedWeather(calm())
    w.check_coverage((-20.0, -18.0), (40.0, 41.0), (TIME[0], TIME[-1]))  # exactly covered
    for lon, lat, times, short in (
        ((-21.0, -18.0), (40.0, 41.0), (TIME[0], TIME[-1]), r"\(lon not covered\)"),
        ((-20.0, -18.0), (39.0, 41.0), (TIME[0], TIME[-1]), r"\(lat not covered\)"),
        ((-20.0, -18.0), (40.0, 41.0), (TIME[0], TIME[-1] + HOUR), r"\(time not covered\)"),
        ((-21.0, -18.0), (40.0, 42.0), (TIME[0], TIME[-1]), r"\(lon and lat not covered\)"),
    ):
        with pytest.raises(WeatherCoverageError, match=short):
            w.check_coverage(lon, lat, times)
    # the same longitudes written 0..360 are covered
    w.check_coverage((340.0, 342.0), (40.0, 41.0), (TIME[0], TIME[-1]))
    # outside the data, sampling gives NaN rather than an error
    assert np.isnan(w.sample(-25.0, 40.5, T0).tws_kn)


def test_protocol_members_and_currents_come_in_pairs() -> None:
    w = GriddedWeather(calm())
    assert isinstance(w, WeatherSource) and w.steady is False
    assert w.fields == {"tws_kn", "twd_deg"} and w.max_current_ms == 0.0
    zero = np.zeros((TIME.size, 2, 3))
    with pytest.raises(WeatherError, match="currents need both components"):
        GriddedWeather([*calm(), field("current_u_ms", zero + 1.0)])
    both = GriddedWeather([*calm(), field("current_u_ms", zero + 0.5), field("current_v_ms", zero - 1.0)])
    assert {"current_u_ms", "current_v_ms"} <= both.fields
    assert both.max_current_ms == pytest.approx(math.hypot(0.5, 1.0))
    # the cost kernel's question "stored currents?" asked of the protocol gives what field_info gave
    for source in (w, both):
        currents = {"current_u_ms", "current_v_ms"}
        assert (currents & source.fields) == (currents & set(source.field_info))


@settings(max_examples=40, deadline=None)
@given(
    values=st.lists(st.floats(-50.0, 50.0, width=32), min_size=18, max_size=18),
    i=st.integers(0, 2),
    j=st.integers(0, 1),
    t=st.integers(0, 2),
)
def test_sampling_at_grid_nodes_returns_the_node_values(values: list[float], i: int, j: int, t: int) -> None:
    hs = 0.5 * np.abs(np.asarray(values).reshape(3, 2, 3))  # in [0, 25] m: plausible (RANGES: [0, 30] m)
    u = np.asarray(values).reshape(3, 2, 3)
    w = GriddedWeather([field("wind_u_ms", u), field("wind_v_ms", u[::-1]), field("hs_m", hs)])
    assert float(w.sample(LON[i], LAT[j], TIME[t]).hs_m) == float(np.float32(hs[t, j, i]))
    assert float(w.interpolate("wind_u_ms", LON[i], LAT[j], TIME[t])) == float(np.float32(u[t, j, i]))
    prepared = w.prepare(LON[i], LAT[j])
    assert float(w.sample_at(prepared, TIME[t]).hs_m) == float(np.float32(hs[t, j, i]))
