"""Reading one member of a kept ensemble file fast (issue 19's benchmark: each worker process reads many members of
one file): the stored codes looked up in one compiled pass straight into the (lat, lon, time) layout of the blocks,
the blocks filled by compiled copies, and the scenario file's other settings read once per process.

Checked against independent references: numpy's ``take`` and ``fmin``/``fmax`` reductions for the look-up; the
numpy construction of the blocks (the compiled fill switched off) on float, packed, coded-direction data with NaN;
a fresh read without anything kept (files not kept open) for every member's weather, bit for bit, and the other
settings of the scenario; and the kept settings are dropped when the scenario file changes or
:func:`~pyroute_rel.weather.io.readers.keep_files_open` is called again.
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import netCDF4
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pyroute_rel._kernels import sampling
from pyroute_rel.analysis import members
from pyroute_rel.weather import gridded
from pyroute_rel.weather.gridded import CodedValues, GriddedWeather, WeatherField
from pyroute_rel.weather.io import readers

N_MEMBERS, NT, NY, NX = 3, 6, 5, 7


@pytest.mark.slow
@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    shape=st.tuples(st.integers(1, 5), st.integers(1, 5), st.integers(1, 5)),
    special=st.sampled_from(["none", "nan", "all_nan", "inf"]),
    with_codes=st.booleans(),
)
def test_look_up_is_numpy_take_and_nan_ignoring_extremes(seed, shape, special, with_codes):
    """``sampling.look_up_codes``: the codes taken along each axis, looked up, laid out (lat, lon, time); the extremes
    of ``table[codes]`` as numpy's fmin/fmax reductions (NaN only when all are NaN); whether any is finite."""
    rng = np.random.default_rng(seed)
    table = rng.uniform(-50.0, 50.0, 256).astype(np.float32)
    if special == "nan":
        table[rng.integers(0, 256, 40)] = np.nan
    elif special == "all_nan":
        table[:] = np.nan
    elif special == "inf":
        table[rng.integers(0, 256, 3)] = np.inf
    lookup = table * np.float32(2.0) + np.float32(1.0)  # another table: the values looked up
    codes = rng.integers(0, 256, shape).astype(np.uint8)
    order = [rng.integers(0, n, rng.integers(1, 6)) for n in shape]  # repeats and any order, as _reorder allows
    values, kept, lo, hi, finite = sampling.look_up_codes(codes, *order, table, lookup, with_codes)
    taken = codes
    for axis, idx in enumerate(order):
        taken = np.take(taken, idx, axis=axis)
    assert values.shape == np.moveaxis(taken, 0, -1).shape
    assert values.tobytes() == np.moveaxis(np.take(lookup, taken), 0, -1).tobytes()
    if with_codes:
        assert np.array_equal(kept, np.moveaxis(taken, 0, -1))
    assert kept.size == (taken.size if with_codes else 0)
    looked = np.take(table, taken)
    for got, want in ((lo, np.fmin.reduce(looked, axis=None)), (hi, np.fmax.reduce(looked, axis=None))):
        assert (np.isnan(got) and np.isnan(want)) or got == want
    assert finite == bool(np.isfinite(looked).any())


