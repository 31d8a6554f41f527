"""Reading the ensemble mean (``member = "mean"``, issue 19): the mean at each point is the float64 sum, in member
order, of the values of the members that have one there, divided by their count (missing where none has).

Checked against the members read one by one (``member = k``) and averaged by numpy, including cells missing in some
members (NaN, or outside the valid range) and in all; identical members give the member itself bit for bit; the
mean read a few members and times at a time is the mean read at once and the sum of xarray's decoded members in
member order; the mean of member files is the mean of the member dimension; the ensemble's mean-field route is
``route`` with ``member = "mean"``; and no dask graph is computed (the reading before session 11 computed one over
every member of the whole file).
"""

from __future__ import annotations

import threading
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from test_evaluate import load_example, write_ensemble_scenario

from pyroute_rel import load_scenario
from pyroute_rel.analysis.ensemble import route_ensemble
from pyroute_rel.analysis.members import mean_of_files, mean_scenario
from pyroute_rel.weather.io import readers

N_MEMBERS = 5
BOX = (-20.0, 26.0, -10.0, 34.0)  # inside the example's grid: the box cut is exercised too
WINDOW = ("2018-06-01T12:00", "2018-06-02T12:00")


def _fields(path: Path, member: int | str | None) -> dict[str, np.ndarray]:
    """The fields as read (float32, on time, lat, lon, after units and directions) by name."""
    with xr.open_dataset(path, decode_timedelta=False) as ds:
        fields = readers.read_fields([(str(path), [ds])], member=member, bbox=BOX, time_window=WINDOW)
    return {f.name: f.values for f in fields}


def _with_gaps(folder: Path, *, quantise: bool) -> Path:
    """A float32 member-dimension file with missing values: u10 missing in members 1 and 3 at some cells and in all
    members at one; swh above its valid_max (missing) in member 2 at some cells. ``quantise``: values on a 1/1024
    grid, so that float64 sums of them are exact in any order."""
    make = load_example("make_ensemble_example")
    ds = make.make_ensemble(N_MEMBERS, resolution_deg=2.0, step_h=12.0, days=2.0, lon=(-24.0, -6.0), lat=(22.0, 38.0))
    ds = ds.astype(np.float32)
    if quantise:
        ds = (np.round(ds * 1024.0) / 1024.0).astype(np.float32)
    u = ds["u10"].values
    u[1, :, 1:3, 2:5] = np.nan
    u[3, 2, 2:4, 3] = np.nan
    u[:, 1, 3, 4] = np.nan  # missing in every member
    h = ds["swh"].values
    h[2, :, 2, 2:6] = 25.0  # above valid_max: missing in member 2 only
    for v in ds.data_vars:
        ds[v].attrs = {"units": {"mwd": "degree", "swh": "m"}.get(str(v), "m s-1")}
    ds["swh"].attrs["valid_max"] = 20.0
    assert np.nanmax(np.delete(h, 2, axis=0)) < 20.0
    path = folder / ("quantised.nc" if quantise else "gaps.nc")
    ds.to_netcdf(path)
    return path


def test_the_mean_is_the_numpy_mean_of_the_members_read_one_by_one(tmp_path: Path):
    path = _with_gaps(tmp_path, quantise=True)
    members = [_fields(path, k) for k in range(N_MEMBERS)]
    mean = _fields(path, "mean")
    assert set(mean) == set(members[0]) == {"wind_u_ms", "wind_v_ms", "hs_m", "wave_dir_deg"}
    for name, got in mean.items():
        stack = np.stack([m[name] for m in members]).astype(np.float64)
        count = np.sum(~np.isnan(stack), axis=0)
        with np.errstate(invalid="ignore"):
            expected = (np.nansum(stack, axis=0) / count).astype(np.float32)  # exact sums: any order
        assert got.dtype == np.float32 and np.array_equal(got, expected, equal_nan=True), name
    u = np.stack([m["wind_u_ms"] for m in members])
    some, every = np.isnan(u).any(axis=0) & ~np.isnan(u).all(axis=0), np.isnan(u).all(axis=0)
    assert some.sum() > 10 and every.sum() == 1 and np.isnan(mean["wind_u_ms"][every]).all()
    assert np.isfinite(mean["wind_u_ms"][some]).all()  # the mean of the others
    h = np.stack([m["hs_m"] for m in members])
    gap = np.isnan(h[2]) & np.isfinite(h[0])  # outside the valid range in member 2: missing there
    assert gap.sum() >= 4 and np.array_equal(mean["hs_m"][gap], np.delete(h, 2, axis=0).mean(axis=0)[gap])


