"""Issue acceptance: an ERA5-layout file holding the control field routes exactly like the uniform scenario."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from pyroute_rel.scenario import load_scenario
from pyroute_rel.units import KN_PER_MS

TOML = """
[route]
start = [-12.0, 45.0]
finish = [-60.0, 17.5]
departure = "2018-06-01T00:00:00Z"
[grid]
n_ranks = 20
aspect = 3.0
half_width_km = 400.0
[weather]
{weather}
[failure]
model = "dickson2018"
apf = 0.5
[avoid]
land = false
"""
UNIFORM = 'kind = "uniform"\ntws_kn = 15.0\ntwd_deg = 0.0\nhs_m = 1.0\nwave_dir_deg = 0.0'


def era5_file(path: Path, *, lon360: bool, lat_descending: bool) -> Path:
    """15 kn from the north (u10 = 0, v10 = -15 kn in m/s), 1 m waves from the north; ERA5 names and attributes."""
    lon = np.arange(-75.0, 5.0, 1.0)
    if lon360:
        lon = np.sort(lon % 360.0)
    lat = np.arange(0.0, 61.0, 1.0)
    if lat_descending:
        lat = lat[::-1]
    time = np.arange(np.datetime64("2018-05-31T00"), np.datetime64("2018-07-20T00"), np.timedelta64(6, "h"))
    shape = (time.size, lat.size, lon.size)
    v = -15.0 / KN_PER_MS
    ds = xr.Dataset(
        {
            "u10": (("time", "latitude", "longitude"), np.zeros(shape, np.float32), {"units": "m s**-1"}),
            "v10": (("time", "latitude", "longitude"), np.full(shape, v, np.float32), {"units": "m s**-1"}),
            "swh": (("time", "latitude", "longitude"), np.ones(shape, np.float32), {"units": "m"}),
            "mwd": (("time", "latitude", "longitude"), np.zeros(shape, np.float32), {"units": "Degree true"}),
        },
        coords={"time": time, "latitude": lat, "longitude": lon},
    )
    ds.to_netcdf(path)
    return path


@pytest.fixture(scope="module")
def uniform_time() -> float:
    return load_uniform().route().voyage_time_h


def load_uniform():
    import tempfile

    d = Path(tempfile.mkdtemp())
    (d / "u.toml").write_text(TOML.format(weather=UNIFORM))
    return load_scenario(d / "u.toml")


@pytest.mark.parametrize("lon360", [False, True])
@pytest.mark.parametrize("lat_descending", [False, True])
def test_era5_layout_uniform_field_routes_like_the_uniform_scenario(
    tmp_path: Path, uniform_time: float, lon360: bool, lat_descending: bool
) -> None:
    era5_file(tmp_path / "era5.nc", lon360=lon360, lat_descending=lat_descending)
    (tmp_path / "f.toml").write_text(TOML.format(weather='kind = "file"\npaths = ["era5.nc"]'))
    route = load_scenario(tmp_path / "f.toml").route()
    # float32 storage of v10 = -7.7167 m/s is exact to ~1e-7 relative: so is the voyage time
    assert route.voyage_time_h == pytest.approx(uniform_time, rel=1e-6)
    assert route.max_failure_probability == 0.0


def test_departure_after_the_file_is_a_coverage_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from pyroute_rel.cli import main

    era5_file(tmp_path / "era5.nc", lon360=False, lat_descending=False)
    text = TOML.format(weather='kind = "file"\npaths = ["era5.nc"]').replace(
        "2018-06-01T00:00:00Z", "2018-09-01T00:00:00Z"
    )
    (tmp_path / "late.toml").write_text(text)
    out = tmp_path / "out"
    code = main(["route", str(tmp_path / "late.toml"), "--out", str(out), "--quiet"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1
    assert "era5.nc" in err and "2018-07" in err  # names the file and the covered range
    assert not out.exists()


def test_start_outside_the_file_is_a_coverage_error(tmp_path: Path) -> None:
    from pyroute_rel.errors import WeatherCoverageError

    era5_file(tmp_path / "era5.nc", lon360=False, lat_descending=False)
    text = TOML.format(weather='kind = "file"\npaths = ["era5.nc"]').replace(
        "start = [-12.0, 45.0]", "start = [-12.0, 65.0]"
    )
    (tmp_path / "north.toml").write_text(text)
    with pytest.raises(WeatherCoverageError, match="era5.nc"):
        load_scenario(tmp_path / "north.toml").route()


@pytest.mark.parametrize("damage,needle", [("nan", "NaN"), ("corrupt", "era5.nc")])
def test_bad_weather_file_exit_2_one_line_no_output(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], damage: str, needle: str
) -> None:
    from pyroute_rel.cli import main

    path = era5_file(tmp_path / "era5.nc", lon360=False, lat_descending=False)
    if damage == "nan":
        with xr.open_dataset(path) as ds:
            bad = ds.load()
        bad["u10"][:] = np.nan
        bad["v10"][:] = np.nan
        path.unlink()
        bad.to_netcdf(path)
    else:
        path.write_bytes(np.random.default_rng(0).bytes(4096))
    (tmp_path / "s.toml").write_text(TOML.format(weather='kind = "file"\npaths = ["era5.nc"]'))
    out = tmp_path / "out"
    code = main(["route", str(tmp_path / "s.toml"), "--out", str(out), "--quiet"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err
    assert needle in err
    assert not out.exists()


@pytest.mark.slow
def test_departure_sweep_reports_an_uncovered_departure_as_a_row(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """One departure outside the file's time range is a 'no route' row; the others still route (QA: it aborted)."""
    import json

    from pyroute_rel.cli import main

    era5_file(tmp_path / "era5.nc", lon360=False, lat_descending=False)
    (tmp_path / "f.toml").write_text(TOML.format(weather='kind = "file"\npaths = ["era5.nc"]'))
    code = main(
        [
            "route",
            str(tmp_path / "f.toml"),
            "--quiet",
            "--json",
            "--departures",
            "2018-06-01T00:00:00Z,2019-01-01T00:00:00Z",
        ]
    )
    rows = json.loads(capsys.readouterr().out)["departures"]
    assert code == 0 and [r["feasible"] for r in rows] == [True, False]
    assert "era5.nc" in rows[1]["reason"] and "2018-07" in rows[1]["reason"]


def test_voyage_outlasting_the_file_says_so(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Departing 5 days before the file ends: the front dies where the data stop, and the message says the weather
    does not cover those arcs in time (QA: it said only 'missing weather data (NaN)')."""
    from pyroute_rel.cli import main

    era5_file(tmp_path / "era5.nc", lon360=False, lat_descending=False)
    text = TOML.format(weather='kind = "file"\npaths = ["era5.nc"]').replace(
        "2018-06-01T00:00:00Z", "2018-07-15T00:00:00Z"
    )
    (tmp_path / "late.toml").write_text(text)
    assert main(["route", str(tmp_path / "late.toml"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "missing weather data (NaN)" in err
    assert "the weather does not cover these arcs" in err and "era5.nc" in err and "(time not covered)" in err
