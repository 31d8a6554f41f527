"""Reading ensemble members from their stored values (issue 19's benchmark: each worker reads many members of one
file kept open, :func:`~pyroute_rel.weather.io.readers.keep_files_open`, and the process routing the mean reads it).

The stored values are read with netCDF4 and decoded by a table of every stored value (8/16-bit integers), then put
in a :class:`~pyroute_rel.weather.gridded.GriddedWeather`. Checked here, bit for bit, against an independent
decoding of the file written in the test (netCDF4 with ``set_auto_maskandscale(False)``, the CF arithmetic in numpy:
``stored * scale_factor + add_offset`` in float64, fill values missing, then float32; directions into [0, 360); the
wave direction stored as its sine and cosine): a packed member, a float member, members with fill values, and the
ensemble mean (float64 sum in member order over the members with a value, divided by their count). And a worker
reading members never imports dask.array (a second of a process's start).
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import netCDF4
import numpy as np
import pytest
import xarray as xr

from pyroute_rel.units import KN_PER_MS
from pyroute_rel.weather.io import readers

N_MEMBERS, NT, NY, NX = 4, 5, 6, 7
FILL = -32767
PACKING = {"u10": (0.002, 0.0), "v10": (0.002, 0.0), "swh": (0.001, 16.0), "mwd": (0.01, 180.0)}
UNITS = {"u10": "m s**-1", "v10": "m s**-1", "swh": "m", "mwd": "Degree true"}


def _write(path: Path, *, packed: bool) -> Path:
    """A member-dimension file like ERA5's ensemble (latitude descending, one chunk per member and variable, zlib),
    with fill values in some cells of some members (and in every member at one cell); packed in 16-bit integers or
    float32. Wave directions from -140 deg (normalised into [0, 360) when read)."""
    rng = np.random.default_rng(7)
    with netCDF4.Dataset(path, "w") as nc:
        for dim, n in (("number", N_MEMBERS), ("valid_time", NT), ("latitude", NY), ("longitude", NX)):
            nc.createDimension(dim, n)
        nc.createVariable("number", "i8", ("number",))[:] = np.arange(N_MEMBERS)
        t = nc.createVariable("valid_time", "i8", ("valid_time",))
        t.units, t.calendar = "hours since 2018-06-01 00:00:00", "proleptic_gregorian"
        t[:] = np.arange(NT) * 6
        lat = nc.createVariable("latitude", "f8", ("latitude",))
        lat.units = "degrees_north"
        lat[:] = np.linspace(40.0, 30.0, NY)
        lon = nc.createVariable("longitude", "f8", ("longitude",))
        lon.units = "degrees_east"
        lon[:] = np.linspace(340.0, 352.0, NX)
        shape = (N_MEMBERS, NT, NY, NX)
        physical = {
            "u10": rng.uniform(-20.0, 20.0, shape),
            "v10": rng.uniform(-20.0, 20.0, shape),
            "swh": rng.uniform(0.5, 9.0, shape),
            "mwd": rng.uniform(-140.0, 359.0, shape),
        }
        for name, values in physical.items():
            dtype, fill = ("i2", FILL) if packed else ("f4", -9999.0)
            v = nc.createVariable(name, dtype, ("number", "valid_time", "latitude", "longitude"), fill_value=fill,
                                  zlib=True, shuffle=True, chunksizes=(1, NT, NY, NX))  # fmt: skip
            v.set_auto_maskandscale(False)
            v.units = UNITS[name]
            if packed:
                scale, offset = PACKING[name]
                v.scale_factor, v.add_offset = scale, offset
                stored = np.round((values - offset) / scale).astype(np.int16)
            else:
                stored = values.astype(np.float32)
            stored[1, :, 2:4, 3] = fill  # missing in member 1
            stored[:, 2, 4, 5] = fill  # missing in every member
            v[:] = stored
    return path


def _decoded(path: Path, name: str) -> np.ndarray:
    """(member, time, lat ascending, lon) decoded independently: float64 arithmetic on the stored values, fill values
    NaN (not float32 yet)."""
    with netCDF4.Dataset(path) as nc:
        v = nc[name]
        v.set_auto_maskandscale(False)
        stored = np.asarray(v[:])
        fill = v.getncattr("_FillValue")
        if "scale_factor" in v.ncattrs():
            values = stored.astype(np.float64) * np.float64(v.scale_factor) + np.float64(v.add_offset)
        else:
            values = stored.astype(np.float32)
        values = np.where(stored == fill, np.nan, values)
    return values[:, :, ::-1, :]


def _expected_block(columns: dict[str, np.ndarray], names: list[str]) -> np.ndarray:
    """The (lat, lon, time, column) float32 block from per-field (time, lat, lon) float32 values."""
    return np.stack([np.moveaxis(columns[n], 0, -1) for n in names], axis=-1).astype(np.float32)


def _columns(fields: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """A block's columns from float32 fields on (time, lat, lon): directions into [0, 360) as float32, the wave
    direction as the float32 sine and cosine of its radians."""
    mwd = np.mod(fields["mwd"], np.float32(360.0))
    rad = np.deg2rad(mwd)
    return {
        "wind_u_ms": fields["u10"],
        "wind_v_ms": fields["v10"],
        "hs_m": fields["swh"],
        "_wave_sin": np.sin(rad),
        "_wave_cos": np.cos(rad),
    }


def _block_bytes_equal(weather, columns: dict[str, np.ndarray]) -> None:
    (block,) = weather._blocks  # one grid
    assert sorted(block.names) == sorted(columns)
    expected = _expected_block(columns, block.names)
    assert block.data.shape == expected.shape
    missing = np.isnan(expected)
    assert np.array_equal(np.isnan(block.data), missing)  # (a NaN's sign bit is not compared)
    assert block.data[~missing].tobytes() == expected[~missing].tobytes()  # bit for bit


@pytest.fixture(scope="module", params=["packed", "float"])
def ens_file(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _write(tmp_path_factory.mktemp("fast") / f"{request.param}.nc", packed=request.param == "packed")


@pytest.fixture
def kept():
    readers.keep_files_open(True)
    yield
    readers.keep_files_open(False)


def test_a_kept_member_is_the_files_decoding_bit_for_bit(ens_file: Path, kept: None):
    """Members read from the kept file (the stored values, and for the packed file their tables), in any order, are
    the independent decoding of the file, fill values missing; and their plans are reused (one open, one plan)."""
    decoded = {n: _decoded(ens_file, n) for n in PACKING}
    readers.files_opened(reset=True)
    for member in (2, 0, 1, 3):
        w = readers.open_weather(ens_file, member=member)
        fields = {n: v[member].astype(np.float32) for n, v in decoded.items()}
        _block_bytes_equal(w, _columns(fields))
        assert np.isnan(w._blocks[0].data[3, 3, :, 0]).all() == (member == 1)  # member 1's fill values
    assert readers.files_opened(reset=True) == {str(ens_file.resolve()): 1}
    (raw,) = (r for _, r in readers._files().raw)
    assert len(raw.plans) == 4  # one per variable, whatever the member
    packed = raw.variable("u10", None).table is not None  # type: ignore[union-attr]
    assert packed == ("packed" in ens_file.name)


def test_a_kept_member_with_a_box_and_window_is_the_same_cut(ens_file: Path, kept: None):
    """A box and a time window cut the same rows, columns and times from the decoding."""
    decoded = {n: _decoded(ens_file, n) for n in PACKING}
    w = readers.open_weather(
        ens_file, member=3, bbox=(-16.0, 33.0, -13.0, 35.0), time_window=("2018-06-01T07:00", "2018-06-01T13:00"),
        margin_deg=0.0,
    )  # fmt: skip
    block = w._blocks[0]
    lat_all, lon_all = np.linspace(30.0, 40.0, NY), np.linspace(340.0, 352.0, NX) - 360.0
    rows = np.flatnonzero(np.isin(lat_all, block.lat))
    cols = np.flatnonzero(np.isin(lon_all, block.lon))
    assert rows.size < NY and cols.size < NX and np.array_equal(block.lat, lat_all[rows])
    times = np.array([1, 2, 3])  # 06:00, 12:00, 18:00 bracket the window
    assert np.array_equal(block.time_s, (times - 1) * 6 * 3600.0)
    fields = {n: v[3][times][:, rows][:, :, cols].astype(np.float32) for n, v in decoded.items()}
    _block_bytes_equal(w, _columns(fields))


def test_the_mean_is_the_float64_sum_in_member_order_over_the_members_with_a_value(ens_file: Path):
    """The ensemble mean read from the stored values: the float64 sum in member order of the decoded values of the
    members that have one, over their count, then float32; NaN where no member has one (a cell missing in all)."""
    decoded = {n: _decoded(ens_file, n) for n in PACKING}
    means = {}
    for name, values in decoded.items():
        total = np.zeros(values.shape[1:])
        count = np.zeros(values.shape[1:])
        for member in values.astype(np.float64):  # in member order
            ok = ~np.isnan(member)
            total[ok] = total[ok] + member[ok]
            count += ok
        with np.errstate(invalid="ignore"):
            means[name] = (total / count).astype(np.float32)
    assert np.isnan(means["u10"][2, 1, 5]) and not np.isnan(means["u10"][2, 2, 5])  # (latitude ascending)
    w = readers.open_weather(ens_file, member="mean")
    _block_bytes_equal(w, _columns(means))
    assert readers._files().raw == []  # the mean's file closed with its stored values


def test_a_member_read_alone_through_xarray_is_the_same(ens_file: Path):
    """The same member read without keeping the file (xarray and dask decode it): the same block."""
    alone = readers.open_weather(ens_file, member=1)
    readers.keep_files_open(True)
    try:
        kept = readers.open_weather(ens_file, member=1)
    finally:
        readers.keep_files_open(False)
    assert alone._blocks[0].data.tobytes() == kept._blocks[0].data.tobytes()


def test_a_changed_unit_or_valid_range_applies_to_the_table_as_to_the_values(tmp_path: Path, kept: None):
    """Units (knots) and a valid range (in packed units) are applied element by element: on the table of stored
    values here, the same numbers as on the values."""
    path = _write(tmp_path / "kn.nc", packed=True)
    with netCDF4.Dataset(path, "a") as nc:
        nc["u10"].units = "knots"
        nc["swh"].valid_max = np.int16(-9000)  # (packed units) 16 - 9 = 7 m
    decoded = {n: _decoded(path, n) for n in PACKING}
    w = readers.open_weather(path, member=2, out_of_range="missing")
    fields = {n: v[2].astype(np.float32) for n, v in decoded.items()}
    fields["u10"] = fields["u10"] * np.float32(1.0 / KN_PER_MS)
    fields["swh"] = np.where(fields["swh"] > 7.0, np.float32(np.nan), fields["swh"])
    assert np.isnan(fields["swh"]).any() and not np.isnan(fields["swh"]).all()
    _block_bytes_equal(w, _columns(fields))


@pytest.mark.slow  # a fresh process: 2-3 s of imports
def test_reading_kept_members_and_the_mean_never_imports_dask_array(tmp_path: Path):
    """In a fresh process (as a worker): members of a kept file and the mean are read without importing dask.array
    (xarray's first selection of a member imported it for its duck-array checks: a second)."""
    path = _write(tmp_path / "ens.nc", packed=True)
    code = (
        "import sys\n"
        "from pyroute_rel.weather.io import readers\n"
        "readers.keep_files_open(True)\n"
        f"for m in (0, 1): readers.open_weather({str(path)!r}, member=m)\n"
        "readers.keep_files_open(False)\n"
        f"readers.open_weather({str(path)!r}, member='mean')\n"
        "print('dask.array' in sys.modules)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True)
    assert out.stdout.strip() == "False", out.stderr


@pytest.mark.slow
def test_a_coded_wave_direction_is_stored_as_its_values_and_a_stale_code_is_ignored():
    """A wave direction given with its codes (:class:`CodedValues`) is stored as the sine and cosine of its values,
    as one without; a copy with other values (``dataclasses.replace``) keeps the old codes but is stored from its own
    values."""
    from dataclasses import replace

    from pyroute_rel.weather.gridded import CodedValues, GriddedWeather, WeatherField

    rng = np.random.default_rng(3)
    table = np.mod(rng.uniform(-100.0, 400.0, 256).astype(np.float32), np.float32(360.0))
    codes = rng.integers(0, 256, (3, 4, 5)).astype(np.uint8)
    values = table[codes]
    lon, lat = np.arange(5.0), np.arange(4.0) + 40.0
    time = np.datetime64("2018-06-01T00:00", "ns") + np.arange(3) * np.timedelta64(6, "h")
    wind = [WeatherField(n, np.ones((3, 4, 5), np.float32), lon, lat, time) for n in ("wind_u_ms", "wind_v_ms")]
    coded = WeatherField("wave_dir_deg", values, lon, lat, time, coded=CodedValues(values, codes, table))
    other = replace(coded, values=np.flip(values, axis=0).copy())  # the same codes, other values
    for field in (coded, other):
        block = GriddedWeather([*wind, field])._blocks[0]
        rad = np.deg2rad(field.values)
        for name, expected in (("_wave_sin", np.sin(rad)), ("_wave_cos", np.cos(rad))):
            got = block.data[..., block.names.index(name)]
            assert got.tobytes() == np.moveaxis(expected, 0, -1).astype(np.float32).tobytes(), name


def test_the_lock_around_netcdf4_calls_is_the_one_xarrays_backend_takes(tmp_path: Path) -> None:
    """Files read here with netCDF4 and files xarray reads in other threads never call HDF5 at once: the lock taken
    here (xarray's ``NETCDF4_PYTHON_LOCK``, not a public name: pinned versions) is held by xarray's netCDF4 store."""
    from xarray.backends.netCDF4_ import NetCDF4DataStore

    path = tmp_path / "a.nc"
    xr.Dataset({"a": ("x", np.arange(3.0))}).to_netcdf(path, engine="netcdf4")
    store = NetCDF4DataStore.open(path)
    try:
        held = getattr(store.lock, "locks", (store.lock,))
        ours = getattr(readers._NETCDF4_LOCK, "locks", (readers._NETCDF4_LOCK,))
        assert ours and all(any(lock is h for h in held) for lock in ours)
    finally:
        store.close()


def test_a_file_the_fast_path_cannot_read_is_read_by_xarray_and_a_bug_is_not_hidden(
    ens_file: Path, kept: None, monkeypatch: pytest.MonkeyPatch
) -> None:
    """When netCDF4 cannot give the stored values (an HDF5 error is an OSError), the member is read by xarray: the
    same block as the fast path's. Any other exception (a bug of ours) is not taken for the file's trouble."""
    fast = readers.open_weather(ens_file, member=2)._blocks[0].data.tobytes()
    readers.keep_files_open(False)
    readers.keep_files_open(True)

    def damaged(*args: object, **kwargs: object) -> None:
        raise OSError("NetCDF: HDF error")

    monkeypatch.setattr(readers, "_raw_variable", damaged)
    slow = readers.open_weather(ens_file, member=2)
    assert slow._blocks[0].data.tobytes() == fast
    assert all(v is None for _, raw in readers._files().raw for v in raw._variables.values())
    readers.keep_files_open(False)
    readers.keep_files_open(True)

    def bug(*args: object, **kwargs: object) -> None:
        raise AttributeError("a bug")

    monkeypatch.setattr(readers, "_raw_variable", bug)
    with pytest.raises(AttributeError, match="a bug"):
        readers.open_weather(ens_file, member=2)
