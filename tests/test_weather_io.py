"""Tests of pyroute_rel.weather.io.readers: readers, normalisation, trilinear sampling, coverage, scenario hook.

Every dataset is built in tmp_path with xarray (or eccodes for GRIB); nothing touches the network.
Independent references: scipy's RegularGridInterpolator, the same data in other layouts, analytical
direction conventions, and unit definitions (1 kn = 1852 m / 3600 s, exact by definition).
"""

from __future__ import annotations

import importlib.util
import re
import sys
import tomllib
import warnings
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.interpolate import RegularGridInterpolator

from pyroute_rel.errors import ScenarioError, WeatherCoverageError, WeatherError, WeatherWarning
from pyroute_rel.units import KN_PER_MS
from pyroute_rel.weather import WeatherSource
from pyroute_rel.weather.io.readers import open_weather, weather_from_dataset, weather_from_mapping

KN = 1852.0 / 3600.0  # [m/s] per knot, exact by definition (international nautical mile)
T0 = np.datetime64("2018-06-01T00:00", "ns")
HOUR = np.timedelta64(3600, "s")
EXAMPLES = Path(__file__).resolve().parents[1] / "examples"

#: A wind component's units attribute (a file without one is read as m/s with a warning).
MS = {"units": "m s**-1"}


def era5(fields, lon, lat, time, *, time_name="time", attrs=None, coords=None):
    """An ERA5-layout dataset: variables on (time, latitude, longitude)."""
    attrs = attrs or {}
    default = {"u10": "m s**-1", "v10": "m s**-1", "swh": "m", "mwd": "Degree true", "pp1d": "s"}
    data = {
        name: ((time_name, "latitude", "longitude"), np.asarray(v, dtype=np.float32),
               attrs.get(name, {"units": default.get(name, "m")}))
        for name, v in fields.items()
    }  # fmt: skip
    return xr.Dataset(data, coords={time_name: time, "latitude": lat, "longitude": lon, **(coords or {})})


def uniform(shape, value):
    return np.full(shape, value, dtype=np.float32)


def angle_diff(a, b):
    return np.abs((np.asarray(a) - np.asarray(b) + 180.0) % 360.0 - 180.0)


def times(n, step_h=6):
    return T0 + np.arange(n) * step_h * HOUR


# ---------------------------------------------------------------------------------------- (a) layouts


@pytest.mark.parametrize("lon_convention", ["0..360", "-180..180"])
@pytest.mark.parametrize("lat_order", ["descending", "ascending"])
def test_uniform_field_in_every_layout(tmp_path, lon_convention, lat_order):
    lon = np.arange(0.0, 360.0, 1.0) if lon_convention == "0..360" else np.arange(-180.0, 180.0, 1.0)
    lat = np.arange(90.0, -90.5, -1.0) if lat_order == "descending" else np.arange(-90.0, 90.5, 1.0)
    time = times(4)
    shape = (time.size, lat.size, lon.size)
    # 15 kn from the north: the air moves south, u = 0, v = -15 kn in m/s
    ds = era5({"u10": uniform(shape, 0.0), "v10": uniform(shape, -15.0 * KN)}, lon, lat, time)
    ds.to_netcdf(tmp_path / "w.nc")
    w = open_weather(tmp_path / "w.nc")
    assert isinstance(w, WeatherSource)
    rng = np.random.default_rng(1)
    plon = np.concatenate([rng.uniform(-180, 180, 500), [-180.0, 179.5, 179.99, -179.99, 0.0, 359.0]])
    plat = np.concatenate([rng.uniform(-90, 90, 500), [90.0, -90.0, 0.0, 45.0, 0.0, 10.0]])
    ptime = T0 + (rng.uniform(0, 18, plon.size) * 3600e9).astype("timedelta64[ns]")
    c = w.sample(plon, plat, ptime)
    np.testing.assert_allclose(c.tws_kn, 15.0, rtol=1e-6)  # float32 storage of v: 6e-8 relative
    assert angle_diff(c.twd_deg, 0.0).max() < 1e-9
    assert np.all((c.twd_deg >= 0.0) & (c.twd_deg < 360.0))
    info = w.field_info["wind_v_ms"]
    assert np.all(np.diff(info.lat) > 0) and np.all(np.diff(info.lon) > 0)
    assert info.lat[0] == -90.0 and info.lat[-1] == 90.0
    assert info.periodic and info.lon[0] == -181.0 and info.lon[1] == -180.0 and info.lon[-1] == 180.0


def _canonical_random_field(seed=3):
    lon = np.arange(-180.0, 180.0, 5.0)
    lat = np.arange(-90.0, 90.1, 5.0)
    time = times(3)
    rng = np.random.default_rng(seed)
    u = rng.normal(size=(time.size, lat.size, lon.size)).astype(np.float32)
    v = rng.normal(size=(time.size, lat.size, lon.size)).astype(np.float32)
    return lon, lat, time, u, v


def test_layouts_give_identical_samples():
    """The same data as 0..360 / -180..180 and descending / ascending latitude sample identically."""
    lon, lat, time, u, v = _canonical_random_field()
    reference = weather_from_dataset(era5({"u10": u, "v10": v}, lon, lat, time))
    rng = np.random.default_rng(4)
    plon, plat = rng.uniform(-180, 180, 2000), rng.uniform(-90, 90, 2000)
    ptime = T0 + (rng.uniform(0, 12, 2000) * 3600e9).astype("timedelta64[ns]")
    expected = reference.sample(plon, plat, ptime)
    roll = lon.size // 2  # 0..355: longitudes 0..175 then 180..355 (= -180..-5)
    lon360 = np.roll(lon, -roll) % 360.0
    for lon_file, lat_file, uu, vv in [
        (lon360, lat, np.roll(u, -roll, axis=2), np.roll(v, -roll, axis=2)),
        (lon, lat[::-1], u[:, ::-1], v[:, ::-1]),
        (lon360, lat[::-1], np.roll(u, -roll, axis=2)[:, ::-1], np.roll(v, -roll, axis=2)[:, ::-1]),
    ]:
        other = weather_from_dataset(era5({"u10": uu, "v10": vv}, lon_file, lat_file, time))
        got = other.sample(plon, plat, ptime)
        np.testing.assert_allclose(got.tws_kn, expected.tws_kn, rtol=1e-12)
        assert angle_diff(got.twd_deg, expected.twd_deg).max() < 1e-9


# -------------------------------------------------------------------------- (b) trilinear interpolation