def _fields(rng: np.random.Generator, *, layout: str) -> list[WeatherField]:
    """Wind, waves (a coded direction) and period on one grid, with NaN; float32 values laid out (time, lat, lon)
    (``"c"``), as views of (lat, lon, time) arrays (``"view"``, as the kept reader gives them), or float64."""
    lon, lat = np.arange(NX, dtype=float) - 20.0, np.arange(NY, dtype=float) + 30.0
    time = np.datetime64("2018-06-01T00:00", "ns") + np.arange(NT) * np.timedelta64(6, "h")

    def laid(values: np.ndarray) -> np.ndarray:
        if layout == "view":
            return np.ascontiguousarray(np.moveaxis(values, 0, -1)).transpose(2, 0, 1)
        return values.astype(np.float64) if layout == "float64" else values

    out = []
    for name, lo, hi in (("wind_u_ms", -20, 20), ("wind_v_ms", -20, 20), ("hs_m", 0, 9), ("wave_period_s", 2, 15)):
        v = rng.uniform(lo, hi, (NT, NY, NX)).astype(np.float32)
        v[rng.random(v.shape) < 0.1] = np.nan
        out.append(WeatherField(name, laid(v), lon, lat, time))
    table = np.mod(rng.uniform(-180.0, 540.0, 1 << 16).astype(np.float32), np.float32(360.0))
    table[7] = np.nan  # a fill value's code
    codes = rng.integers(0, 1 << 16, (NT, NY, NX)).astype(np.uint16)
    codes[0, 1, :] = 7
    if layout == "view":
        codes = np.ascontiguousarray(np.moveaxis(codes, 0, -1)).transpose(2, 0, 1)
    values = laid(table[codes])
    out.append(WeatherField("wave_dir_deg", values, lon, lat, time, coded=CodedValues(values, codes, table)))
    return out


@pytest.mark.parametrize("layout", ["c", "view", "float64"])
def test_blocks_filled_by_the_compiled_copies_equal_the_numpy_construction(layout, monkeypatch):
    """The blocks built with the compiled fill (a coded wave direction's sine and cosine, with a missing code) equal,
    bit for bit, those numpy builds (the fill switched off), beside float32 values in either layout and float64
    values (copied by numpy both ways)."""
    fields = _fields(np.random.default_rng(11), layout=layout)
    fast = GriddedWeather(fields)
    monkeypatch.setattr(gridded, "_fill_column", lambda *args: False)
    slow = GriddedWeather(fields)
    for a, b in zip(fast._blocks, slow._blocks, strict=True):
        assert a.names == b.names
        assert a.data.tobytes() == b.data.tobytes()  # NaN bit patterns included
    assert np.isnan(fast._blocks[0].data).any()


def _ensemble(folder: Path) -> Path:
    """An ERA5-like ensemble file (16-bit packed, zlib, latitude descending, fill values, a valid range, wave
    direction from -140 deg) and a scenario file reading it."""
    rng = np.random.default_rng(5)
    path = folder / "ens.nc"
    with netCDF4.Dataset(path, "w") as nc:
        for dim, n in (("number", N_MEMBERS), ("valid_time", NT), ("latitude", NY), ("longitude", NX)):
            nc.createDimension(dim, n)
        nc.createVariable("number", "i8", ("number",))[:] = np.arange(N_MEMBERS)
        t = nc.createVariable("valid_time", "i8", ("valid_time",))
        t.units, t.calendar = "hours since 2018-06-01 00:00:00", "proleptic_gregorian"
        t[:] = np.arange(NT) * 24
        nc.createVariable("latitude", "f8", ("latitude",))[:] = np.linspace(44.0, 32.0, NY)
        nc.createVariable("longitude", "f8", ("longitude",))[:] = np.linspace(-24.0, -6.0, NX)
        nc["latitude"].units, nc["longitude"].units = "degrees_north", "degrees_east"
        for name, units, (scale, offset), (lo, hi) in (
            ("u10", "m s**-1", (0.002, 0.0), (-20.0, 20.0)),
            ("v10", "m s**-1", (0.002, 0.0), (-20.0, 20.0)),
            ("swh", "m", (0.001, 16.0), (0.5, 9.0)),
            ("mwd", "Degree true", (0.01, 180.0), (-140.0, 359.0)),
        ):
            v = nc.createVariable(name, "i2", ("number", "valid_time", "latitude", "longitude"), fill_value=-32767,
                                  zlib=True, shuffle=True, chunksizes=(1, NT, NY, NX))  # fmt: skip
            v.set_auto_maskandscale(False)
            v.units, v.scale_factor, v.add_offset = units, scale, offset
            stored = np.round((rng.uniform(lo, hi, (N_MEMBERS, NT, NY, NX)) - offset) / scale).astype(np.int16)
            stored[1, :, 2, 3] = -32767
            if name == "swh":
                v.valid_range = np.array([-16000, 32000], np.int16)  # packed units: below 0 m missing
                stored[2, 1, 1, 1] = -16500
            v[:] = stored
    toml = folder / "ens.toml"
    toml.write_text(
        '[route]\nstart = [-20.0, 35.0]\nfinish = [-10.0, 41.0]\ndeparture = "2018-06-01T00:00:00Z"\n'
        '[grid]\nn_ranks = 8\nhalf_width_km = 100.0\n[boat]\npolar = "maribot_vane"\n'
        '[weather]\nkind = "file"\npaths = ["ens.nc"]\n[failure]\nmodel = "dickson2018"\napf = 1.0\n'
    )
    return toml


