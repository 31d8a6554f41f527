"""Real forecast files with one time step are steady weather (issue 17 item 8).

GRIB1 and GRIB2 files are written here by ecCodes from its own samples (``regular_ll_sfc_grib1/2``: a global 2.5 deg
grid like GFS's, 10 m wind) and read through cfgrib; NetCDF files by xarray. The reference for the routed test is
the uniform scenario with the same wind.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from pyroute_rel.errors import WeatherCoverageError, WeatherWarning
from pyroute_rel.scenario import load_scenario
from pyroute_rel.units import KN_PER_MS
from pyroute_rel.weather.io.readers import open_weather

eccodes = pytest.importorskip("eccodes")
pytest.importorskip("cfgrib")

SAMPLES = {1: "regular_ll_sfc_grib1", 2: "regular_ll_sfc_grib2"}
LON = np.arange(0.0, 360.0, 2.5)  # 144 columns, as GFS 2.5 deg
LAT = np.arange(90.0, -90.1, -2.5)  # 73 rows, north to south (GRIB's scanning order)


def grib_file(path: Path, edition: int, when: str, wind: dict[str, np.ndarray | float]) -> Path:
    """One time (``when``, 'YYYYMMDDHH') of 10 m wind on a global 2.5 deg grid, written by ecCodes from its sample of
    ``edition``; ``wind`` maps shortName (``10u``, ``10v``) to a value or a (73, 144) array [m/s]."""
    with open(path, "ab") as fh:
        for short_name, values in wind.items():
            h = eccodes.codes_grib_new_from_samples(SAMPLES[edition])
            try:
                eccodes.codes_set_key_vals(h, {"Ni": LON.size, "Nj": LAT.size})
                for key, value in {
                    "latitudeOfFirstGridPointInDegrees": 90.0,
                    "latitudeOfLastGridPointInDegrees": -90.0,
                    "longitudeOfFirstGridPointInDegrees": 0.0,
                    "longitudeOfLastGridPointInDegrees": 357.5,
                    "iDirectionIncrementInDegrees": 2.5,
                    "jDirectionIncrementInDegrees": 2.5,
                }.items():
                    eccodes.codes_set(h, key, value)
                eccodes.codes_set(h, "dataDate", int(when[:8]))
                eccodes.codes_set(h, "dataTime", int(when[8:]) * 100)
                eccodes.codes_set(h, "typeOfLevel", "heightAboveGround")
                eccodes.codes_set(h, "level", 10)
                eccodes.codes_set(h, "shortName", short_name)
                eccodes.codes_set_values(h, np.broadcast_to(np.asarray(values, float), (LAT.size, LON.size)).ravel())
                eccodes.codes_write(h, fh)
            finally:
                eccodes.codes_release(h)
    return path


# 15.55 kn from the north: u = 0, v = -8 m/s, both exact in float32 and in GRIB's simple packing of a constant field
NORTHERLY = {"10u": 0.0, "10v": -8.0}


@pytest.mark.parametrize("edition", [1, 2])
def test_a_grib_file_with_one_time_is_steady_and_says_so_once(tmp_path: Path, edition: int) -> None:
    path = grib_file(tmp_path / f"gfs.grib{edition}", edition, "2018060100", NORTHERLY)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        w = open_weather(path, time_window=("2018-06-01T06:00", "2018-07-01T00:00"))
    ours = [c for c in caught if issubclass(c.category, WeatherWarning)]
    assert len(ours) == 1, [str(c.message) for c in caught]
    assert str(ours[0].message) == (
        f"weather '{path}' has a single time (2018-06-01T00:00): taken as steady weather, used at all times of the "
        "voyage"
    )
    assert w.steady is True
    assert all(f.time is None for f in w.field_info.values())
    # any time, even long after the file's: the same 8 m/s from the north (= 8 x 3600/1852 kn)
    for when in ("2018-06-01T00:00", "2018-06-20T13:00", "2017-01-01T00:00"):
        c = w.sample([-30.0, 100.0], [40.0, -20.0], np.datetime64(when))
        np.testing.assert_array_equal(c.tws_kn, 8.0 * KN_PER_MS)
        np.testing.assert_array_equal(c.twd_deg, 0.0)
    w.check_coverage((-40.0, -10.0), (20.0, 50.0), (np.datetime64("2018-06-01"), np.datetime64("2018-08-01")))


@pytest.mark.parametrize("edition", [1, 2])
def test_a_grib_field_with_structure_samples_its_values_at_every_time(tmp_path: Path, edition: int) -> None:
    # u grows 0.25 m/s per column eastward (0 at lon 0 .. 35.75 at lon 357.5); v = 0
    u = np.tile(0.25 * np.arange(LON.size), (LAT.size, 1))
    path = grib_file(tmp_path / "gfs.grb", edition, "2018060112", {"10u": u, "10v": 0.0})
    with pytest.warns(WeatherWarning, match="single time"):
        w = open_weather(path)
    # at lon 10 (column 4): u = 1.0 m/s, wind from the west (270); midway between columns 4 and 5: 1.125 m/s
    for when in ("2018-06-01T12:00", "2018-09-01T00:00"):
        got = w.interpolate("wind_u_ms", [10.0, 11.25], 30.0, np.datetime64(when))
        # packing: GRIB's simple packing stores 0.25 steps exactly with enough bits; allow its decimal precision
        np.testing.assert_allclose(got, [1.0, 1.125], atol=1e-3)
        assert w.sample(10.0, 30.0, np.datetime64(when)).twd_deg == pytest.approx(270.0, abs=1e-9)


def test_several_single_time_files_each_a_field_are_steady_together(tmp_path: Path) -> None:
    # wind from a GRIB2 analysis at 00Z, waves from a NetCDF analysis at 06Z: each field has one time -> steady
    wind = grib_file(tmp_path / "wind.grib2", 2, "2018060100", NORTHERLY)
    xr.Dataset(
        {"swh": (("time", "latitude", "longitude"), np.full((1, 3, 4), 1.5, np.float32), {"units": "m"})},
        coords={
            "time": [np.datetime64("2018-06-01T06:00", "ns")],
            "latitude": [30.0, 40.0, 50.0],
            "longitude": [-40.0, -30.0, -20.0, -10.0],
        },
    ).to_netcdf(tmp_path / "waves.nc")
    with pytest.warns(WeatherWarning) as record:
        w = open_weather([wind, tmp_path / "waves.nc"])
    ours = [r for r in record if issubclass(r.category, WeatherWarning)]
    assert len(ours) == 1
    assert "(2018-06-01T00:00, 2018-06-01T06:00): taken as steady weather" in str(ours[0].message)
    assert w.steady and {"hs_m", "tws_kn"} <= w.fields
    c = w.sample(-25.0, 35.0, np.datetime64("2018-07-04T00:00"))
    assert float(c.hs_m) == 1.5 and float(c.tws_kn) == 8.0 * KN_PER_MS


def test_files_with_several_times_keep_the_coverage_rule(tmp_path: Path) -> None:
    # two GFS steps of one field, one file each: joined along time, not steady; outside 00Z..06Z not covered
    for hour in ("00", "06"):
        grib_file(tmp_path / f"gfs.f0{hour}.grib2", 2, f"20180601{hour}", NORTHERLY)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no steady-weather note
        w = open_weather(sorted(tmp_path.glob("*.grib2")))
    assert w.steady is False
    assert w.field_info["wind_u_ms"].time.size == 2
    w.check_coverage((-40.0, -10.0), (20.0, 50.0), (np.datetime64("2018-06-01T00"), np.datetime64("2018-06-01T06")))
    with pytest.raises(WeatherCoverageError, match=r"\(time not covered\)"):
        w.check_coverage((-40.0, -10.0), (20.0, 50.0), (np.datetime64("2018-06-01"), np.datetime64("2018-06-02")))
    assert np.isnan(w.sample(-30.0, 40.0, np.datetime64("2018-06-02")).tws_kn)


def test_one_single_time_field_beside_a_time_series_is_not_steady(tmp_path: Path) -> None:
    # wind has two times, waves one: the waves cover their instant only (today's rule), nothing is steady
    for hour in ("00", "06"):
        grib_file(tmp_path / f"gfs.f0{hour}.grib2", 2, f"20180601{hour}", NORTHERLY)
    xr.Dataset(
        {"swh": (("time", "latitude", "longitude"), np.full((1, 2, 2), 1.0, np.float32), {"units": "m"})},
        coords={"time": [np.datetime64("2018-06-01T00", "ns")], "latitude": [30.0, 50.0], "longitude": [-40.0, -10.0]},
    ).to_netcdf(tmp_path / "waves.nc")
    w = open_weather([*sorted(tmp_path.glob("*.grib2")), tmp_path / "waves.nc"])
    assert w.steady is False and w.field_info["hs_m"].time.size == 1
    with pytest.raises(WeatherCoverageError, match=r"variable 'swh' .*\(time not covered\)"):
        w.check_coverage((-35.0, -15.0), (35.0, 45.0), (np.datetime64("2018-06-01T00"), np.datetime64("2018-06-01T06")))


def test_a_netcdf_file_with_one_time_is_steady_too(tmp_path: Path) -> None:
    dims = ("time", "latitude", "longitude")
    xr.Dataset(
        {
            "u10": (dims, np.zeros((1, 2, 2), np.float32), {"units": "m s-1"}),
            "v10": (dims, np.full((1, 2, 2), -8.0, np.float32), {"units": "m s-1"}),
        },
        coords={"time": [np.datetime64("2018-05-01T00", "ns")], "latitude": [30.0, 50.0], "longitude": [-40.0, -10.0]},
    ).to_netcdf(tmp_path / "analysis.nc")
    # its time lies before the window asked for: a single time is kept whatever the window (it is steady weather)
    with pytest.warns(WeatherWarning, match=r"single time \(2018-05-01T00:00\)"):
        w = open_weather(tmp_path / "analysis.nc", time_window=("2018-06-01", "2018-07-01"))
    assert w.steady
    assert float(w.sample(-20.0, 40.0, np.datetime64("2018-06-15")).tws_kn) == 8.0 * KN_PER_MS


TOML = """
[route]
start = [-12.0, 45.0]
finish = [-60.0, 17.5]
departure = "2018-06-01T03:00:00Z"
[grid]
n_ranks = 20
aspect = 3.0
half_width_km = 400.0
[weather]
{weather}
[failure]
model = "none"
[avoid]
land = false
"""


def test_a_one_time_grib2_file_routes_like_the_uniform_scenario(tmp_path: Path) -> None:
    grib_file(tmp_path / "gfs.t00z.pgrb2.2p50.f000", 2, "2018060100", NORTHERLY)
    (tmp_path / "g.toml").write_text(TOML.format(weather='kind = "file"\npaths = ["gfs.t00z.pgrb2.2p50.f000"]'))
    # the same wind as a uniform field: 8 m/s from the north = 8 x 3600/1852 kn (no waves in either: hs_m = 0 for
    # the uniform field, none in the file; the failure model is "none", so neither is asked for)
    tws = 8.0 * KN_PER_MS
    (tmp_path / "u.toml").write_text(TOML.format(weather=f'kind = "uniform"\ntws_kn = {tws!r}\ntwd_deg = 0.0'))
    with pytest.warns(WeatherWarning, match="single time"):
        gridded = load_scenario(tmp_path / "g.toml")
    assert gridded.weather.steady
    route = gridded.route()
    reference = load_scenario(tmp_path / "u.toml").route()
    assert route.voyage_time_h == pytest.approx(reference.voyage_time_h, abs=1e-9)
    np.testing.assert_array_equal(route.lon_deg, reference.lon_deg)
    np.testing.assert_array_equal(route.lat_deg, reference.lat_deg)


def test_the_command_line_says_steady_once_in_one_line(tmp_path: Path, capsys) -> None:
    from pyroute_rel.cli.main import main

    grib_file(tmp_path / "gfs.f000", 2, "2018060100", NORTHERLY)
    (tmp_path / "g.toml").write_text(TOML.format(weather='kind = "file"\npaths = ["gfs.f000"]'))
    assert main(["route", str(tmp_path / "g.toml"), "--quiet", "--json"]) == 0
    _, err = capsys.readouterr()
    lines = [line for line in err.splitlines() if "steady" in line]
    assert lines == [
        f"pyroute-rel: warning: weather '{tmp_path / 'gfs.f000'}' has a single time (2018-06-01T00:00): taken as "
        "steady weather, used at all times of the voyage"
    ]