def _irregular():
    rng = np.random.default_rng(7)
    lon = np.sort(rng.choice(np.arange(-70.0, 0.01, 0.25), 23, replace=False))
    lat = np.sort(rng.choice(np.arange(5.0, 55.01, 0.25), 19, replace=False))[::-1]  # stored descending
    hours = np.sort(rng.choice(np.arange(0, 240, 1), 9, replace=False)).astype(float)
    time = T0 + (hours * 3600).astype("timedelta64[s]")
    shape = (hours.size, lat.size, lon.size)
    # wind 8 m/s and currents 2 m/s typical: inside their plausible ranges (weather.base.RANGES)
    scales = {"u10": 8.0, "v10": 8.0, "uo": 2.0, "vo": 2.0}
    fields = {k: rng.normal(scale=scale, size=shape).astype(np.float32) for k, scale in scales.items()}
    ds = era5(fields, lon, lat, time, attrs={"uo": {"units": "m s-1"}, "vo": {"units": "m s-1"}})
    return weather_from_dataset(ds), lon, lat, hours, fields


IRREGULAR = _irregular()


@pytest.mark.slow
@settings(max_examples=40, deadline=None)
@given(
    st.lists(
        st.tuples(
            st.one_of(st.floats(-70.0, 0.0), st.sampled_from(IRREGULAR[1].tolist())),
            st.one_of(st.floats(5.0, 55.0), st.sampled_from(IRREGULAR[2].tolist())),
            st.one_of(st.floats(0.0, 1.0), st.sampled_from([0.0, 1.0])),
        ),
        min_size=1,
        max_size=50,
    )
)
def test_trilinear_matches_scipy_regular_grid_interpolator(points):
    w, lon, lat, hours, fields = IRREGULAR
    p = np.array(points)
    plon = np.clip(p[:, 0], lon[0], lon[-1])
    plat = np.clip(p[:, 1], lat.min(), lat.max())
    phours = hours[0] + p[:, 2] * (hours[-1] - hours[0])
    ptime = T0 + np.round(phours * 3600e9).astype("timedelta64[ns]")
    exact_hours = (ptime - T0) / np.timedelta64(1, "h")
    xi = np.column_stack([exact_hours, plat, plon])
    ref = {
        k: RegularGridInterpolator((hours, lat[::-1], lon), v[:, ::-1].astype(np.float64))(xi)
        for k, v in fields.items()
    }
    np.testing.assert_allclose(w.interpolate("wind_u_ms", plon, plat, ptime), ref["u10"], rtol=0, atol=1e-11)
    np.testing.assert_allclose(w.interpolate("wind_v_ms", plon, plat, ptime), ref["v10"], rtol=0, atol=1e-11)
    c = w.sample(plon, plat, ptime)
    np.testing.assert_allclose(c.current_u_ms, ref["uo"], rtol=0, atol=1e-11)
    np.testing.assert_allclose(c.current_v_ms, ref["vo"], rtol=0, atol=1e-11)
    np.testing.assert_allclose(c.tws_kn, np.hypot(ref["u10"], ref["v10"]) / KN, rtol=1e-10)


@settings(max_examples=60, deadline=None)
@given(
    st.floats(-180.0, 180.0),
    st.sampled_from([0.1, 0.25, 0.3, 1.0 / 3.0, 0.5, 2.5, 3600.0]),
    st.integers(3, 400),
    st.integers(0, 2**32 - 1),
)
def test_cell_search_equals_binary_search(origin, step, n, seed):
    """The arithmetic cell search of regular axes gives the same cells as np.searchsorted, also at nodes +- 1 ulp."""
    from pyroute_rel.weather.gridded import _locate  # private kernel: the index arithmetic under test

    axis = origin + step * np.arange(n)
    rng = np.random.default_rng(seed)
    x = np.concatenate(
        [
            axis,
            np.nextafter(axis, -np.inf),
            np.nextafter(axis, np.inf),
            rng.uniform(axis[0] - step, axis[-1] + step, 500),
        ]
    )
    i, w, stride, ok = _locate(axis, x, 7)
    ref = np.clip(np.searchsorted(axis, x, side="right") - 1, 0, n - 1)
    np.testing.assert_array_equal(i, ref)
    np.testing.assert_array_equal(ok, (x >= axis[0]) & (x <= axis[-1]))
    np.testing.assert_array_equal(stride, np.where(w > 0, 7, 0))
    assert np.all(w[ok] >= 0) and np.all(w[ok] <= 1)  # one ulp below a node rounds to exactly 1


def test_sample_broadcasts_and_keeps_shape():
    w = IRREGULAR[0]
    c = w.sample(np.linspace(-60, -10, 5)[None, :], np.linspace(10, 50, 3)[:, None], T0 + 24 * HOUR)
    assert c.tws_kn.shape == (3, 5) and c.current_u_ms.shape == (3, 5) and c.hs_m.shape == (3, 5)
    flat = w.sample(np.tile(np.linspace(-60, -10, 5), 3), np.repeat(np.linspace(10, 50, 3), 5), T0 + 24 * HOUR)
    np.testing.assert_array_equal(c.tws_kn.ravel(), flat.tws_kn)


# ------------------------------------------------------------------------------ (c) direction conventions


@pytest.mark.parametrize(
    ("u", "v", "twd"),
    [(1.0, 0.0, 270.0), (-1.0, 0.0, 90.0), (0.0, 1.0, 180.0), (0.0, -1.0, 0.0), (-1.0, -1.0, 45.0)],
)
def test_wind_direction_is_where_the_wind_comes_from(u, v, twd):
    lon, lat, time = np.array([-10.0, 0.0]), np.array([40.0, 50.0]), times(2)
    shape = (2, 2, 2)
    w = weather_from_dataset(era5({"u10": uniform(shape, u), "v10": uniform(shape, v)}, lon, lat, time))
    c = w.sample(-5.0, 45.0, T0 + 3 * HOUR)
    assert angle_diff(c.twd_deg, twd) < 1e-9
    np.testing.assert_allclose(c.tws_kn, np.hypot(u, v) / KN, rtol=1e-12)


def test_wave_direction_is_averaged_as_a_unit_vector():
    lon, lat, time = np.array([-10.0, 0.0]), np.array([40.0, 50.0]), times(2)
    shape = (2, 2, 2)
    mwd = np.empty(shape, dtype=np.float32)
    mwd[0], mwd[1] = 359.0, 1.0  # in time
    fields = {"u10": uniform(shape, 1.0), "v10": uniform(shape, 0.0), "mwd": mwd, "swh": uniform(shape, 2.0)}
    w = weather_from_dataset(era5(fields, lon, lat, time))
    c = w.sample(-5.0, 45.0, T0 + 3 * HOUR)  # half way: 0, not 180
    assert angle_diff(c.wave_dir_deg, 0.0) < 1e-4  # float32 sin/cos of the stored angles
    mwd[0, :, 0], mwd[0, :, 1] = 350.0, 20.0  # in space: bisector of 350 and 20 is 5
    w = weather_from_dataset(era5({**fields, "mwd": mwd}, lon, lat, time))
    assert angle_diff(w.sample(-5.0, 45.0, T0).wave_dir_deg, 5.0) < 1e-4
    assert angle_diff(w.interpolate("wave_dir_deg", -5.0, 45.0, T0), 5.0) < 1e-4