@pytest.fixture
def kept():
    readers.keep_files_open(True)
    yield
    readers.keep_files_open(False)


def _same_scenario(a, b) -> None:
    """Every setting equal; the weather's blocks and grids bit for bit."""
    for f in dataclasses.fields(a):
        if f.name != "weather":
            assert np.all(getattr(a, f.name) == getattr(b, f.name)), f.name
    assert a.weather.field_info.keys() == b.weather.field_info.keys()
    for x, y in zip(a.weather._blocks, b.weather._blocks, strict=True):
        assert x.names == y.names
        assert x.data.tobytes() == y.data.tobytes()
        assert x.lon.tobytes() == y.lon.tobytes() and x.lat.tobytes() == y.lat.tobytes()
        assert x.time_s.tobytes() == y.time_s.tobytes() and x.t0 == y.t0


def test_a_kept_member_is_a_fresh_read_bit_for_bit(tmp_path: Path, monkeypatch):
    """With the files kept open, each member (in any order, again) is the scenario read afresh with nothing kept:
    every setting, and the weather's blocks byte for byte (packed values, a fill value, a valid range, a coded wave
    direction); every field of the kept members was looked up in one pass."""
    toml = _ensemble(tmp_path)
    fresh = {m: members.member_scenario(toml, m) for m in range(N_MEMBERS)}
    assert np.isnan(fresh[1].weather._blocks[0].data).any()
    quick = []
    one_pass = readers._finish_looked_up
    monkeypatch.setattr(readers, "_finish_looked_up", lambda *a: quick.append(one_pass(*a)) or quick[-1])
    readers.keep_files_open(True)
    try:
        for m in (2, 0, 1, 2):
            _same_scenario(members.member_scenario(toml, m), fresh[m])
        assert len(members._kept()) == 1
        assert len(quick) == 4 * 4 and all(f is not None for f in quick)
    finally:
        readers.keep_files_open(False)
    members.member_scenario(toml, 0)
    assert not len(members._kept())  # not kept once the files are not


def _apf(toml: Path) -> float:
    return float(members.member_scenario(toml, 1).apf)


def test_the_kept_settings_are_dropped_when_the_file_changes_or_keeping_starts_again(tmp_path: Path, kept: None):
    """A scenario file changed (new size or time) is read again; one changed in place with its old size and time is
    kept (its stamp) until keep_files_open is called again; a member out of range is named as a fresh read names
    it."""
    toml = _ensemble(tmp_path)
    assert _apf(toml) == 1.0
    toml.write_text(toml.read_text().replace("apf = 1.0", "apf = 0.25"))
    assert _apf(toml) == 0.25  # size changed
    stamp = toml.stat()
    toml.write_text(toml.read_text().replace("apf = 0.25", "apf = 0.50"))  # same size
    os.utime(toml, ns=(stamp.st_atime_ns, stamp.st_mtime_ns))
    assert _apf(toml) == 0.25  # same stamp: kept
    readers.keep_files_open(True)
    assert _apf(toml) == 0.5
    with pytest.raises(Exception) as kept_error:
        members.member_scenario(toml, N_MEMBERS)
    readers.keep_files_open(False)
    with pytest.raises(type(kept_error.value)) as fresh_error:
        members.member_scenario(toml, N_MEMBERS)
    assert str(kept_error.value) == str(fresh_error.value)
    assert str(fresh_error.value).startswith(str(toml))