@pytest.mark.parametrize("packed", [False, True])
def test_identical_members_give_the_member_bit_for_bit(tmp_path: Path, packed: bool):
    make = load_example("make_ensemble_example")
    options = {"resolution_deg": 2.0, "step_h": 12.0, "days": 2.0, "spread": 0.0}
    path = tmp_path / "same.nc"
    if packed:  # int16 with float64 scale factors, as ERA5: decoded in float64
        make.write_ensemble(path, 4, **options)
    else:
        make.make_ensemble(4, **options).astype(np.float32).to_netcdf(path)
    member, mean = _fields(path, 0), _fields(path, "mean")
    assert member["wind_u_ms"].size > 100
    for name, values in member.items():
        assert np.array_equal(mean[name], values, equal_nan=True), name


def test_reading_a_few_members_and_times_at_a_time_is_the_sum_in_member_order(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    """With a budget of two times of one member, the mean is read in many pieces, each within the budget, and is
    bit for bit the mean read at once, which is the float64 sum of xarray's decoded members in member order (packed
    values: the sums are inexact, so the order shows) over their count."""
    make = load_example("make_ensemble_example")
    path = make.write_ensemble(tmp_path / "packed.nc", 6, resolution_deg=2.0, step_h=12.0, days=3.0)
    at_once = _fields(path, "mean")
    reads: list[tuple[int, ...]] = []
    read = readers._read

    def spy(da, selectors, dims, where):
        values = read(da, selectors, dims, where)
        reads.append(values.shape)
        return values

    shape = at_once["wind_u_ms"].shape
    budget = 2 * 8 * shape[1] * shape[2]
    monkeypatch.setattr(readers, "_read", spy)
    monkeypatch.setattr(readers, "MEAN_READ_BYTES", budget)
    pieces = _fields(path, "mean")
    assert len(reads) == 4 * 6 * -(-shape[0] // 2) and max(8 * np.prod(s) for s in reads) <= budget
    with xr.open_dataset(path) as ds:
        lat = np.sort(ds["latitude"].values)
        t = ds["valid_time"].values
        keep_t = (t >= np.datetime64(WINDOW[0]) - np.timedelta64(12, "h")) & (
            t <= np.datetime64(WINDOW[1]) + np.timedelta64(12, "h")
        )
        for name, var in (("wind_u_ms", "u10"), ("hs_m", "swh")):
            assert np.array_equal(pieces[name], at_once[name], equal_nan=True), name
            decoded = ds[var].sortby("latitude").values[:, keep_t]  # (member, time, lat, lon), float64
            lon = ds["longitude"].values
            decoded = decoded[..., (lat >= BOX[1] - 3.0) & (lat <= BOX[3] + 3.0), :]
            decoded = decoded[..., (lon >= BOX[0] - 3.0) & (lon <= BOX[2] + 3.0)]
            total = np.zeros(decoded.shape[1:])
            for member in decoded:  # no value is missing here
                total = total + member
            assert decoded.dtype == np.float64 and total.shape == at_once[name].shape
            assert np.array_equal(at_once[name], (total / 6).astype(np.float32)), name


@pytest.mark.slow
def test_the_mean_of_member_files_is_the_mean_of_the_member_dimension(tmp_path: Path):
    """The same members as one file with a member dimension or as files, one per member: the same mean field, bit
    for bit (sums inexact: the order of the files is the order of the members), missing values included; and the
    mean scenarios of both sample the same weather."""
    path = _with_gaps(tmp_path, quantise=False)
    files = []
    with xr.open_dataset(path) as ds:
        for k in range(N_MEMBERS):
            files.append(tmp_path / f"member{k}.nc")
            ds.isel(number=k).drop_vars("number").to_netcdf(files[-1])
    out = mean_of_files(files, tmp_path / "mean.nc")
    of_files, of_dimension = _fields(out, None), _fields(path, "mean")
    assert set(of_files) == set(of_dimension)
    for name, values in of_dimension.items():
        assert np.array_equal(of_files[name], values, equal_nan=True), name
    assert np.isnan(of_dimension["wind_u_ms"]).sum() == 1
    scenario = write_ensemble_scenario(tmp_path / "scenario", n_members=1)
    text = scenario.read_text()
    scenario.write_text(text.replace('paths = ["ens.nc"]', f'paths = ["{path}"]'))
    a = mean_scenario(scenario).weather
    b = mean_scenario(scenario, member_files=files).weather
    lon, lat = np.linspace(-14.0, -22.0, 9), np.linspace(31.0, 25.0, 9)
    when = np.datetime64("2018-06-01T03:00") + np.arange(9) * np.timedelta64(5, "h")
    sa, sb = a.sample(lon, lat, when), b.sample(lon, lat, when)
    for name in ("tws_kn", "twd_deg", "hs_m", "wave_dir_deg"):
        assert np.array_equal(getattr(sa, name), getattr(sb, name), equal_nan=True), name


@pytest.mark.slow
def test_the_mean_field_route_of_the_ensemble_is_route_with_member_mean(tmp_path: Path):
    scenario = write_ensemble_scenario(tmp_path, n_members=3)
    res = route_ensemble(scenario, members=[0], engine="inline")
    by_key = tmp_path / "mean.toml"
    by_key.write_text(scenario.read_text().replace('kind = "file"', 'kind = "file"\nmember = "mean"'))
    expected = load_scenario(by_key).route()
    got = res.mean_route
    assert got is not None and got.ok and res.names[-1] == "mean"
    assert np.array_equal(got.lon_deg, expected.lon_deg) and np.array_equal(got.lat_deg, expected.lat_deg)
    assert got.voyage_time_h == expected.voyage_time_h


def test_reading_the_mean_computes_no_dask_graph(tmp_path: Path):
    """Before, the mean was a dask reduction over every member of the whole file (threads on every core)."""
    dask = pytest.importorskip("dask")
    make = load_example("make_ensemble_example")
    path = make.write_ensemble(tmp_path / "ens.nc", 3, resolution_deg=2.0, step_h=12.0, days=2.0)
    computed: list[object] = []

    def scheduler(*args: object, **kwargs: object) -> None:
        computed.append(args)
        raise AssertionError("a dask graph was computed")

    threads = threading.active_count()
    with dask.config.set(scheduler=scheduler):
        w = readers.open_weather(path, member="mean", bbox=BOX, time_window=WINDOW)
    assert not computed and threading.active_count() == threads
    assert sorted(w.fields) == ["hs_m", "twd_deg", "tws_kn", "wave_dir_deg"]


@pytest.mark.slow  # cfgrib's first import and open: 2-3 s
def test_the_mean_of_a_grib_ensemble_is_the_numpy_mean_of_its_members(tmp_path: Path):
    """An ECMWF-ENS-like GRIB2 file (perturbed members 1..3, read by cfgrib without dask): the same definition."""
    pytest.importorskip("cfgrib")
    eccodes = pytest.importorskip("eccodes")
    rng = np.random.default_rng(3)
    path = tmp_path / "ens.grib2"
    with open(path, "wb") as fh:
        for member in (1, 2, 3):
            for step in (0, 6):
                for number in (2, 3):  # u, v
                    h = eccodes.codes_grib_new_from_samples("regular_ll_sfc_grib2")
                    eccodes.codes_set(h, "productDefinitionTemplateNumber", 1)  # an individual ensemble forecast
                    for key, value in [("discipline", 0), ("parameterCategory", 2), ("parameterNumber", number),
                                       ("typeOfFirstFixedSurface", 103), ("scaleFactorOfFirstFixedSurface", 0),
                                       ("scaledValueOfFirstFixedSurface", 10), ("dataDate", 20180601),
                                       ("dataTime", 0), ("stepUnits", 1), ("forecastTime", step),
                                       ("typeOfEnsembleForecast", 3), ("perturbationNumber", member),
                                       ("numberOfForecastsInEnsemble", 3)]:  # fmt: skip
                        eccodes.codes_set(h, key, value)
                    eccodes.codes_set_key_vals(h, {
                        "Ni": 5, "Nj": 4, "latitudeOfFirstGridPointInDegrees": 50.0,
                        "latitudeOfLastGridPointInDegrees": 20.0, "longitudeOfFirstGridPointInDegrees": 300.0,
                        "longitudeOfLastGridPointInDegrees": 340.0, "iDirectionIncrementInDegrees": 10.0,
                        "jDirectionIncrementInDegrees": 10.0,
                    })  # fmt: skip
                    eccodes.codes_set(h, "bitsPerValue", 24)
                    eccodes.codes_set_values(h, rng.integers(-4000, 4000, 20) / 256.0)  # exact in float32 and GRIB
                    eccodes.codes_write(h, fh)
                    eccodes.codes_release(h)
    members = [readers.open_weather(path, member=k) for k in range(3)]
    mean = readers.open_weather(path, member="mean")
    assert mean.field_info["wind_u_ms"].time.size == 2 and mean.field_info["wind_u_ms"].lat.size == 4
    for block, *parts in zip(mean._blocks, *(m._blocks for m in members), strict=True):
        stack = np.stack([p.flat for p in parts]).astype(np.float64)
        assert not np.array_equal(stack[0], stack[1])
        assert np.array_equal(block.flat, (stack.sum(axis=0) / 3).astype(np.float32))