def test_speed_and_direction_file_round_trips_through_u_v():
    """A file with wind speed [knots] and direction (CF standard names) samples back to the same at nodes."""
    rng = np.random.default_rng(5)
    lon, lat, time = np.arange(-20.0, 1.0, 5.0), np.arange(30.0, 51.0, 5.0), times(3)
    shape = (time.size, lat.size, lon.size)
    speed, direction = rng.uniform(1, 30, shape), rng.uniform(0, 360, shape)
    ds = xr.Dataset(
        {
            "ws": (("time", "lat", "lon"), speed, {"units": "knots", "standard_name": "wind_speed"}),
            "wd": (("time", "lat", "lon"), direction, {"units": "degrees", "standard_name": "wind_from_direction"}),
        },
        coords={"time": time, "lat": lat, "lon": lon},
    )
    w = weather_from_dataset(ds)
    t, y, x = np.meshgrid(time, lat, lon, indexing="ij")
    c = w.sample(x, y, t)
    np.testing.assert_allclose(c.tws_kn, speed, rtol=1e-6)  # float32 u/v storage
    assert angle_diff(c.twd_deg, direction).max() < 1e-4


# --------------------------------------------------------------------------------------------- (d) units


@pytest.mark.parametrize("units", ["knots", "kt", "kn", "knot", "kts"])
def test_knots_are_converted(units):
    lon, lat, time = np.array([-10.0, 0.0]), np.array([40.0, 50.0]), times(2)
    shape = (2, 2, 2)
    ds = era5({"u10": uniform(shape, 0.0), "v10": uniform(shape, -15.0)}, lon, lat, time,
              attrs={"u10": {"units": units}, "v10": {"units": units}})  # fmt: skip
    w = weather_from_dataset(ds)
    np.testing.assert_allclose(w.sample(-5.0, 45.0, T0).tws_kn, 15.0, rtol=1e-6)
    np.testing.assert_allclose(w.interpolate("wind_v_ms", -5.0, 45.0, T0), -15.0 * KN, rtol=1e-6)


@pytest.mark.parametrize("units", ["m s**-1", "m s-1", "m/s", "m.s-1", "meter per second", None, "unknown"])
def test_metres_per_second_spellings_and_missing_units(units):
    lon, lat, time = np.array([-10.0, 0.0]), np.array([40.0, 50.0]), times(2)
    a = {} if units is None else {"units": units}
    ds = era5({"u10": uniform((2, 2, 2), 3.0), "v10": uniform((2, 2, 2), 4.0)}, lon, lat, time,
              attrs={"u10": a, "v10": a})  # fmt: skip
    np.testing.assert_allclose(weather_from_dataset(ds).sample(-5, 45, T0).tws_kn, 5.0 / KN, rtol=1e-7)


@pytest.mark.parametrize(("units", "variable"), [("K", "u10"), ("furlong/fortnight", "u10"), ("m s**-1", "swh")])
def test_wrong_units_are_rejected_naming_file_and_variable(tmp_path, units, variable):
    lon, lat, time = np.array([-10.0, 0.0]), np.array([40.0, 50.0]), times(2)
    fields = {k: uniform((2, 2, 2), 1.0) for k in ("u10", "v10", "swh")}
    ds = era5(fields, lon, lat, time, attrs={variable: {"units": units}})
    ds.to_netcdf(tmp_path / "bad_units.nc")
    with pytest.raises(WeatherError, match=rf"bad_units\.nc' variable '{variable}' has units '{re.escape(units)}'"):
        open_weather(tmp_path / "bad_units.nc")


def test_other_units_converted():
    lon, lat, time = np.array([-10.0, 0.0]), np.array([40.0, 50.0]), times(2)
    values = {"u10": 1.0, "v10": 0.0, "swh": 250.0, "mwd": np.pi / 2, "uo": 50.0, "vo": 0.0}
    fields = {k: uniform((2, 2, 2), v) for k, v in values.items()}
    attrs = {"swh": {"units": "cm"}, "mwd": {"units": "radians"}, "uo": {"units": "cm/s"}, "vo": {"units": "cm s-1"}}
    c = weather_from_dataset(era5(fields, lon, lat, time, attrs=attrs)).sample(-5, 45, T0)
    np.testing.assert_allclose([c.hs_m, c.wave_dir_deg, c.current_u_ms], [2.5, 90.0, 0.5], rtol=1e-6)


# --------------------------------------------------------------------- (e) coverage, NaN, broken inputs


def _regional(tmp_path, name="regional.nc", **extra):
    lon, lat, time = np.arange(-70.0, 0.1, 2.0), np.arange(55.0, 4.9, -2.5), times(9)
    shape = (time.size, lat.size, lon.size)
    fields = {"u10": uniform(shape, 5.0), "v10": uniform(shape, 0.0), **extra}
    era5(fields, lon, lat, time).to_netcdf(tmp_path / name)
    return tmp_path / name


def test_check_coverage_names_file_variable_and_ranges(tmp_path):
    w = open_weather(_regional(tmp_path))
    w.check_coverage((-60.0, -10.0), (10.0, 50.0), (T0, T0 + 48 * HOUR))  # inside: no error
    with pytest.raises(WeatherCoverageError, match=r"regional\.nc' variable 'u10' .*lon \[-70, 0\].*requested lon "
                       r"\[-75, -10\].*\(lon not covered\)"):  # fmt: skip
        w.check_coverage((-75.0, -10.0), (10.0, 50.0), (T0, T0 + 48 * HOUR))
    with pytest.raises(WeatherCoverageError, match=r"time 2018-06-01T00:00 \.\. 2018-06-03T00:00.*"
                       r"2018-06-01T00:00 \.\. 2018-06-04T00:00 \(time not covered\)"):  # fmt: skip
        w.check_coverage((-60.0, -10.0), (10.0, 50.0), (T0, T0 + 72 * HOUR))
    with pytest.raises(WeatherCoverageError, match="lat not covered"):
        w.check_coverage((-60.0, -10.0), (0.0, 50.0), (T0, T0 + 48 * HOUR))


def test_points_outside_the_data_are_nan(tmp_path):
    w = open_weather(_regional(tmp_path))
    c = w.sample([-71.0, 1.0, -30.0, -30.0, -30.0], [30.0, 30.0, 4.0, 30.0, 30.0],
                 [T0, T0, T0, T0 - HOUR, T0 + 49 * HOUR])  # fmt: skip
    assert np.isnan(c.tws_kn).all() and np.isnan(c.twd_deg).all()
    np.testing.assert_allclose(w.sample(-30.0, 30.0, T0 + 48 * HOUR).tws_kn, 5.0 / KN, rtol=1e-7)


def test_nan_cells_give_nan_only_where_they_contribute(tmp_path):
    lon, lat, time = np.arange(-70.0, 0.1, 2.0), np.arange(55.0, 4.9, -2.5), times(9)
    swh = uniform((time.size, lat.size, lon.size), 2.0)
    j, i = np.flatnonzero(lat == 30.0)[0], np.flatnonzero(lon == -30.0)[0]
    swh[:, j, i] = np.nan  # a land point at (-30, 30)
    w = open_weather(_regional(tmp_path, swh=swh))
    cells = w.sample([-31.0, -29.0, -31.0, -29.0], [29.0, 29.0, 31.0, 31.0], T0 + 5 * HOUR).hs_m
    assert np.isnan(cells).all()  # the four cells around the NaN node
    clear = w.sample([-33.0, -27.0, -30.0, -32.0, -30.0], [30.0, 30.0, 27.5, 30.0, 35.0], T0 + 5 * HOUR).hs_m
    np.testing.assert_array_equal(clear, 2.0)  # beside it, and on grid lines through neighbouring nodes
    assert np.isfinite(w.sample(-31.0, 29.0, T0 + 5 * HOUR).tws_kn)  # wind is a separate field


def test_all_nan_field_is_an_error(tmp_path):
    path = _regional(tmp_path, swh=np.full((9, 21, 36), np.nan, dtype=np.float32))
    with pytest.raises(WeatherError, match=r"regional\.nc' variable 'swh' is all NaN"):
        open_weather(path)


@pytest.mark.parametrize("head", [b"", b"CDF\x01", b"\x89HDF\r\n\x1a\n", b"GRIB"])
def test_corrupt_file_is_an_error_naming_the_file(tmp_path, head):
    path = tmp_path / "corrupt.nc"
    path.write_bytes(head + np.random.default_rng(0).bytes(3000))
    with pytest.raises(WeatherError, match=r"corrupt\.nc"):
        open_weather(path)


def test_missing_file_is_an_error(tmp_path):
    with pytest.raises(WeatherError, match=r"nothere\.nc': not found"):
        open_weather(tmp_path / "nothere.nc")


def test_missing_wind_is_an_error(tmp_path):
    lon, lat, time = np.array([-10.0, 0.0]), np.array([40.0, 50.0]), times(2)
    era5({"swh": uniform((2, 2, 2), 1.0)}, lon, lat, time).to_netcdf(tmp_path / "waves.nc")
    with pytest.raises(WeatherError, match=r"no 10 m wind .* in 'waves\.nc'|no 10 m wind .*waves\.nc"):
        open_weather(tmp_path / "waves.nc")
    era5({"u10": uniform((2, 2, 2), 1.0)}, lon, lat, time).to_netcdf(tmp_path / "u_only.nc")
    with pytest.raises(WeatherError, match=r"u_only\.nc' variable 'u10' gives one wind component"):
        open_weather(tmp_path / "u_only.nc")


# ------------------------------------------------------------------------------------- (f) several files


def test_wind_and_waves_from_two_files_on_different_grids(tmp_path):
    rng = np.random.default_rng(11)
    wlon, wlat, wtime = np.arange(0.0, 360.0, 2.0), np.arange(90.0, -90.1, -2.0), times(5, step_h=6)
    u = rng.normal(size=(5, wlat.size, wlon.size)).astype(np.float32)
    era5({"u10": u, "v10": u * 0 + 1}, wlon, wlat, wtime).to_netcdf(tmp_path / "wind.nc")
    glon, glat, gtime = np.arange(-70.0, 0.1, 0.5), np.arange(5.0, 55.1, 0.5), times(9, step_h=3)
    swh = rng.uniform(0.5, 6, size=(9, glat.size, glon.size)).astype(np.float32)
    mwd = rng.uniform(0, 360, size=swh.shape).astype(np.float32)
    era5({"swh": swh, "mwd": mwd}, glon, glat, gtime).to_netcdf(tmp_path / "waves.nc")
    w = open_weather([tmp_path / "wind.nc", tmp_path / "waves.nc"])
    assert w.fields == {"tws_kn", "twd_deg", "hs_m", "wave_dir_deg"}
    assert w.field_info["hs_m"].lon.size == glon.size and w.field_info["wind_u_ms"].periodic
    plon, plat = rng.uniform(-70, 0, 300), rng.uniform(5, 55, 300)
    hours = rng.uniform(0, 24, 300)
    ptime = T0 + np.round(hours * 3600e9).astype("timedelta64[ns]")
    xi_h = (ptime - T0) / np.timedelta64(1, "h")
    c = w.sample(plon, plat, ptime)
    ref_hs = RegularGridInterpolator((np.arange(9) * 3.0, glat, glon), swh.astype(float))(
        np.column_stack([xi_h, plat, plon])
    )
    np.testing.assert_allclose(c.hs_m, ref_hs, rtol=0, atol=1e-11)
    lon_w = np.append(wlon, 360.0)
    u_w = np.concatenate([u, u[:, :, :1]], axis=2)[:, ::-1].astype(float)
    ref_u = RegularGridInterpolator((np.arange(5) * 6.0, wlat[::-1], lon_w), u_w)(
        np.column_stack([xi_h, plat, plon % 360])
    )
    np.testing.assert_allclose(w.interpolate("wind_u_ms", plon, plat, ptime), ref_u, rtol=0, atol=1e-11)
    assert np.isnan(c.wave_period_s).all()
    assert not c.current_u_ms.any() and not c.current_v_ms.any()


def test_consecutive_files_join_in_time(tmp_path):
    lon, lat, time, u, v = _canonical_random_field(seed=9)
    time = times(6)
    u, v = np.concatenate([u, -u]), np.concatenate([v, v * 2])
    era5({"u10": u[:3], "v10": v[:3]}, lon, lat, time[:3]).to_netcdf(tmp_path / "june_a.nc")
    era5({"u10": u[3:], "v10": v[3:]}, lon, lat, time[3:]).to_netcdf(tmp_path / "june_b.nc")
    whole = weather_from_dataset(era5({"u10": u, "v10": v}, lon, lat, time))
    joined = open_weather([tmp_path / "june_b.nc", tmp_path / "june_a.nc"])
    rng = np.random.default_rng(2)
    plon, plat = rng.uniform(-180, 180, 500), rng.uniform(-90, 90, 500)
    ptime = T0 + (rng.uniform(0, 30, 500) * 3600e9).astype("timedelta64[ns]")
    np.testing.assert_array_equal(joined.sample(plon, plat, ptime).tws_kn, whole.sample(plon, plat, ptime).tws_kn)
    era5({"u10": u[2:], "v10": v[2:]}, lon, lat, time[2:]).to_netcdf(tmp_path / "overlap.nc")
    with pytest.raises(WeatherError, match="overlap in time"):
        open_weather([tmp_path / "june_a.nc", tmp_path / "overlap.nc"])


# --------------------------------------------------------------------------- (g) CMEMS, names, members


def _cmems(tmp_path, current_names=("uo", "vo")):
    lon, lat, time = np.arange(-40.0, -19.9, 1.0), np.arange(20.0, 40.1, 1.0), times(4)
    depth = np.array([5.0, 0.494, 1.54])  # unsorted: the shallowest is the second level
    shape3, shape4 = (4, lat.size, lon.size), (4, 3, lat.size, lon.size)
    cur = np.empty(shape4, dtype=np.float32)
    cur[:, 0], cur[:, 1], cur[:, 2] = 9.0, 0.25, 7.0
    dims4 = ("time", "depth", "latitude", "longitude")
    ds = xr.Dataset(
        {
            "VHM0": (("time", "latitude", "longitude"), uniform(shape3, 3.0), {"units": "m"}),
            "VMDR": (("time", "latitude", "longitude"), uniform(shape3, 200.0), {"units": "degree"}),
            "VTPK": (("time", "latitude", "longitude"), uniform(shape3, 9.0), {"units": "s"}),
            current_names[0]: (dims4, cur, {"units": "m s-1"}),
            current_names[1]: (dims4, -cur, {"units": "m s-1"}),
        },
        coords={"time": time, "depth": ("depth", depth, {"standard_name": "depth", "positive": "down"}),
                "latitude": lat, "longitude": lon},
    )  # fmt: skip
    ds.to_netcdf(tmp_path / "cmems.nc")
    wind = era5({"u10": uniform((4, 2, 2), 1.0), "v10": uniform((4, 2, 2), 0.0)},
                np.array([-50.0, 0.0]), np.array([0.0, 60.0]), time)  # fmt: skip
    wind.to_netcdf(tmp_path / "wind.nc")
    return [tmp_path / "wind.nc", tmp_path / "cmems.nc"]


@pytest.mark.parametrize("current_names", [("uo", "vo"), ("utotal", "vtotal")])
def test_cmems_names_and_shallowest_depth(tmp_path, current_names):
    w = open_weather(_cmems(tmp_path, current_names))
    assert w.fields == {"tws_kn", "twd_deg", "hs_m", "wave_dir_deg", "wave_period_s", "current_u_ms", "current_v_ms"}
    c = w.sample(-30.3, 30.7, T0 + 7 * HOUR)
    np.testing.assert_allclose([c.hs_m, c.wave_dir_deg, c.wave_period_s], [3.0, 200.0, 9.0], rtol=1e-6)
    np.testing.assert_array_equal([c.current_u_ms, c.current_v_ms], [0.25, -0.25])
    assert w.field_info["current_u_ms"].variable == current_names[0]


def test_standard_names_and_explicit_mapping(tmp_path):
    lon, lat, time = np.array([-10.0, 0.0]), np.array([40.0, 50.0]), times(2)
    shape = (2, 2, 2)
    ds = xr.Dataset(
        {
            "a": (("time", "latitude", "longitude"), uniform(shape, 2.0), {"standard_name": "eastward_wind"}),
            "b": (("time", "latitude", "longitude"), uniform(shape, 0.0), {"standard_name": "northward_wind"}),
            "h1": (("time", "latitude", "longitude"), uniform(shape, 1.0), {"units": "m"}),
            "h2": (("time", "latitude", "longitude"), uniform(shape, 4.0), {"units": "m"}),
        },
        coords={"time": time, "latitude": lat, "longitude": lon},
    )
    w = weather_from_dataset(ds)
    assert w.fields == {"tws_kn", "twd_deg"} and w.field_info["wind_u_ms"].variable == "a"
    w = weather_from_dataset(ds, variables={"hs_m": "h2"})
    np.testing.assert_array_equal(w.sample(-5.0, 45.0, T0).hs_m, 4.0)
    with pytest.raises(WeatherError, match=r"variables\['hs_m'\] = 'h3': no such variable"):
        weather_from_dataset(ds, variables={"hs_m": "h3"})
    with pytest.raises(WeatherError, match=r"field must be one of .* \(got 'hs'\)"):
        weather_from_dataset(ds, variables={"hs": "h2"})
    ds["c"] = ds["a"].assign_attrs(standard_name="eastward_wind")
    with pytest.raises(WeatherError, match=r"variables \['a', 'c'\] all look like wind_u_ms"):
        weather_from_dataset(ds)


def test_ensemble_member_must_be_chosen(tmp_path):
    lon, lat, time = np.array([-10.0, 0.0]), np.array([40.0, 50.0]), times(2)
    u = np.arange(3, dtype=np.float32)[:, None, None, None] + np.zeros((3, 2, 2, 2), dtype=np.float32)
    dims = ("number", "time", "latitude", "longitude")
    ds = xr.Dataset({"u10": (dims, u, MS), "v10": (dims, u * 0, MS)},
                    coords={"number": [0, 1, 2], "time": time, "latitude": lat, "longitude": lon})  # fmt: skip
    ds.to_netcdf(tmp_path / "ens.nc")
    with pytest.raises(WeatherError, match=r"ens\.nc' variable 'u10' has 3 ensemble members.*member=<0\.\.2>"):
        open_weather(tmp_path / "ens.nc")
    w = open_weather(tmp_path / "ens.nc", member=2)
    np.testing.assert_allclose(w.interpolate("wind_u_ms", -5.0, 45.0, T0), 2.0)
    with pytest.raises(WeatherError, match=r"member must be in \[0, 2\] \(got 3\)"):
        open_weather(tmp_path / "ens.nc", member=3)
    with pytest.raises(WeatherError, match="no file has an ensemble dimension"):
        open_weather(_regional(tmp_path), member=1)


def test_era5_expver_dimension_is_merged(tmp_path):
    """Legacy CDS downloads mixing ERA5 (expver 1) and ERA5T (expver 5): each time is in exactly one."""
    lon, lat, time = np.array([-10.0, 0.0]), np.array([50.0, 40.0]), times(4)
    u = np.full((4, 2, 2, 2), np.nan, dtype=np.float32)
    u[:2, 0], u[2:, 1] = 1.0, 3.0  # first two times final ERA5, last two ERA5T
    dims = ("time", "expver", "latitude", "longitude")
    ds = xr.Dataset({"u10": (dims, u, MS), "v10": (dims, u * 0, MS)},
                    coords={"time": time, "expver": [1, 5], "latitude": lat, "longitude": lon})  # fmt: skip
    ds.to_netcdf(tmp_path / "expver.nc")
    w = open_weather(tmp_path / "expver.nc")
    np.testing.assert_array_equal(w.interpolate("wind_u_ms", -5.0, 45.0, times(4)), [1.0, 1.0, 3.0, 3.0])


# -------------------------------------------------------------------------------------------- (h) GRIB


def _write_grib(path: Path) -> None:
    """GFS-like GRIB2: 10 m u/v plus 2 m temperature and 500 hPa u (other levels), two forecast steps."""
    eccodes = pytest.importorskip("eccodes")
    messages = {"u": (2, 2, 103, 10), "v": (2, 3, 103, 10), "t": (0, 0, 103, 2), "u500": (2, 2, 100, 50000)}
    with open(path, "wb") as fh:
        for step in (0, 3):
            for name, (category, number, level_type, level) in messages.items():
                h = eccodes.codes_grib_new_from_samples("regular_ll_sfc_grib2")
                for key, value in [("discipline", 0), ("parameterCategory", category), ("parameterNumber", number),
                                   ("typeOfFirstFixedSurface", level_type), ("scaleFactorOfFirstFixedSurface", 0),
                                   ("scaledValueOfFirstFixedSurface", level), ("dataDate", 20180601),
                                   ("dataTime", 0), ("stepUnits", 1), ("forecastTime", step)]:  # fmt: skip
                    eccodes.codes_set(h, key, value)
                eccodes.codes_set_key_vals(h, {
                    "Ni": 5, "Nj": 4, "latitudeOfFirstGridPointInDegrees": 50.0,
                    "latitudeOfLastGridPointInDegrees": 20.0, "longitudeOfFirstGridPointInDegrees": 300.0,
                    "longitudeOfLastGridPointInDegrees": 340.0, "iDirectionIncrementInDegrees": 10.0,
                    "jDirectionIncrementInDegrees": 10.0,
                })  # fmt: skip
                eccodes.codes_set(h, "bitsPerValue", 24)
                # integers (exact in GRIB simple packing): u = 10*row + col + step, v = 1
                values = (np.arange(4)[:, None] * 10 + np.arange(5)[None, :] + step).ravel().astype(float)
                eccodes.codes_set_values(h, values if name != "v" else np.ones(20))
                eccodes.codes_write(h, fh)
                eccodes.codes_release(h)


@pytest.mark.skipif(importlib.util.find_spec("cfgrib") is None, reason="cfgrib not installed")
def test_grib_gfs_10m_wind_with_mixed_levels(tmp_path, monkeypatch):
    path = tmp_path / "gfs.t00z.pgrb2.0p25.f000"  # GFS names carry no suffix: detected by the GRIB magic
    _write_grib(path)
    calls = []
    original = xr.open_dataset

    def spy(*args, **kwargs):
        calls.append(kwargs.get("backend_kwargs", {}).get("filter_by_keys"))
        return original(*args, **kwargs)

    monkeypatch.setattr(xr, "open_dataset", spy)
    w = open_weather(path)
    assert {"typeOfLevel": "heightAboveGround", "level": 10} in calls
    info = w.field_info["wind_u_ms"]
    np.testing.assert_array_equal(info.lon, [-60.0, -50.0, -40.0, -30.0, -20.0])
    np.testing.assert_array_equal(info.lat, [20.0, 30.0, 40.0, 50.0])
    np.testing.assert_array_equal(info.time, [T0, T0 + 3 * HOUR])
    # node (-50, 40) is row 1 (from 50N), column 1: u = 11 + step; halfway in space and time
    np.testing.assert_allclose(w.interpolate("wind_u_ms", -50.0, 40.0, T0 + 3 * HOUR), 14.0, atol=1e-6)
    np.testing.assert_allclose(w.interpolate("wind_u_ms", -45.0, 35.0, T0 + 90 * 60 * 10**9 * np.timedelta64(1, "ns")),
                               (11 + 12 + 21 + 22) / 4 + 1.5, atol=1e-6)  # fmt: skip
    assert not list(tmp_path.glob("*.idx"))  # no index files written next to the data


def test_grib_without_cfgrib_says_how_to_install(tmp_path, monkeypatch):
    path = tmp_path / "wind.grib2"
    path.write_bytes(b"GRIB" + bytes(100))
    monkeypatch.setitem(sys.modules, "cfgrib", None)  # makes `import cfgrib` raise ImportError
    with pytest.raises(WeatherError, match=r"wind\.grib2' needs cfgrib .*pip install 'pyroute_rel\[grib\]'"):
        open_weather(path)


# --------------------------------------------------------------------------------- (i) box and window


def _global_file(tmp_path):
    lon, lat, time = np.arange(0.0, 360.0, 1.0), np.arange(90.0, -90.1, -1.0), times(20, step_h=3)
    rng = np.random.default_rng(21)
    u = rng.normal(size=(time.size, lat.size, lon.size)).astype(np.float32)
    era5({"u10": u, "v10": -u}, lon, lat, time).to_netcdf(tmp_path / "global.nc")
    return tmp_path / "global.nc"


def test_bbox_and_time_window_load_only_the_subset(tmp_path):
    path = _global_file(tmp_path)
    full = open_weather(path)
    window = ("2018-06-01T07:00Z", np.datetime64("2018-06-02T01:00"))
    cut = open_weather(path, bbox=(-70.0, 5.0, 0.0, 55.0), time_window=window)
    info = cut.field_info["wind_u_ms"]
    # box +- 1 deg margin, plus the bracketing grid point on each side; times 06:00 .. 03:00 next day
    np.testing.assert_array_equal(info.lon, np.arange(-72.0, 2.1, 1.0))
    np.testing.assert_array_equal(info.lat, np.arange(3.0, 57.1, 1.0))
    np.testing.assert_array_equal(info.time, T0 + np.arange(6, 28, 3) * HOUR)
    assert cut.nbytes == 8 * 55 * 75 * 2 * 4  # float32 u and v
    assert full.nbytes > 20 * cut.nbytes
    rng = np.random.default_rng(3)
    plon, plat = rng.uniform(-70, 0, 1000), rng.uniform(5, 55, 1000)
    ptime = np.datetime64("2018-06-01T07:00") + (rng.uniform(0, 18, 1000) * 3600e9).astype("timedelta64[ns]")
    # same grid values; time weights differ only by rounding (times are counted from each cut's first step)
    np.testing.assert_allclose(cut.sample(plon, plat, ptime).tws_kn, full.sample(plon, plat, ptime).tws_kn, rtol=1e-12)


def test_bbox_across_the_antimeridian(tmp_path):
    path = _global_file(tmp_path)
    cut = open_weather(path, bbox=(170.0, -10.0, -170.0, 10.0), margin_deg=0.0)
    np.testing.assert_array_equal(cut.field_info["wind_u_ms"].lon, np.arange(169.0, 191.1, 1.0))
    full = open_weather(path)
    plon = np.array([170.0, 175.5, 179.9, -180.0, -179.5, -170.0])
    plat, ptime = np.linspace(-10, 10, 6), T0 + 5 * HOUR
    # same grid values; time weights differ only by rounding (times are counted from each cut's first step)
    np.testing.assert_allclose(cut.sample(plon, plat, ptime).tws_kn, full.sample(plon, plat, ptime).tws_kn, rtol=1e-12)
    cut.check_coverage((171.0, -171.0), (-9.0, 9.0), (T0, T0 + HOUR))
    with pytest.raises(WeatherCoverageError, match="lon not covered"):
        cut.check_coverage((160.0, -171.0), (-9.0, 9.0), (T0, T0 + HOUR))


def test_box_or_window_outside_a_file_is_a_coverage_error(tmp_path):
    path = _regional(tmp_path)
    with pytest.raises(WeatherCoverageError, match=r"regional\.nc' variable 'u10' covers .*outside the requested box"):
        open_weather(path, bbox=(10.0, 5.0, 30.0, 20.0))
    with pytest.raises(
        WeatherCoverageError,
        match=r"regional\.nc' variable 'u10' \(it covers 2018-06-01T00:00 \.\. "
        r"2018-06-03T00:00\) has no time in the requested",
    ):
        open_weather(path, time_window=("2018-07-01", "2018-07-02"))
    with pytest.raises(WeatherError, match=r"bbox must be"):
        open_weather(path, bbox=(0.0, 50.0, 10.0, 40.0))


# ------------------------------------------------------------------------------------- scenario hook


def test_weather_from_mapping_resolves_paths_and_checks_keys(tmp_path):
    (tmp_path / "data").mkdir()
    _regional(tmp_path / "data")
    table = {"kind": "file", "paths": ["data/regional.nc"], "variables": {"wind_u_ms": "u10"}}
    w = weather_from_mapping(table, base_dir=tmp_path)
    np.testing.assert_allclose(w.sample(-30.0, 30.0, T0).tws_kn, 5.0 / KN, rtol=1e-7)
    bad = [
        ({**table, "pths": []}, r"\[weather\]: unknown key 'pths'"),
        ({**table, "kind": "uniform"}, r"\[weather\]\.kind must be one of \['file'\]"),
        ({**table, "paths": "data/regional.nc"}, r"\[weather\]\.paths must be a non-empty array"),
        ({**table, "member": True}, r"\[weather\]\.member must be an integer"),
        ({**table, "variables": {"hs": "swh"}}, r"\[weather\]\.variables: unknown field 'hs'"),
    ]
    for t, message in bad:
        with pytest.raises(ScenarioError, match=message):
            weather_from_mapping(t, base_dir=tmp_path)
    with pytest.raises(WeatherError, match=r"other\.nc': not found"):
        weather_from_mapping({**table, "paths": ["other.nc"]}, base_dir=tmp_path)


# ------------------------------------------------------------------------------------------- example


@pytest.mark.slow
def test_example_script_writes_an_era5_layout_file(tmp_path):
    spec = importlib.util.spec_from_file_location("make_era5_example", EXAMPLES / "make_era5_example.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    out = module.write(tmp_path / "data" / "era5_synthetic.nc", resolution_deg=1.0, days=6)
    again = module.write(tmp_path / "again.nc", resolution_deg=1.0, days=6)
    assert out.read_bytes() == again.read_bytes()  # deterministic
    with xr.open_dataset(out) as ds:
        assert set(ds.data_vars) == {"u10", "v10", "swh", "mwd", "pp1d"}
        assert ds["u10"].dims == ("valid_time", "latitude", "longitude") and ds["u10"].dtype == np.float32
        assert ds.latitude[0] == 55.0 and ds.latitude[-1] == 5.0  # ERA5: descending
        assert ds.longitude[0] == -70.0 and ds.longitude[-1] == 0.0
        assert ds["mwd"].attrs["units"] == "Degree true" and ds["u10"].encoding["zlib"]
    scenario = tomllib.loads((EXAMPLES / "microtransat_era5.toml").read_text())
    assert scenario["weather"]["paths"] == ["data/era5_synthetic.nc"]
    w = weather_from_mapping(scenario["weather"], base_dir=tmp_path)
    assert w.fields == {"tws_kn", "twd_deg", "hs_m", "wave_dir_deg", "wave_period_s"}
    start, finish = scenario["route"]["start"], scenario["route"]["finish"]
    c = w.sample([start[0], finish[0]], [start[1], finish[1]], np.datetime64("2018-06-03"))
    assert np.isfinite(c.hs_m).all() and np.isfinite(c.tws_kn).all()  # start and finish are at sea
    assert np.isnan(w.sample(-5.0, 40.0, np.datetime64("2018-06-03")).hs_m)  # Spain: no waves on land


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_compiled_wind_vector_equals_numpy(seed):
    """The compiled speed and direction of (u, v) vectors equal numpy's hypot and geodesy.bearing_deg (signed zeros,
    calm, NaN and the axes included): wind *from* = bearing of (-u, -v)."""
    from pyroute_rel._kernels.sampling import vectors  # the arithmetic under test
    from pyroute_rel.geodesy import bearing_deg
    from pyroute_rel.units import KN_PER_MS

    rng = np.random.default_rng(seed)
    special = np.array([0.0, -0.0, 1.0, -1.0, 1e-300, -1e-300, np.nan])
    u = np.concatenate([rng.normal(0.0, 8.0, 2000), np.repeat(special, special.size)])
    v = np.concatenate([rng.normal(0.0, 8.0, 2000), np.tile(special, special.size)])
    speed, direction = np.empty(u.size), np.empty(u.size)
    vectors(u, v, -1.0, KN_PER_MS, speed, direction)
    # sqrt(u^2 + v^2), not hypot (15x slower): a wind under 1e-154 m/s underflows to calm
    np.testing.assert_allclose(speed, np.hypot(u, v) * KN_PER_MS, rtol=1e-15, atol=1e-290)
    expected = bearing_deg(-u, -v)
    np.testing.assert_array_equal(np.isnan(direction), np.isnan(expected))
    diff = (direction - expected + 180.0) % 360.0 - 180.0
    np.testing.assert_allclose(diff[~np.isnan(expected)], 0.0, atol=1e-12)
    assert np.all((direction[~np.isnan(direction)] >= 0.0) & (direction[~np.isnan(direction)] < 360.0))


def test_max_current_bounds_every_sampled_current():
    """The pruning DP's speed bound needs a current no sample can exceed: max |u| and max |v| combined."""
    rng = np.random.default_rng(4)
    lat, lon = np.arange(10.0, 20.1, 1.0), np.arange(-40.0, -29.9, 1.0)
    u, v = rng.normal(0.0, 0.6, (2, lat.size, lon.size))
    u[3, 4] = np.nan  # a land cell
    dims = ("latitude", "longitude")
    ds = xr.Dataset(
        {"u10": (dims, np.ones_like(u)), "v10": (dims, np.zeros_like(u)), "uo": (dims, u), "vo": (dims, v)},
        coords={"latitude": lat, "longitude": lon},
    )
    w = weather_from_dataset(ds)
    assert w.max_current_ms == pytest.approx(np.hypot(np.nanmax(np.abs(u)), np.nanmax(np.abs(v))), rel=1e-6)
    c = w.sample(rng.uniform(-40, -30, 5000), rng.uniform(10, 20, 5000), np.datetime64("2018-06-01"))
    speed = np.hypot(c.current_u_ms, c.current_v_ms)
    assert np.nanmax(speed) <= w.max_current_ms
    no_current = weather_from_dataset(ds[["u10", "v10"]])
    assert no_current.max_current_ms == 0.0


@pytest.mark.parametrize("special", ["/dev/zero", "/dev/null"])
def test_a_device_as_weather_file_is_refused_in_one_line(special) -> None:
    from pyroute_rel.weather.io.readers import open_weather

    with pytest.raises(WeatherError, match=r": not a regular file \(a character device\)"):
        open_weather(special)


@pytest.mark.parametrize("paths", [None, 5, [None], ["a.nc", 3]])
def test_open_weather_refuses_what_is_not_a_path(paths: object) -> None:
    # 5 raised TypeError ("not iterable"), [None] TypeError from pathlib.
    with pytest.raises(WeatherError, match=r"weather files must be a path or a list of paths"):
        open_weather(paths)  # type: ignore[arg-type]


def test_a_file_without_a_time_axis_is_steady_and_says_so(tmp_path: Path) -> None:
    """Issue 34: a weather file without time is steady weather, said in one warning as for a file of a single time
    (it was silent); a time dimension without dates that can be decoded is refused in one line naming the file."""
    dims = ("latitude", "longitude")
    coords = {"latitude": [30.0, 50.0], "longitude": [-40.0, -10.0]}
    ms = {"units": "m s-1"}
    u = np.full((2, 2), 10.0, np.float32)
    xr.Dataset({"u10": (dims, u, ms), "v10": (dims, u * 0, ms)}, coords=coords).to_netcdf(tmp_path / "still.nc")
    with pytest.warns(WeatherWarning, match=r"still\.nc' has no time axis: taken as steady weather") as seen:
        w = open_weather(tmp_path / "still.nc")
    assert len(seen) == 1 and w.steady
    assert float(w.sample(-20.0, 40.0, np.datetime64("2030-01-01")).tws_kn) == pytest.approx(10.0 * KN_PER_MS, rel=1e-6)
    timed = ("time", *dims)
    for name, time_attrs in (("numbers", {}), ("hours_no_epoch", {"units": "hours"})):
        ds = xr.Dataset(
            {"u10": (timed, np.stack([u, u]), ms), "v10": (timed, np.stack([u, u]) * 0, ms)},
            coords={**coords, "time": ("time", [0.0, 6.0], time_attrs)},
        )
        ds.to_netcdf(tmp_path / f"{name}.nc")
        with pytest.raises(
            WeatherError, match=rf"{name}\.nc' variable 'u10': time dimension 'time' has no decodable date"
        ):
            open_weather(tmp_path / f"{name}.nc")


def test_a_wind_file_without_units_is_read_as_m_per_s_with_a_warning(tmp_path: Path) -> None:
    """Issue 34: a wind file in knots without a units attribute was read as m/s without a word (124.82 h against
    133.06 h labelled). A file's speed without units warns which unit was taken; labelled, it does not."""
    dims = ("time", "latitude", "longitude")  # with times: a file without them is steady, which warns too
    times = np.array(["2018-05-31T00", "2018-06-02T00"], dtype="datetime64[ns]")
    coords = {"time": times, "latitude": [30.0, 50.0], "longitude": [-40.0, -10.0]}
    u = np.full((2, 2, 2), 10.0, np.float32)
    xr.Dataset({"u10": (dims, u), "v10": (dims, u * 0)}, coords=coords).to_netcdf(tmp_path / "bare.nc")
    t = np.datetime64("2018-06-01")
    with pytest.warns(WeatherWarning, match=r"bare\.nc' variable '[uv]10' has no units attribute: read as m/s") as seen:
        bare = open_weather(tmp_path / "bare.nc")
        bare_kn = float(bare.sample(-20.0, 40.0, t).tws_kn)
    assert {str(w.message).split("variable ")[1][:5] for w in seen} == {"'u10'", "'v10'"}
    knots = {"units": "knots"}
    xr.Dataset({"u10": (dims, u, knots), "v10": (dims, u * 0, knots)}, coords=coords).to_netcdf(tmp_path / "kn.nc")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        labelled = open_weather(tmp_path / "kn.nc")
    assert bare_kn == pytest.approx(10.0 * KN_PER_MS, rel=1e-6)
    assert float(labelled.sample(-20.0, 40.0, t).tws_kn) == pytest.approx(10.0, rel=1e-6)


@pytest.mark.slow
def test_a_corrupt_grib_file_is_one_line_without_cfgrib_s_traceback(tmp_path):
    """Issue 34: cfgrib printed its traceback (through its logger) before the one-line error. In a fresh process (no
    test harness catching the log): nothing on stderr but what the caller prints."""
    import subprocess
    import sys

    path = tmp_path / "bad.grib2"
    path.write_bytes(b"GRIB" + bytes(range(256)) * 2)
    code = (
        "from pyroute_rel.errors import WeatherError\n"
        "from pyroute_rel.weather.io.readers import open_weather\n"
        "try:\n"
        f"    open_weather({str(path)!r})\n"
        "except WeatherError as exc:\n"
        "    print(exc)\n"
    )
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert run.stderr == "" and run.stdout.startswith(f"cannot read GRIB file '{path}'"), run.stderr
