"""Reading gridded, time-varying weather files (ERA5, GFS, WAVEWATCH III, CMEMS) into a :class:`GriddedWeather`.

Files are read once (:func:`open_weather`, :func:`weather_from_dataset`), cut to the route's box and
time window, normalised (longitude in [-180, 180), latitude ascending, units converted) and handed over as
:class:`~pyroute_rel.weather.gridded.WeatherField` arrays on (time, lat, lon); sampling them is
:mod:`pyroute_rel.weather.gridded`'s job.

Each field of :data:`VARIABLES` is found by name (ERA5 ``u10 v10 swh mwd pp1d``, GFS via cfgrib ``u10 v10``,
WAVEWATCH III ``HTSGW DIRPW PERPW``, CMEMS ``VHM0 VMDR VTPK``, ``utotal vtotal`` or ``uo vo``), then by CF
``standard_name``; ``variables={field: file_variable}`` overrides the search. Each field keeps its own grid
and time axis; the same field in several files on one grid is joined along time (monthly ERA5 files, one
GRIB file per GFS step). Units come from the ``units`` attribute; a missing, empty or ``"unknown"`` one
means m/s, degrees, m or s by the field's kind; a unit not recognised for the kind (``K`` for wind) is an error.

Wind speed and direction files are stored as (u, v). A file without time is steady, and so are files whose fields
each have a single time (an analysis, or one forecast step downloaded alone; a warning says so); with several
times, the data cover the times they hold. Every value is checked against its plausible range
(:data:`~pyroute_rel.weather.base.RANGES`): declared fill values and values outside a declared CF ``valid_range``
(``valid_min``, ``valid_max``) are missing (NaN), undeclared fill values (9.97e36, 1e20) are out of range, refused
or (``out_of_range="missing"``) made missing.

References
----------
Hersbach, H. et al. (2020). The ERA5 global reanalysis. Q. J. R. Meteorol. Soc. 146, 1999-2049.
https://doi.org/10.1002/qj.3803
"""

from __future__ import annotations

import logging
import os
import threading
import warnings
from collections.abc import Callable, Hashable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, replace
from importlib.util import find_spec
from pathlib import Path
from typing import Any, NamedTuple, TypeVar

import numpy as np
import numpy.typing as npt
import xarray as xr

from pyroute_rel._kernels import sampling
from pyroute_rel.errors import (
    ScenarioError,
    WeatherCoverageError,
    WeatherError,
    WeatherWarning,
    brief,
    check_instance,
    check_numbers,
)
from pyroute_rel.files import check_regular_file
from pyroute_rel.store import current_store
from pyroute_rel.times import iso_minute, to_datetime64
from pyroute_rel.units import KN_PER_MS
from pyroute_rel.weather import cache
from pyroute_rel.weather.base import RANGES
from pyroute_rel.weather.gridded import (
    OUT_OF_RANGE,
    CodedValues,
    GriddedWeather,
    PreparedPoints,
    WeatherField,
    check_plausible,
)

__all__ = [
    "BBOX_MARGIN_DEG",
    "GRIB_FILTERS",
    "VARIABLES",
    "GriddedWeather",
    "PreparedPoints",
    "WeatherField",
    "open_weather",
    "read_fields",
    "weather_from_dataset",
    "weather_from_mapping",
    "ensemble_size",
    "keep_files_open",
    "files_kept_open",
    "files_opened",
    "MEAN_READ_BYTES",
    "accumulate_member",
    "member_mean",
    "valid_range",
]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.intp]
_ScalarT = TypeVar("_ScalarT", bound=np.generic)


#: Margin added on every side of a ``bbox`` when cutting files [deg] (the grid points bracketing the
#: box plus margin are kept as well, so interpolation at the edge of the box is exact).
BBOX_MARGIN_DEG = 1.0

#: Fields read from files: name -> description. Keys of the ``variables`` mapping.
#: ``tws_kn``/``twd_deg`` are an alternative to ``wind_u_ms``/``wind_v_ms`` for files holding wind speed
#: and direction; whatever their file units, they are converted and stored as (u, v).
VARIABLES: dict[str, str] = {
    "wind_u_ms": "eastward 10 m wind, to [m/s]",
    "wind_v_ms": "northward 10 m wind, to [m/s]",
    "tws_kn": "10 m wind speed [kn] (alternative to wind_u_ms/wind_v_ms)",
    "twd_deg": "10 m wind direction, from [deg] (alternative to wind_u_ms/wind_v_ms)",
    "hs_m": "significant wave height [m]",
    "wave_dir_deg": "mean or peak wave direction, from [deg]",
    "wave_period_s": "peak or mean wave period [s]",
    "current_u_ms": "eastward surface current, to [m/s]",
    "current_v_ms": "northward surface current, to [m/s]",
}

#: cfgrib ``filter_by_keys`` tried in turn on a GRIB file, so files mixing levels open: GFS 10 m wind,
#: single-level instantaneous fields (ERA5 10 m wind, WAVEWATCH III), ERA5 wave parameters.
GRIB_FILTERS: tuple[dict[str, Any], ...] = (
    {"typeOfLevel": "heightAboveGround", "level": 10},
    {"typeOfLevel": "surface", "stepType": "instant"},
    {"typeOfLevel": "meanSea"},
)

# Names tried first, in order of preference (compared case-insensitively).
_NAMES: dict[str, tuple[str, ...]] = {
    "wind_u_ms": ("u10", "10u", "u10m", "ugrd10m", "ugrd_10maboveground", "ugrd", "uwnd"),
    "wind_v_ms": ("v10", "10v", "v10m", "vgrd10m", "vgrd_10maboveground", "vgrd", "vwnd"),
    "tws_kn": (),
    "twd_deg": (),
    "hs_m": ("swh", "htsgw", "vhm0", "hs"),
    "wave_dir_deg": ("mwd", "dirpw", "vmdr", "dir", "dp"),
    "wave_period_s": ("pp1d", "perpw", "vtpk", "mwp", "vtm10", "vtm02"),
    "current_u_ms": ("utotal", "uo", "ucur", "uogrd", "water_u"),
    "current_v_ms": ("vtotal", "vo", "vcur", "vogrd", "water_v"),
}
# CF standard names, tried when no name matched.
_STANDARD_NAMES: dict[str, tuple[str, ...]] = {
    "wind_u_ms": ("eastward_wind",),
    "wind_v_ms": ("northward_wind",),
    "tws_kn": ("wind_speed",),
    "twd_deg": ("wind_from_direction",),
    "hs_m": ("sea_surface_wave_significant_height",),
    "wave_dir_deg": (
        "sea_surface_wave_from_direction",
        "sea_surface_wave_from_direction_at_variance_spectral_density_maximum",
        "sea_surface_wave_to_direction",
    ),
    "wave_period_s": (
        "sea_surface_wave_period_at_variance_spectral_density_maximum",
        "sea_surface_wave_mean_period",
        "sea_surface_wave_mean_period_from_variance_spectral_density_first_frequency_moment",
        "sea_surface_wave_mean_period_from_variance_spectral_density_second_frequency_moment",
    ),
    "current_u_ms": ("eastward_sea_water_velocity", "surface_eastward_sea_water_velocity"),
    "current_v_ms": ("northward_sea_water_velocity", "surface_northward_sea_water_velocity"),
}
_KIND = {
    "wind_u_ms": "speed", "wind_v_ms": "speed", "tws_kn": "speed", "twd_deg": "direction",
    "hs_m": "height", "wave_dir_deg": "direction", "wave_period_s": "period",
    "current_u_ms": "speed", "current_v_ms": "speed",
}  # fmt: skip
_SPEED = {
    "ms-1": 1.0, "m/s": 1.0, "m/sec": 1.0, "mps": 1.0, "cm/s": 0.01, "cms-1": 0.01,
    **{
        f"{m}{per}": 1.0
        for m in ("meter", "meters", "metre", "metres")
        for per in ("/second", "persecond", "second-1", "s-1")
    },
    **dict.fromkeys(("knots", "knot", "kt", "kts", "kn"), 1.0 / KN_PER_MS),
    **dict.fromkeys(("km/h", "kmh-1", "kph"), 1.0 / 3.6),
}  # fmt: skip
#: Accepted ``units`` per kind (normalised: lower case, without spaces, ``*``, ``^``, ``_``, ``.``) -> factor.
_UNITS: dict[str, dict[str, float]] = {
    "speed": _SPEED,
    "direction": {
        **dict.fromkeys(("deg", "degree", "degrees", "degreetrue", "degreestrue", "degtrue", "°"), 1.0),
        **dict.fromkeys(("rad", "radian", "radians"), 180.0 / np.pi),
    },
    "height": {**dict.fromkeys(("m", "meter", "meters", "metre", "metres"), 1.0), "cm": 0.01,
               **dict.fromkeys(("ft", "foot", "feet"), 0.3048)},
    "period": dict.fromkeys(("s", "sec", "second", "seconds"), 1.0),
}  # fmt: skip
_DEFAULT_UNITS = {"speed": "m s-1", "direction": "degree", "height": "m", "period": "s"}
_MISSING_UNITS = ("", "unknown", "none")

_LON_NAMES = ("longitude", "lon", "long")
_LAT_NAMES = ("latitude", "lat")
_TIME_NAMES = ("time", "valid_time", "step", "t", "ocean_time")
_MEMBER_NAMES = ("number", "realization", "member", "ensemble", "ens")
_DEPTH_NAMES = ("depth", "deptht", "depthu", "depthv", "z", "lev", "depthbelowsea")
_GRIB_SUFFIXES = (".grib", ".grb", ".grib1", ".grib2", ".grb2")


def open_weather(
    paths: str | os.PathLike[str] | Sequence[str | os.PathLike[str]],
    *,
    variables: Mapping[str, str] | None = None,
    bbox: Sequence[float] | None = None,
    time_window: Sequence[Any] | None = None,
    member: int | str | None = None,
    margin_deg: float = BBOX_MARGIN_DEG,
    out_of_range: str = "error",
) -> GriddedWeather:
    """Read NetCDF/GRIB weather files into a :class:`GriddedWeather`.

    Files are opened lazily (dask chunks for NetCDF; no dask for the ensemble mean) and only the box and time
    window are read.
    Declared fill values (``_FillValue``, ``missing_value``) and values outside the CF ``valid_range`` (or
    ``valid_min`` / ``valid_max``, in packed units when packed) are missing (NaN), never data. When every field read
    has a single time (an analysis, or one step of a forecast downloaded alone), the weather is steady: it is used
    at all times, ``steady`` is True, and a :class:`~pyroute_rel.errors.WeatherWarning` says so once.

    Parameters
    ----------
    paths : One file or several (wind from one, waves from another; or consecutive times).
        NetCDF (netCDF4/HDF5 or classic) and GRIB (needs ``pip install 'pyroute_rel[grib]'``) are told
        apart by their first bytes.
    variables : ``{field: file_variable}`` overriding the automatic search, fields from :data:`VARIABLES`.
    bbox : ``(west, south, east, north)`` [deg] to read (plus ``margin_deg`` and the bracketing grid
        points); ``east < west`` crosses 180°. Default: the whole file.
    time_window : ``(first, last)`` time to read (``datetime64``, ``datetime`` or ISO 8601 string, UTC),
        plus the bracketing time steps. Default: all times.
    member : Ensemble member, as the position along the ``number`` (or ``realization``) dimension
        (equal to the member number for ERA5 and GEFS), or ``"mean"`` for the ensemble mean (each stored
        variable averaged over the members: wind as its u and v components, the usual layout). Required when a
        file holds several members: an ensemble is never reduced silently. The mean at each point is the float64
        sum, in member order, of the decoded values of the members that have a value there (not a fill value, not
        outside the valid range: the values ``member=k`` reads), divided by their count, then stored as float32;
        missing where no member has a value. It is read after the box and window are cut, in groups of members
        holding at most :data:`MEAN_READ_BYTES` of decoded values at once, in this thread (no dask).
    margin_deg : Margin around ``bbox`` [deg].
    out_of_range : ``"error"`` (default): a value outside its plausible range
        (:data:`~pyroute_rel.weather.base.RANGES`; an undeclared fill value, a negative wave height) is an error
        naming the file, variable, count and a location; ``"missing"``: such values are missing (NaN: arcs through
        them are forbidden) and a :class:`~pyroute_rel.errors.WeatherWarning` says how many.

    Raises
    ------
    WeatherError
        A file is missing or unreadable, a variable has wrong units, implausible values or is all NaN, wind is
        missing.
    WeatherCoverageError
        A file does not reach into ``bbox``, or no file of a field reaches into ``time_window``.
    """
    if isinstance(paths, str | os.PathLike):
        paths = [paths]
    if not isinstance(paths, Sequence) or not all(isinstance(p, str | os.PathLike) for p in paths):
        raise WeatherError(
            f"weather files must be a path or a list of paths (str or pathlib.Path) (got {brief(paths)})"
        )
    if not paths:
        raise WeatherError("no weather file given (expected at least one path)")
    opened: list[tuple[str, list[xr.Dataset]]] = []
    keep = _files().keep and isinstance(member, int | np.integer) and not isinstance(member, bool)
    try:
        for p in paths:
            lazy = member == "mean"  # read member group by member group, without dask (_load_mean)
            opened.append((str(p), _kept_file(Path(p)) if keep else _open_file(Path(p), lazy=lazy)))
        return GriddedWeather(
            read_fields(
                opened,
                variables=variables,
                bbox=bbox,
                time_window=time_window,
                member=member,
                margin_deg=margin_deg,
                out_of_range=out_of_range,
                files_read=True,
            )
        )
    finally:
        for _, datasets in opened if not keep else ():
            for ds in datasets:
                _close(ds)


class _OpenFiles:
    """The store's part (:mod:`pyroute_rel.store`) that owns the weather files opened here: those kept open for the
    next members (:func:`keep_files_open`), by (resolved path, size, modification time); the stored values of each
    file opened lazily with netCDF4 (:class:`_RawFile`), with the dataset it belongs to (found by that reference,
    not by an id); and how many times each file was opened (:func:`files_opened`). Emptied with the store: its files
    are closed."""

    def __init__(self, store: Any) -> None:
        self.allowed = bool(store.keep)  # (a store that keeps nothing keeps no file open)
        self.keep = False
        self.generation = 0
        self.kept: dict[tuple[str, int, int], list[xr.Dataset]] = {}
        self.raw: list[tuple[xr.Dataset, _RawFile]] = []
        self.opened: dict[str, int] = {}
        self.lock = threading.RLock()

    def close_kept(self) -> None:
        with self.lock:
            kept, self.kept = list(self.kept.values()), {}
            self.generation += 1
        for datasets in kept:
            for ds in datasets:
                self.close(ds)

    def close(self, ds: xr.Dataset) -> None:
        """Close a dataset :func:`_open_file` opened, and its :class:`_RawFile` if any."""
        with self.lock:
            raw = [r for d, r in self.raw if d is ds]
            self.raw = [(d, r) for d, r in self.raw if d is not ds]
        for r in raw:
            r.close()
        ds.close()

    def clear(self) -> None:
        self.close_kept()
        with self.lock:
            self.opened.clear()

    def raw_of(self, ds: xr.Dataset) -> _RawFile | None:
        with self.lock:
            return next((r for d, r in self.raw if d is ds), None)


def _files() -> _OpenFiles:
    return current_store().part("weather.files", _OpenFiles)


def keep_files_open(keep: bool) -> None:
    """Whether :func:`open_weather` keeps (in the current store, :mod:`pyroute_rel.store`) the files it reads one
    ensemble member from (``member = k``), for the next members: a process routing many members of one file
    (:mod:`pyroute_rel.analysis.ensemble`) opens it once and reads each member's box from it, without dask (the same
    values: the file's decoding, element by element). Either way, the files kept so far are closed (a file changed since
    is opened again: it is kept by its path, size and modification time). The ensemble mean (``member = "mean"``) opens
    its own file, read without dask as well."""
    files = _files()
    files.close_kept()
    files.keep = bool(keep) and files.allowed


def files_kept_open() -> int | None:
    """None when files are not kept open (:func:`keep_files_open`); else a number that changes whenever the kept
    files are closed (at each call of :func:`keep_files_open`, and when the store is emptied): what a caller keeps
    along with the files (:mod:`pyroute_rel.analysis.members` keeps a scenario file's settings) is dropped with them."""
    files = _files()
    return files.generation if files.keep else None


def files_opened(reset: bool = False) -> dict[str, int]:
    """How many times each weather file (resolved path) was opened to read it, in the current store (``reset``:
    count from zero again)."""
    files = _files()
    with files.lock:
        out = dict(files.opened)
        if reset:
            files.opened.clear()
    return out


def _kept_file(path: Path) -> list[xr.Dataset]:
    files = _files()
    key = cache.file_stamps([path])[0]
    with files.lock:
        datasets = files.kept.get(key)
        if datasets is None or key[1] < 0:
            for old in [k for k in files.kept if k[0] == key[0]]:  # the file as it was: closed
                for ds in files.kept.pop(old):
                    files.close(ds)
            datasets = files.kept[key] = _open_file(path, lazy=True)
    return datasets


def weather_from_dataset(
    ds: xr.Dataset,
    *,
    variables: Mapping[str, str] | None = None,
    bbox: Sequence[float] | None = None,
    time_window: Sequence[Any] | None = None,
    member: int | str | None = None,
    margin_deg: float = BBOX_MARGIN_DEG,
    source: str = "<dataset>",
    out_of_range: str = "error",
) -> GriddedWeather:
    """A :class:`GriddedWeather` from an in-memory :class:`xarray.Dataset` laid out like one of the supported files.

    Options as for :func:`open_weather`; ``source`` names the dataset in messages.

    Examples
    --------
    >>> import xarray as xr
    >>> ds = xr.Dataset(
    ...     {"u10": (("latitude", "longitude"), np.ones((2, 2)), {"units": "m s**-1"}),
    ...      "v10": (("latitude", "longitude"), np.zeros((2, 2)), {"units": "m s**-1"})},
    ...     coords={"latitude": [50.0, 40.0], "longitude": [340.0, 350.0]})
    >>> w = weather_from_dataset(ds)
    >>> c = w.sample(-15.0, 45.0, np.datetime64("2018-06-01T00:00"))
    >>> round(float(c.tws_kn), 4), float(c.twd_deg), sorted(w.fields)
    (1.9438, 270.0, ['twd_deg', 'tws_kn'])
    """
    check_instance(ds, xr.Dataset, "ds", WeatherError, expected="an xarray.Dataset")
    check_instance(source, str, "source", WeatherError)
    return GriddedWeather(
        read_fields(
            [(source, [ds])],
            variables=variables,
            bbox=bbox,
            time_window=time_window,
            member=member,
            margin_deg=margin_deg,
            out_of_range=out_of_range,
        )
    )


def weather_from_mapping(
    table: Mapping[str, Any],
    *,
    base_dir: str | os.PathLike[str],
    bbox: Sequence[float] | None = None,
    time_window: Sequence[Any] | None = None,
    where: str = "[weather]",
) -> GriddedWeather:
    """Build from a scenario's ``[weather]`` table with ``kind = "file"``.

    Keys: ``kind = "file"``, ``paths = ["a.nc", ...]`` (relative to ``base_dir``, the TOML file's folder),
    optional ``variables = {hs_m = "VHM0", ...}``, ``member = 0`` and ``out_of_range = "error"`` or ``"missing"``
    (see :func:`open_weather`). ``bbox`` and ``time_window`` are
    passed on to :func:`open_weather` (the route's box and voyage window).

    Raises :class:`~pyroute_rel.errors.ScenarioError` naming the key on a malformed table.
    """
    allowed = ("kind", "paths", "variables", "member", "out_of_range")
    for key in table:
        if key not in allowed:
            raise ScenarioError(f"{where}: unknown key {key!r} (expected one of {', '.join(allowed)})")
    if table.get("kind") != "file":
        raise ScenarioError(f"{where}.kind must be one of ['file'] here (got {table.get('kind')!r})")
    raw = table.get("paths")
    if (
        not isinstance(raw, Sequence)
        or isinstance(raw, str)
        or not raw
        or not all(isinstance(p, str) and p for p in raw)
    ):
        raise ScenarioError(f"{where}.paths must be a non-empty array of file names (got {raw!r})")
    variables = table.get("variables")
    if variables is not None:
        if not isinstance(variables, Mapping) or not all(isinstance(v, str) for v in variables.values()):
            raise ScenarioError(f'{where}.variables must be a table of field = "file variable" (got {variables!r})')
        for key in (k for k in variables if k not in VARIABLES):
            raise ScenarioError(f"{where}.variables: unknown field {key!r} (expected one of {', '.join(VARIABLES)})")
    member = table.get("member")
    if (
        member is not None
        and member != "mean"
        and (isinstance(member, bool) or not isinstance(member, int) or member < 0)
    ):
        raise ScenarioError(f'{where}.member must be an integer >= 0 or "mean" (got {member!r})')
    out_of_range = table.get("out_of_range", "error")
    if not isinstance(out_of_range, str) or out_of_range not in OUT_OF_RANGE:
        raise ScenarioError(
            f"{where}.out_of_range must be one of {list(OUT_OF_RANGE)} (what to do with implausible values) "
            f"(got {brief(out_of_range)})"
        )
    base = Path(base_dir)
    paths = [p if p.is_absolute() else base / p for p in (Path(s).expanduser() for s in raw)]
    if cache.enabled():  # a sweep's process: read every time once, keep it for the next runs (weather.cache)
        stamp = (
            "file",
            cache.file_stamps(paths),
            tuple(sorted((variables or {}).items())),
            member,
            out_of_range,
            None if bbox is None else tuple(float(b) for b in bbox),
        )
        return cache.cached(
            stamp,
            lambda: open_weather(paths, variables=variables, bbox=bbox, member=member, out_of_range=out_of_range),
            nbytes=lambda w: w.nbytes,
        )
    return open_weather(
        paths, variables=variables, bbox=bbox, time_window=time_window, member=member, out_of_range=out_of_range
    )


def ensemble_size(paths: str | os.PathLike[str] | Sequence[str | os.PathLike[str]]) -> int | None:
    """Number of ensemble members in weather files: the size of their member dimension (``number``,
    ``realization``, ``member``, ...), None when no file has one.

    Raises
    ------
    WeatherError
        A file is unreadable, or two files hold different numbers of members.
    """
    if isinstance(paths, str | os.PathLike):
        paths = [paths]
    sizes: dict[int, str] = {}
    for p in paths:
        for ds in _open_file(Path(p), lazy=True):  # the sizes only: no dask (a second of imports)
            try:
                for dim, n in ds.sizes.items():
                    if str(dim).lower() in _MEMBER_NAMES:
                        sizes.setdefault(int(n), str(p))
            finally:
                _close(ds)
    if len(sizes) > 1:
        raise WeatherError(
            "weather files hold different numbers of ensemble members: "
            + ", ".join(f"{n} in '{p}'" for n, p in sizes.items())
        )
    return next(iter(sizes), None)


# ----------------------------------------------------------------------------------------------- reading


def _open_file(path: Path, *, lazy: bool = False) -> list[xr.Dataset]:
    """The file's datasets, its variables dask arrays (``lazy``: xarray's lazily indexed arrays, nothing cached:
    a selection reads that selection; a netCDF4 file's stored values are read and decoded here, :class:`_RawFile`).
    Close them with :func:`_close`."""
    hint = ": list the NetCDF or GRIB files in it under [weather].paths"  # (a device or FIFO is never read)
    check_regular_file(path, error=WeatherError, label=f"weather file '{path}'", folder_hint=hint)
    try:
        with open(path, "rb") as fh:
            head = fh.read(8)
    except OSError as exc:
        raise WeatherError(f"cannot read weather file '{path}': {exc}") from exc
    if head.startswith(b"GRIB") or path.suffix.lower() in _GRIB_SUFFIXES:
        return _open_grib(path)
    if not (head.startswith(b"CDF") or head.startswith(b"\x89HDF\r\n\x1a\n")):
        raise WeatherError(f"weather file '{path}' is not a NetCDF or GRIB file (starts with {head[:4]!r})")
    files = _files()
    try:
        engine = "netcdf4" if find_spec("netCDF4") else ("scipy" if head.startswith(b"CDF") else "h5netcdf")
        opts: dict[str, Any] = {"chunks": None, "cache": False} if lazy else {"chunks": {}}
        if lazy and engine == "netcdf4":
            ds = _open_with_small_chunk_cache(path, opts)
            with files.lock:
                files.raw.append((ds, _RawFile(path)))  # its stored values, read and decoded here
        else:
            ds = xr.open_dataset(path, engine=engine, decode_timedelta=False, **opts)
        _count_opened(files, path)
        return [ds]
    except Exception as exc:  # netCDF4/HDF5 raise many types for damaged files
        raise WeatherError(f"cannot read weather file '{path}': {type(exc).__name__}: {exc}") from exc


#: HDF5 chunk cache of each variable of a file read without dask (a member kept open, the ensemble mean) [bytes]:
#: HDF5's own default. netCDF-C's (64 MiB a variable) would keep up to that much of decompressed chunks, each read once.
LAZY_CHUNK_CACHE_BYTES = 2**20


def _open_with_small_chunk_cache(path: Path, opts: Mapping[str, Any]) -> xr.Dataset:
    """``xr.open_dataset`` with netCDF4, its variables given a chunk cache of :data:`LAZY_CHUNK_CACHE_BYTES` (netCDF4
    sets a variable's cache when it opens the file, from the process-wide setting, put back at once)."""
    import netCDF4

    before = netCDF4.get_chunk_cache()
    netCDF4.set_chunk_cache(LAZY_CHUNK_CACHE_BYTES, before[1], before[2])
    try:
        return xr.open_dataset(path, engine="netcdf4", decode_timedelta=False, **opts)
    finally:
        netCDF4.set_chunk_cache(*before)


def _open_grib(path: Path) -> list[xr.Dataset]:
    try:
        import cfgrib  # noqa: F401
    except (ImportError, RuntimeError) as exc:  # RuntimeError: eccodes library not found
        raise WeatherError(
            f"reading GRIB file '{path}' needs cfgrib and eccodes: pip install 'pyroute_rel[grib]' ({exc})"
        ) from exc
    out = []
    with _cfgrib_quiet() as skipped:
        for keys in GRIB_FILTERS:
            try:
                ds = xr.open_dataset(
                    path, engine="cfgrib", decode_timedelta=True,
                    backend_kwargs={"filter_by_keys": dict(keys), "indexpath": ""},
                )  # fmt: skip
            except Exception as exc:
                raise WeatherError(f"cannot read GRIB file '{path}': {type(exc).__name__}: {exc}") from exc
            if ds.data_vars:
                out.append(ds)
            else:
                ds.close()
    if skipped:
        warnings.warn(
            f"GRIB file '{path}': {len(skipped)} corrupted message(s) skipped by cfgrib ({skipped[0]})",
            WeatherWarning,
            stacklevel=3,
        )
    _count_opened(_files(), path)
    return out


@contextmanager
def _cfgrib_quiet() -> Iterator[list[str]]:
    """cfgrib's log while a file is opened, held back (issue 34: a corrupt file printed cfgrib's traceback through its
    logger before the one-line error); yields the messages it logged, for one warning."""
    logger = logging.getLogger("cfgrib")
    seen: list[str] = []

    class _Hold(logging.Handler):
        def emit(self, record: logging.LogRecord) -> None:
            seen.append(" ".join(record.getMessage().split())[:120])

    hold, before = _Hold(), logger.propagate
    logger.addHandler(hold)
    logger.propagate = False
    try:
        yield seen
    finally:
        logger.removeHandler(hold)
        logger.propagate = before


def _count_opened(files: _OpenFiles, path: Path) -> None:
    name = str(path.resolve())
    with files.lock:
        files.opened[name] = files.opened.get(name, 0) + 1


def _close(ds: xr.Dataset) -> None:
    """Close a dataset :func:`_open_file` opened, and its :class:`_RawFile` if any."""
    _files().close(ds)


#: What netCDF4, HDF5 and xarray's CF decoding raise for a file they cannot read or decode (a damaged chunk is an
#: OSError or RuntimeError, odd packing attributes a ValueError); anything else is a bug of ours and propagates.
FILE_ERRORS = (OSError, RuntimeError, ValueError)


class _RawFile:
    """The stored values (packed integers, fill values: as in the file) of the variables of a netCDF4 file xarray
    opened lazily, read with netCDF4 and decoded here exactly as xarray decodes them (:class:`_RawVariable`): the
    same numbers, without xarray's indexing (most of a member's reading time besides the decompression) or the
    import of dask its first selection brings (a second). Opened at the first read; keeps each variable's
    :class:`_RawVariable`, reading plans (:class:`_Plan`) and the variables found (:func:`_detect`) for the next
    member, until closed."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.plans: dict[tuple[Any, ...], _Plan] = {}
        self.detected: dict[tuple[Any, ...], dict[str, tuple[xr.Dataset, str]]] = {}
        self._nc: Any = None
        self._variables: dict[str, _RawVariable | None] = {}

    def variable(self, var: str, array: Callable[[], xr.DataArray]) -> _RawVariable | None:
        """The variable ``var`` of the file (``array()``: as xarray decodes it), or None when it is not read here (not
        stored as numbers on its dimensions, or not decoded to its type)."""
        if var not in self._variables:
            da = array()
            try:
                with _NETCDF4_LOCK:
                    self._variables[var] = _raw_variable(self._open(), var, da)
            except FILE_ERRORS:  # the file's trouble, not ours: xarray reads it (and says what is wrong)
                self._variables[var] = None
        return self._variables[var]

    def _open(self) -> Any:
        if self._nc is None:
            import netCDF4

            before = netCDF4.get_chunk_cache()
            netCDF4.set_chunk_cache(LAZY_CHUNK_CACHE_BYTES, before[1], before[2])
            try:
                self._nc = netCDF4.Dataset(self.path, "r")
            finally:
                netCDF4.set_chunk_cache(*before)
        return self._nc

    def close(self) -> None:
        self.plans.clear()
        self.detected.clear()
        self._variables.clear()
        if self._nc is not None:
            with _NETCDF4_LOCK:
                self._nc.close()
            self._nc = None


def _netcdf4_lock() -> Any:
    """The lock xarray's netCDF4 backend takes around netCDF4 and HDF5 calls (the libraries are not thread-safe):
    ours must be the same, so that a file read here and one xarray reads in another thread never call HDF5 at once.
    xarray has no public name for it; the tested versions are pinned in pyproject.toml and
    ``tests/test_fast_read.py`` checks that the backend still holds this lock."""
    from xarray.backends.netCDF4_ import NETCDF4_PYTHON_LOCK

    return NETCDF4_PYTHON_LOCK


_NETCDF4_LOCK = _netcdf4_lock()


@dataclass(frozen=True)
class _RawVariable:
    """A variable's stored values and how xarray decodes them.

    Attributes
    ----------
    variable : The netCDF4 variable, returning stored values (no masking or scaling).
    dims : Its dimensions.
    stored : Type of its stored values (native byte order).
    attrs : Its attributes, as xarray's netCDF4 backend hands them to the CF decoding.
    table : For 8- and 16-bit integers: the decoded value of every stored value (indexed by its bits read as an
        unsigned integer, :meth:`codes`); else None (the values read are decoded).
    """

    variable: Any
    dims: tuple[str, ...]
    stored: np.dtype[Any]
    attrs: dict[str, Any]
    table: npt.NDArray[Any] | None

    def read(self, selectors: Mapping[Hashable, Any], dims: Sequence[Hashable]) -> npt.NDArray[Any]:
        """The stored values of a selection (along each of the variable's dimensions an integer, a slice or sorted
        unique indices; all of a dimension not given), on ``dims`` in that order (a dimension of ``dims`` the
        variable lacks, the ``_time`` added to a field without time, gets length 1)."""
        key = tuple(selectors.get(d, slice(None)) for d in self.dims)
        with _NETCDF4_LOCK:
            values = np.asarray(self.variable[key])
        if values.dtype != self.stored:
            values = values.astype(self.stored)
        kept = [d for d, k in zip(self.dims, key, strict=True) if not isinstance(k, int | np.integer)]
        values = values.transpose([kept.index(d) for d in dims if d in kept])  # type: ignore[arg-type]
        for axis, d in enumerate(dims):
            if d not in kept:
                values = np.expand_dims(values, axis)
        return values

    def codes(self, values: npt.NDArray[Any]) -> npt.NDArray[Any]:
        """Stored 8- or 16-bit integers as indices into :attr:`table`."""
        return values.view(np.dtype(f"u{self.stored.itemsize}"))

    def decode(self, values: npt.NDArray[Any]) -> npt.NDArray[Any]:
        """Stored values decoded (xarray's numbers)."""
        if self.table is not None:
            return np.take(self.table, self.codes(values))
        return _decode_stored(values, self.attrs, self.variable.name)


def _raw_variable(nc: Any, var: str, da: xr.DataArray) -> _RawVariable | None:
    """The :class:`_RawVariable` of ``var`` in an open netCDF4 file, or None when it is not read here."""
    v = nc.variables.get(var)
    if v is None or tuple(v.dimensions) != tuple(map(str, da.dims)) or tuple(v.shape) != tuple(da.shape):
        return None
    stored = v.dtype
    if not isinstance(stored, np.dtype) or stored.kind not in "iuf":
        return None
    stored = stored.newbyteorder("=")
    v.set_auto_maskandscale(False)  # as xarray's netCDF4 backend reads it
    v.set_auto_chartostring(False)
    attrs = {k: v.getncattr(k) for k in v.ncattrs()}
    attrs.pop("least_significant_digit", None)  # (moved to the encoding by the backend)
    table = None
    if stored.kind in "iu" and stored.itemsize <= 2:
        table = _decode_stored(
            np.arange(1 << (8 * stored.itemsize)).astype(f"u{stored.itemsize}").view(stored), attrs, var
        )
        decoded = table.dtype
    else:
        decoded = _decode_stored(np.zeros(1, stored), attrs, var).dtype
    if decoded != da.dtype or decoded.kind not in "iuf":
        return None
    return _RawVariable(v, tuple(v.dimensions), stored, attrs, table)


def _decode_stored(values: npt.NDArray[Any], attrs: Mapping[str, Any], name: str) -> npt.NDArray[Any]:
    """Stored values decoded by xarray's CF decoding (fill values, ``scale_factor``, ``add_offset``, ``_Unsigned``)
    with the options :func:`_open_file` opens files with: element by element, the numbers xarray reads."""
    # fastpath: the values taken as they are (a parameter of the constructor's signature; without it xarray's check
    # for chunked arrays imports dask, a second, which the members read here never need)
    variable = xr.Variable(tuple(f"_{k}" for k in range(values.ndim)), values, dict(attrs), fastpath=True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # (xarray warned when it opened the file)
        decoded = xr.conventions.decode_cf_variable(name, variable, concat_characters=False, decode_timedelta=False)
    return np.asarray(decoded.values)


def _read_stored(
    stored: _RawVariable, selectors: Mapping[Hashable, Any], dims: Sequence[Hashable], where: str
) -> npt.NDArray[Any]:
    """:meth:`_RawVariable.read`, a failure a WeatherError."""
    try:
        return stored.read(selectors, dims)
    except Exception as exc:  # netCDF4/HDF5 raise many types for damaged files
        raise WeatherError(f"cannot read {where}: {type(exc).__name__}: {exc}") from exc


def read_fields(
    files: list[tuple[str, list[xr.Dataset]]],
    *,
    variables: Mapping[str, str] | None = None,
    bbox: Sequence[float] | None = None,
    time_window: Sequence[Any] | None = None,
    member: int | str | None = None,
    margin_deg: float | None = None,
    out_of_range: str = "error",
    files_read: bool = False,
) -> list[WeatherField]:
    """Find, cut, convert, check and merge every field of opened files, ``[(name, [datasets]), ...]``.

    Options as for :func:`open_weather`; ``margin_deg`` defaults to :data:`BBOX_MARGIN_DEG`. Fields that each have
    a single time come back without time (steady), with a :class:`~pyroute_rel.errors.WeatherWarning`; so do
    ``files_read`` (files, not datasets made in code) without any time.
    """
    variables, box, window, margin_deg = _check_options(
        files, variables, bbox, time_window, member, margin_deg, out_of_range
    )
    parts: dict[str, list[WeatherField]] = {}
    dropped: dict[str, list[str]] = {}
    used_member = False
    for source, datasets in files:
        found = _detected(source, datasets, variables)
        for name, (ds, var) in found.items():
            field, had_members = _extract(
                _variable(ds, var), name, source, var, box, window, member, margin_deg, out_of_range,
                raw=_files().raw_of(ds),
            )  # fmt: skip
            used_member |= had_members
            if field is None:
                covered = ""
                tname = next((c for c in ("time", "valid_time") if c in ds[var].coords), None)
                if tname is not None and ds[var][tname].size:
                    tv = np.asarray(ds[var][tname].values).astype("datetime64[m]")
                    covered = f" (it covers {iso_minute(tv.min())} .. {iso_minute(tv.max())})"
                dropped.setdefault(name, []).append(f"'{source}' variable '{var}'{covered}")
            else:
                parts.setdefault(name, []).append(field)
    if member is not None and not used_member:
        raise WeatherError(
            f"member={member} was given but no file has an ensemble dimension ({', '.join(_MEMBER_NAMES)})"
        )
    for name, sources in dropped.items():
        if name not in parts:
            raise WeatherCoverageError(
                f"weather {', '.join(sources)} has no time in the requested window "
                f"{iso_minute(window[0])} .. {iso_minute(window[1])}"  # type: ignore[index]
            )
    merged = {name: _join_in_time(name, fields) for name, fields in parts.items()}
    _speed_direction_to_uv(merged)
    for u, v, what in (("wind_u_ms", "wind_v_ms", "wind"), ("current_u_ms", "current_v_ms", "current")):
        if (u in merged) != (v in merged):
            have = merged.get(u) or merged[v]
            raise WeatherError(
                f"weather file '{have.source}' variable '{have.variable}' gives one {what} component but the "
                f"other ({v if u in merged else u}) was not found; name it with variables={{...}}"
            )
    return _steady_if_single_time(list(merged.values()), files_read)


def _check_options(
    files: list[tuple[str, list[xr.Dataset]]],
    variables: Any,
    bbox: Any,
    time_window: Any,
    member: Any,
    margin_deg: Any,
    out_of_range: Any,
) -> tuple[dict[str, str], tuple[float, float, float, float] | None, tuple[np.datetime64, np.datetime64] | None, float]:
    """The options of :func:`read_fields` checked -> (variables, box, time window, margin [deg])."""
    if not isinstance(out_of_range, str) or out_of_range not in OUT_OF_RANGE:
        raise WeatherError(f"out_of_range must be one of {list(OUT_OF_RANGE)} (got {brief(out_of_range)})")
    margin_deg = BBOX_MARGIN_DEG if margin_deg is None else margin_deg
    margin = check_numbers(margin_deg, "margin_deg", WeatherError, missing=False, unit="deg")
    if margin.shape != () or margin < 0:
        raise WeatherError(f"margin_deg must be a finite number >= 0 [deg] (got {brief(margin_deg)})")
    if variables is not None:
        check_instance(variables, Mapping, "variables", WeatherError, expected='a dict {field: "file variable"}')
    if (
        member is not None
        and not (isinstance(member, str) and member == "mean")
        and (isinstance(member, bool) or not isinstance(member, (int, np.integer)) or member < 0)
    ):
        raise WeatherError(f'member must be an integer >= 0 or "mean" (got {brief(member)})')
    variables = dict(variables or {})
    for key, name in variables.items():
        if not isinstance(name, str):
            raise WeatherError(f"variables[{brief(key)}] must be the name of a file variable (got {brief(name)})")
        if key not in VARIABLES:
            raise WeatherError(f"variables: field must be one of {list(VARIABLES)} (got {key!r})")
        if not any(name in ds.data_vars for _, dss in files for ds in dss):
            where = ", ".join(f"'{s}'" for s, _ in files)
            raise WeatherError(f"variables[{key!r}] = {name!r}: no such variable in {where}")
    box = _check_bbox(bbox)
    window = None
    if time_window is not None:
        if not isinstance(time_window, (list, tuple, np.ndarray)) or len(time_window) != 2:
            raise WeatherError(f"time_window must be a pair (first, last) (got {brief(time_window)})")
        window = (to_datetime64(time_window[0], "time_window"), to_datetime64(time_window[1], "time_window"))
        if window[1] < window[0]:
            raise WeatherError(f"time_window must have first <= last (got {brief(time_window)})")
    return variables, box, window, float(margin)


def _steady_if_single_time(fields: list[WeatherField], files_read: bool) -> list[WeatherField]:
    """Fields that each have a single time (an analysis; one forecast step) -> the same fields steady (no time),
    with a warning saying so once; any field with several times leaves them all as they are. Files read
    (``files_read``) without any time are steady too, which a warning says (a dataset made in code is quiet)."""
    singles = [f for f in fields if f.time is not None]
    if not singles:  # no field has a time axis: steady, said for files as for a single time (issue 34)
        sources = sorted({f.source for f in fields})
        if files_read and sources:
            warnings.warn(
                f"weather {', '.join(map(repr, sources))} has no time axis: taken as steady weather, used at all "
                "times of the voyage",
                WeatherWarning,
                stacklevel=3,
            )
        return fields
    if any(f.time.size != 1 for f in singles):  # type: ignore[union-attr]
        return fields
    times = sorted({iso_minute(f.time[0]) for f in singles})  # type: ignore[index]
    sources = sorted({f.source for f in singles})
    warnings.warn(
        f"weather {', '.join(map(repr, sources))} has a single time ({', '.join(times)}): taken as steady weather, "
        "used at all times of the voyage",
        WeatherWarning,
        stacklevel=3,
    )
    return [replace(f, time=None) for f in fields]


def _variable(ds: xr.Dataset, var: str) -> Callable[[], xr.DataArray]:
    """``ds[var]``, asked for when called."""
    return lambda: ds[var]


def _detected(
    source: str, datasets: list[xr.Dataset], variables: Mapping[str, str]
) -> dict[str, tuple[xr.Dataset, str]]:
    """:func:`_detect`, kept with a file's stored values (:class:`_RawFile`) for the next member."""
    raw = _files().raw_of(datasets[0]) if len(datasets) == 1 else None
    if raw is None:
        return _detect(source, datasets, variables)
    key = (source, tuple(sorted(variables.items())))
    found = raw.detected.get(key)
    if found is None:
        found = raw.detected[key] = _detect(source, datasets, variables)
    return dict(found)


def _detect(source: str, datasets: list[xr.Dataset], variables: Mapping[str, str]) -> dict[str, tuple[xr.Dataset, str]]:
    """Which variable of which dataset of one file gives each field."""
    found: dict[str, tuple[xr.Dataset, str]] = {}
    for name in VARIABLES:
        if name in variables:
            hit = next((ds for ds in datasets if variables[name] in ds.data_vars), None)
            if hit is not None:
                found[name] = (hit, variables[name])
            continue
        for ds in datasets:
            lower = {str(v).lower(): str(v) for v in ds.data_vars}
            var = next((lower[c] for c in _NAMES[name] if c in lower), None)
            if var is None:
                by_std = [str(v) for v in ds.data_vars if ds[v].attrs.get("standard_name") in _STANDARD_NAMES[name]]
                if len(by_std) > 1:
                    raise WeatherError(
                        f"weather file '{source}': variables {by_std} all look like {name} "
                        f"({VARIABLES[name]}); choose one with variables={{'{name}': ...}}"
                    )
                var = by_std[0] if by_std else None
            if var is not None:
                found[name] = (ds, var)
                break
    if "wind_u_ms" in found or "wind_v_ms" in found:  # u/v win over speed/direction
        found.pop("tws_kn", None)
        found.pop("twd_deg", None)
    return found


def _dim_kind(da: xr.DataArray, dim: Hashable) -> str:
    name = str(dim).lower()
    coord = da.coords.get(dim)
    attrs = coord.attrs if coord is not None else {}
    std = str(attrs.get("standard_name", "")).lower()
    units = str(attrs.get("units", "")).lower().replace(" ", "_")
    if name in _LON_NAMES or std == "longitude" or units in ("degrees_east", "degree_east", "degree_e"):
        return "lon"
    if name in _LAT_NAMES or std == "latitude" or units in ("degrees_north", "degree_north", "degree_n"):
        return "lat"
    if name in _TIME_NAMES or std == "time" or (coord is not None and coord.dtype.kind in "Mm"):
        return "time"
    if name in _MEMBER_NAMES:
        return "member"
    if name in _DEPTH_NAMES or std == "depth":
        return "depth"
    return "other"


def _extract(
    array: Callable[[], xr.DataArray],
    name: str,
    source: str,
    var: str,
    box: tuple[float, float, float, float] | None,
    window: tuple[np.datetime64, np.datetime64] | None,
    member: int | str | None,
    margin: float,
    out_of_range: str = "error",
    *,
    raw: _RawFile | None = None,
) -> tuple[WeatherField | None, bool]:
    """Cut one variable to the box and window, load it, convert units, check its values -> (field or None, had
    members). A variable with a single time is kept whatever the window (it may be steady weather).

    ``array``: the variable, as xarray reads it (not asked for when a kept plan reads the stored values). ``raw``:
    the file's stored values (:class:`_RawFile`), read and decoded here when the variable allows it (the same numbers
    as xarray's), its plan kept for the next member."""
    stored = raw.variable(var, array) if raw is not None else None
    key = (source, var, name, box, window, margin, member == "mean")
    plan = raw.plans.get(key) if raw is not None and stored is not None else None
    da: Any = None
    if plan is None:
        plan, da = _plan(array(), name, source, var, box, window, member, margin, stored)
        if stored is not None and plan.fixed is not None and not plan.member_dims:
            raw.plans[key] = plan  # type: ignore[union-attr]
    elif plan.member_dim is not None:  # a kept plan: the member checked as _drop_extra_dims does
        _member_index(plan.member_dim[0], plan.member_dim[1], member, plan.where)
    if plan.index is None:
        return None, plan.had_members
    raw_read = None if stored is None or plan.fixed is None else _Stored(stored, _fixed_with_member(plan, member))
    if plan.member_dims:  # each member's values outside the valid range are missing before the mean
        values = _load_mean(
            array() if da is None else da, plan.member_dims, plan.dims, plan.index, plan.where, plan.valid, raw_read
        )
    elif raw_read is not None and plan.tables is not None:
        coded = _finish_coded(plan, raw_read.variable, raw_read.fixed, name, source, var, out_of_range)
        return coded, plan.had_members
    elif raw_read is not None:
        stored, fixed = raw_read
        selectors, inverse = plan.selection
        values = _reorder(stored.decode(_read_stored(stored, {**fixed, **selectors}, plan.dims, plan.where)), inverse)
        values = values.astype(np.float32, copy=False)
    else:
        values = _load(array() if da is None else da, plan.dims, plan.index, plan.where)
    values = _in_units(values, plan, name)
    return _finish(values, plan, name, source, var, out_of_range), plan.had_members


@dataclass(frozen=True)
class _Plan:
    """How one variable of a file is read, whatever member: where (for messages), valid range, attributes, the
    (time, lat, lon) dimensions and the indices to read along them (``index`` None: no time in the window), the
    field's axes, the member dimensions averaged (the mean), the index fixed along every other dimension of the
    variable (None: read through xarray only), the member dimension and its size, and (variables stored as 8- or
    16-bit integers) the field's value for every stored value, as read and with directions normalised."""

    where: str
    valid: tuple[float, float] | None
    attrs: Mapping[Hashable, Any]
    dims: tuple[Hashable, Hashable, Hashable]
    index: tuple[IntArray, ...] | None
    times: npt.NDArray[np.datetime64] | None
    lon: FloatArray
    lat: FloatArray
    periodic: bool
    member_dims: list[Hashable]
    had_members: bool
    cut: bool
    fixed: dict[Hashable, int] | None = None
    member_dim: tuple[Hashable, int] | None = None
    tables: tuple[npt.NDArray[np.float32], npt.NDArray[np.float32]] | None = None
    selection: tuple[dict[Hashable, Any], list[IntArray | None]] = ({}, [])  # _selectors of dims and index


def _plan(
    da: xr.DataArray,
    name: str,
    source: str,
    var: str,
    box: tuple[float, float, float, float] | None,
    window: tuple[np.datetime64, np.datetime64] | None,
    member: int | str | None,
    margin: float,
    stored: _RawVariable | None = None,
) -> tuple[_Plan, xr.DataArray]:
    """The variable's :class:`_Plan` (its tables when ``stored`` has a table) and the variable cut to one member (and
    depth), on (time, lat, lon) and the member dimensions of a mean."""
    where = f"weather file '{source}' variable '{var}'"
    valid = valid_range(da, where)  # before any selection: attributes and encoding as the file has them
    kinds = {d: _dim_kind(da, d) for d in da.dims}
    member_dim = next(((d, int(da.sizes[d])) for d, k in kinds.items() if k == "member"), None)
    da, had_members, fixed = _drop_extra_dims(da, kinds, member, where)
    if member_dim is not None and fixed is not None:
        fixed.pop(member_dim[0], None)  # the member is put in at each read (_fixed_with_member)
    lon_dim, lat_dim, time_dims = ([d for d in da.dims if kinds[d] == kind] for kind in ("lon", "lat", "time"))
    if len(lon_dim) != 1 or len(lat_dim) != 1 or lon_dim[0] not in da.coords or lat_dim[0] not in da.coords:
        raise WeatherError(
            f"{where} is not on a regular longitude/latitude grid (dimensions {list(da.dims)}; expected 1-D "
            f"'longitude'/'lon' and 'latitude'/'lat' coordinates)"
        )
    lon_dim_, lat_dim_ = lon_dim[0], lat_dim[0]
    da, tdim, times = _time_axis(da, time_dims, where)
    # index plans
    lon_plan = _lon_plan(np.asarray(da[lon_dim_].values, dtype=float), box, margin)
    lat_plan = _sorted_plan(np.asarray(da[lat_dim_].values, dtype=float), box and (box[1], box[3]), margin)
    if lon_plan is None or lat_plan is None:
        x, y = np.asarray(da[lon_dim_].values), np.asarray(da[lat_dim_].values)
        raise WeatherCoverageError(
            f"{where} covers lon [{x.min():g}, {x.max():g}], lat [{y.min():g}, {y.max():g}] [deg], outside the "
            f"requested box lon [{box[0]:g}, {box[2]:g}], lat [{box[1]:g}, {box[3]:g}]"  # type: ignore[index]
        )
    if lat_plan[1].size < 2 or lon_plan[1].size < 2:
        raise WeatherError(f"{where} needs at least two latitudes and two longitudes")
    t_index = np.arange(da.sizes[tdim])
    plan = _Plan(
        where, valid, dict(da.attrs), (tdim, lat_dim_, lon_dim_), None, times, lon_plan[1], lat_plan[1],
        lon_plan[2], [d for d in da.dims if kinds.get(d) == "member"] if member == "mean" else [], had_members,
        bool(box or window), fixed, member_dim,
    )  # fmt: skip
    if times is not None and times.size > 1:
        t_plan = _time_plan(times, window, where)
        if t_plan is None:
            return plan, da
        t_index, times = t_plan
    if times is not None and np.isnat(times).any():
        raise WeatherError(f"{where} has missing (NaT) times")
    index = (t_index, lat_plan[0], lon_plan[0])
    plan = replace(plan, index=index, times=times, selection=_selectors(plan.dims, index))
    if stored is not None and stored.table is not None and fixed is not None and not plan.member_dims:
        table = _in_units(stored.table.astype(np.float32, copy=False), plan, name)  # every stored value, as read
        plan = replace(plan, tables=(table, _normalise_direction(table, plan.attrs, name)))
    return plan, da


def _in_units(values: npt.NDArray[np.float32], plan: _Plan, name: str) -> npt.NDArray[np.float32]:
    """Values read (float32): outside the declared valid range missing (a mean's members had it applied), in the
    units of the field (element by element: applied to the data, or to a table of every stored value)."""
    if plan.valid is not None and not plan.member_dims:  # outside the declared valid range: missing, like a fill value
        lo, hi = np.float64(plan.valid[0]), np.float64(plan.valid[1])
        values = np.where((values < lo) | (values > hi), np.float32(np.nan), values).astype(np.float32, copy=False)
    return _convert_units(values, plan.attrs, name, plan.where)


def _finish(
    values: npt.NDArray[np.float32],
    plan: _Plan,
    name: str,
    source: str,
    var: str,
    out_of_range: str,
    normalised: Callable[[], CodedValues] | None = None,
) -> WeatherField:
    """The field of values in its units: checked (:func:`check_plausible`), directions normalised (``normalised``:
    they are, looked up by code, as long as no value was made missing), refused when all NaN."""
    field = WeatherField(name, values, plan.lon, plan.lat, plan.times, source, var, plan.periodic)
    checked = check_plausible(field, out_of_range=out_of_range)
    coded = None
    if normalised is not None and checked is field:
        coded = normalised()
        values = coded.values
    else:
        values = _normalise_direction(checked.values, plan.attrs, name)  # type: ignore[arg-type]
    if not np.isfinite(values).any():
        raise WeatherError(f"{plan.where} is all NaN{' inside the requested box and time window' if plan.cut else ''}")
    return replace(checked, values=values, coded=coded)


def _finish_coded(
    plan: _Plan,
    stored: _RawVariable,
    fixed: Mapping[Hashable, Any],
    name: str,
    source: str,
    var: str,
    out_of_range: str,
) -> WeatherField:
    """:func:`_finish` for a variable of 8- or 16-bit integers: its stored values read, each looked up in the plan's
    tables (the field's value for every stored value: the same numbers as decoding, converting and normalising
    each)."""
    selectors, inverse = plan.selection
    read = stored.codes(_read_stored(stored, {**fixed, **selectors}, plan.dims, plan.where))
    table, normalised = plan.tables  # type: ignore[misc]
    quick = _finish_looked_up(plan, read, inverse, table, normalised, name, source, var)
    if quick is not None:
        return quick
    codes = _reorder(read, inverse)
    values = np.take(table, codes)
    if _KIND[name] != "direction":
        return _finish(values, plan, name, source, var, out_of_range)
    later = lambda: CodedValues(np.take(normalised, codes), codes, normalised)  # noqa: E731
    return _finish(values, plan, name, source, var, out_of_range, later)


def _finish_looked_up(
    plan: _Plan,
    codes: npt.NDArray[np.unsignedinteger],
    inverse: Sequence[IntArray | None],
    table: npt.NDArray[np.float32],
    normalised: npt.NDArray[np.float32],
    name: str,
    source: str,
    var: str,
) -> WeatherField | None:
    """:func:`_finish_coded` in one pass over the codes read (``inverse``: as :func:`_reorder` reorders them) when
    every value is plausible and some finite (else None: :func:`_finish` says what is wrong): each code looked up
    (:func:`sampling.look_up_codes`) into an array laid out (lat, lon, time), the layout of
    :class:`~pyroute_rel.weather.gridded.GriddedWeather`'s blocks, the field's values its (time, lat, lon) view; the
    same numbers."""
    if codes.ndim != 3 or codes.size == 0 or table.dtype != np.float32 or normalised.dtype != np.float32:
        return None
    it, iy, ix = (
        np.arange(n) if k is None else np.asarray(k, dtype=np.intp) for n, k in zip(codes.shape, inverse, strict=True)
    )
    direction = _KIND[name] == "direction"
    lookup = normalised if direction else table
    values, kept, lo, hi, finite = sampling.look_up_codes(codes, it, iy, ix, table, lookup, direction)
    rng = RANGES[name]
    if lo < rng.lo or hi > rng.hi or not finite:  # (NaN only when all NaN; check_plausible's test)
        return None
    values = values.transpose(2, 0, 1)
    coded = CodedValues(values, kept.transpose(2, 0, 1), lookup) if direction else None
    return WeatherField(name, values, plan.lon, plan.lat, plan.times, source, var, plan.periodic, coded=coded)


def _fixed_with_member(plan: _Plan, member: int | str | None) -> dict[Hashable, Any]:
    """The index along every dimension but (time, lat, lon) (and a mean's members): the plan's, plus the member's."""
    fixed: dict[Hashable, Any] = dict(plan.fixed or {})
    if plan.member_dim is not None and not plan.member_dims:
        fixed[plan.member_dim[0]] = _member_index(plan.member_dim[0], plan.member_dim[1], member, plan.where)
    return fixed


def _member_index(dim: Hashable, n: int, member: int | str | None, where: str) -> int:
    """The position of ``member`` along the member dimension ``dim`` of size ``n`` (None: its only member)."""
    if member is None and n > 1:
        raise WeatherError(f"{where} has {n} ensemble members (dimension '{dim}'); choose one with member=<0..{n - 1}>")
    index = 0 if member is None else member
    if not 0 <= index < n:  # type: ignore[operator]
        raise WeatherError(f"{where}: member must be in [0, {n - 1}] (got {member})")
    return int(index)  # type: ignore[arg-type]


def valid_range(da: xr.DataArray, where: str) -> tuple[float, float] | None:
    """The CF ``valid_range`` (or ``valid_min`` / ``valid_max``) of a variable in its unpacked units, or None.

    As the CF conventions (section 2.5.1) and the netCDF user guide say, these bounds are in the packed data's units
    when the variable is packed (``scale_factor`` / ``add_offset``, which xarray moved to ``encoding`` when it
    unpacked the values); ``valid_range`` wins over ``valid_min`` / ``valid_max``. Values outside are missing.
    """

    def number(key: str, value: Any) -> float:
        try:
            x = float(value)
        except (TypeError, ValueError):
            x = float("nan")
        if np.isnan(x):
            raise WeatherError(f"{where} has a {key} attribute that is not a number (got {brief(value)})")
        return x

    attrs = da.attrs
    if "valid_range" in attrs:
        pair = np.atleast_1d(np.asarray(attrs["valid_range"], dtype=object)).ravel()
        if pair.size != 2:
            raise WeatherError(
                f"{where}: valid_range must be two numbers [min, max] (got {brief(attrs['valid_range'])})"
            )
        lo, hi = number("valid_range", pair[0]), number("valid_range", pair[1])
    elif "valid_min" in attrs or "valid_max" in attrs:
        lo = number("valid_min", attrs["valid_min"]) if "valid_min" in attrs else -np.inf
        hi = number("valid_max", attrs["valid_max"]) if "valid_max" in attrs else np.inf
    else:
        return None
    if lo > hi:
        raise WeatherError(f"{where}: the valid range has min {lo:g} > max {hi:g}")
    packing = da.encoding  # unpacked by xarray; packing attributes still in attrs mean values are still packed
    scale = number("scale_factor", packing.get("scale_factor", 1.0)) if "scale_factor" not in attrs else 1.0
    offset = number("add_offset", packing.get("add_offset", 0.0)) if "add_offset" not in attrs else 0.0
    lo, hi = lo * scale + offset, hi * scale + offset
    return (min(lo, hi), max(lo, hi))


def _drop_extra_dims(
    da: xr.DataArray, kinds: Mapping[Hashable, str], member: int | str | None, where: str
) -> tuple[xr.DataArray, bool, dict[Hashable, int] | None]:
    """Pick the ensemble member, the shallowest depth and ERA5's merged ``expver``; refuse other dimensions of more
    than one value -> (the variable on lon, lat and time only, whether it had members, the index taken along each
    dimension dropped: None when ``expver`` was merged)."""
    had_members = False
    fixed: dict[Hashable, int] | None = {}
    for dim, kind in kinds.items():
        n = da.sizes[dim]
        if kind == "member":
            had_members = True
            if member == "mean":  # kept: averaged by _load_mean once the box and window are cut
                continue
            index = _member_index(dim, n, member, where)
        elif kind == "depth":
            depth = np.asarray(da[dim].values, dtype=float) if dim in da.coords else np.arange(n, dtype=float)
            index = int(np.nanargmin(np.abs(depth)))  # the shallowest level
        elif kind == "other" and str(dim).lower() == "expver":  # ERA5 + ERA5T: each time is in one of them
            parts = [da.isel({dim: k}).drop_vars([dim], errors="ignore") for k in range(n)]
            da = parts[0]
            for part in parts[1:]:
                da = da.fillna(part)
            fixed = None
            continue
        elif kind == "other":
            if n != 1:
                raise WeatherError(
                    f"{where} has an unexpected dimension '{dim}' of size {n} "
                    f"(expected time, latitude, longitude and optionally number and depth)"
                )
            index = 0
        else:
            continue
        da = _take(da, dim, index)
        if fixed is not None:
            fixed[dim] = index
    return da, had_members, fixed


def _take(da: xr.DataArray, dim: Hashable, index: int) -> xr.DataArray:
    """``da.isel({dim: index})``, the coordinates along ``dim`` alone (not dates) dropped first: nothing reads them
    afterwards, and selecting them makes xarray import dask.array (a second) for its duck-array checks."""
    drop = [c for c, v in da.coords.items() if v.dims == (dim,) and v.dtype.kind != "M"]
    return da.drop_vars(drop).isel({dim: index})


def _time_axis(
    da: xr.DataArray, time_dims: list[Hashable], where: str
) -> tuple[xr.DataArray, Hashable, npt.NDArray[np.datetime64] | None]:
    """The variable with one time dimension (a length-1 ``_time`` added when it has none), its name, and the valid
    times (``datetime64[ns]``; None for a field without time)."""
    if len(time_dims) > 1:
        raise WeatherError(f"{where} has several time dimensions {time_dims}; give one valid time per field")
    valid = None
    for cname in ("valid_time", "time", *[str(c) for c in da.coords]):
        c = da.coords.get(cname)
        if c is not None and c.dtype.kind == "M" and set(c.dims) <= set(time_dims):
            valid = c
            break
    if time_dims:
        tdim = time_dims[0]
        if valid is None or valid.ndim != 1:
            raise WeatherError(f"{where}: time dimension '{tdim}' has no decodable date coordinate")
        return da, tdim, np.asarray(valid.values).astype("datetime64[ns]")
    tdim = "_time"
    da = da.expand_dims(tdim)
    return da, tdim, None if valid is None else np.asarray([valid.values]).astype("datetime64[ns]")


def _time_plan(
    times: npt.NDArray[np.datetime64], window: tuple[np.datetime64, np.datetime64] | None, where: str
) -> tuple[IntArray, npt.NDArray[np.datetime64]] | None:
    """The time indices to read (in order) and their times, or None when no time falls in the window."""
    if np.isnat(times).any():
        raise WeatherError(f"{where} has missing (NaT) times")
    t_plan = _sorted_plan(
        times.astype(np.int64), window and (int(window[0].astype(np.int64)), int(window[1].astype(np.int64))), 0
    )
    if t_plan is None:
        return None
    if np.any(np.diff(np.sort(times.astype(np.int64))) == 0):
        raise WeatherError(f"{where} has repeated times")
    return t_plan[0], t_plan[1].astype("datetime64[ns]")


def _load(
    da: xr.DataArray, dims: tuple[Hashable, Hashable, Hashable], index: tuple[IntArray, ...], where: str
) -> npt.NDArray[np.float32]:
    """Read only the needed rows/columns (sorted, unique; slices where contiguous), then reorder."""
    selectors, inverse = _selectors(dims, index)
    values = _read(da, selectors, dims, where).astype(np.float32, copy=False)
    return _reorder(values, inverse)


def _selectors(
    dims: Sequence[Hashable], index: Sequence[IntArray]
) -> tuple[dict[Hashable, Any], list[IntArray | None]]:
    """What to read along each dimension (the sorted unique indices; a slice where contiguous), and how to put the
    values read back in the order of ``index`` (None: already in order)."""
    selectors: dict[Hashable, Any] = {}
    inverse: list[IntArray | None] = []
    for dim, idx in zip(dims, index, strict=True):
        uniq, inv = np.unique(idx, return_inverse=True)
        contiguous = uniq.size == uniq[-1] - uniq[0] + 1
        selectors[dim] = slice(int(uniq[0]), int(uniq[-1]) + 1) if contiguous else uniq
        inverse.append(None if np.array_equal(inv, np.arange(inv.size)) else inv)
    return selectors, inverse


class _Stored(NamedTuple):
    """A variable's stored values (:class:`_RawVariable`) and the index along its dimensions other than those read."""

    variable: _RawVariable
    fixed: Mapping[Hashable, Any]


def _read(
    da: xr.DataArray | _Stored, selectors: Mapping[Hashable, Any], dims: Sequence[Hashable], where: str
) -> npt.NDArray:
    """The decoded values of a selection, on ``dims`` in that order (numeric, else a WeatherError), from xarray or
    from the stored values."""
    if isinstance(da, _Stored):
        return da.variable.decode(_read_stored(da.variable, {**da.fixed, **selectors}, dims, where))
    try:
        values = np.asarray(da.isel(selectors).transpose(*dims).values)
    except Exception as exc:
        raise WeatherError(f"cannot read {where}: {type(exc).__name__}: {exc}") from exc
    if values.dtype.kind not in "fiu":
        raise WeatherError(f"{where} is not numeric (dtype {values.dtype})")
    return values


def _reorder(values: npt.NDArray[_ScalarT], inverse: Sequence[IntArray | None]) -> npt.NDArray[_ScalarT]:
    for axis, order in enumerate(inverse):
        if order is not None:
            values = np.take(values, order, axis=axis)
    return values


#: At most this many bytes of decoded values (float64) are read at once for the ensemble mean (``member="mean"``): the
#: members are read in groups, and a range of times at a time when one member's box and window exceed it (xarray's
#: decoding briefly holds about twice as much). The running sum and count take 9 bytes per value of the result (up to
#: 255 members; 12 with more), the result 4.
MEAN_READ_BYTES = 64 * 2**20


def _load_mean(
    da: xr.DataArray,
    member_dims: Sequence[Hashable],
    dims: tuple[Hashable, Hashable, Hashable],
    index: tuple[IntArray, ...],
    where: str,
    valid: tuple[float, float] | None,
    raw: _Stored | None = None,
) -> npt.NDArray[np.float32]:
    """The ensemble mean of the box and window ``index`` cuts: the members' decoded values read in groups of members
    (and of times) of at most :data:`MEAN_READ_BYTES`, without dask, summed in float64 in member order where they
    have a value (not NaN, inside ``valid``: as ``member=k`` reads them) and divided by how many have one (NaN where
    none has); ``raw``: read from the stored values."""
    selectors, inverse = _selectors(dims, index)
    shape = tuple(np.arange(da.sizes[d])[selectors[d]].size for d in dims)
    n_members = [da.sizes[d] for d in member_dims]
    counter = np.uint8 if np.prod(n_members) < 256 else np.int32
    total, count = np.full(shape, -0.0), np.zeros(shape, dtype=counter)  # -0.0 + x == x, for x = -0.0 too
    step_bytes = 8 * shape[1] * shape[2] * int(np.prod(n_members[1:]))  # one time of one member (of the first dim)
    n_times = int(min(shape[0], max(1, MEAN_READ_BYTES // step_bytes)))
    group = int(max(1, MEAN_READ_BYTES // (step_bytes * n_times)))
    t_all = np.arange(da.sizes[dims[0]])[selectors[dims[0]]]
    for t0 in range(0, shape[0], n_times):
        t_sel = t_all[t0 : t0 + n_times]
        cut = {**selectors, dims[0]: slice(int(t_sel[0]), int(t_sel[-1]) + 1) if _contiguous(t_sel) else t_sel}
        for m0 in range(0, n_members[0], group):
            cut[member_dims[0]] = slice(m0, min(m0 + group, n_members[0]))
            part = (total[t0 : t0 + n_times], count[t0 : t0 + n_times])
            if raw is not None and raw.variable.table is not None:
                _accumulate_stored(*part, raw, cut, [*member_dims, *dims], where, valid)
                continue
            block = _read(raw or da, cut, [*member_dims, *dims], where).reshape(-1, t_sel.size, shape[1], shape[2])
            _accumulate_block(*part, block, valid)
    return _reorder(member_mean(total, count).astype(np.float32), inverse)


def _accumulate_stored(
    total: FloatArray,
    count: npt.NDArray[np.integer],
    raw: _Stored,
    selectors: Mapping[Hashable, Any],
    dims: Sequence[Hashable],
    where: str,
    valid: tuple[float, float] | None,
) -> None:
    """:func:`_accumulate_block` of the members of a selection of 8- or 16-bit stored values: each member's decoded
    values looked up (:attr:`_RawVariable.table`) into one buffer, then added."""
    stored = raw.variable
    table = stored.table
    assert table is not None  # (called for 8- and 16-bit stored values, which have one)
    codes = stored.codes(_read_stored(stored, {**raw.fixed, **selectors}, dims, where)).reshape(-1, *total.shape)
    values = np.empty(total.shape, table.dtype)
    for member in codes:
        np.take(table, member, out=values, mode="clip")  # (a code is always inside the table: nothing clips)
        _accumulate_block(total, count, values[np.newaxis], valid)


def _accumulate_block(
    total: FloatArray, count: npt.NDArray[np.integer], block: npt.NDArray[Any], valid: tuple[float, float] | None
) -> None:
    """:func:`accumulate_member` for each member of ``block`` in order (when no value is missing: the same sums, one
    pass a member)."""
    if valid is None and block.dtype.kind == "f" and not np.isnan(block).any():
        for values in block:
            total += values
        count += block.shape[0]
        return
    for values in block:
        accumulate_member(total, count, values, valid)


def _contiguous(idx: IntArray) -> bool:
    return bool(idx.size == idx[-1] - idx[0] + 1)


def accumulate_member(
    total: FloatArray,
    count: npt.NDArray[np.integer],
    values: npt.NDArray[np.floating] | npt.NDArray[np.integer],
    valid: tuple[float, float] | None = None,
) -> None:
    """Add one ensemble member's decoded values to a running sum, in place: ``total`` (float64, start at -0.0) gets
    each value that is not missing (NaN, or outside ``valid`` once in float32, as a member is read) added in float64,
    ``count`` (integer) counts them. Adding the members in member order and then :func:`member_mean` is the ensemble
    mean of :func:`open_weather` ``(member="mean")`` and of :func:`pyroute_rel.analysis.members.mean_of_files`."""
    values64 = np.asarray(values, dtype=np.float64)
    ok = ~np.isnan(values64)
    if valid is not None:
        as_read = values64.astype(np.float32)
        ok &= (as_read >= np.float64(valid[0])) & (as_read <= np.float64(valid[1]))
    np.add(total, values64, out=total, where=ok)
    count += ok


def member_mean(total: FloatArray, count: npt.NDArray[np.integer]) -> FloatArray:
    """The mean of :func:`accumulate_member`'s sum: ``total / count`` [float64], NaN where no member has a value."""
    out = np.full(total.shape, np.nan)
    np.divide(total, count, out=out, where=count > 0)
    return out


def _lon_plan(
    lon: FloatArray, box: tuple[float, float, float, float] | None, margin: float
) -> tuple[IntArray, FloatArray, bool] | None:
    """File indices and the increasing, contiguous longitude axis [deg] they form; None if outside the box.

    Longitudes are mapped to [-180, 180) and sorted; a global grid gets one wrapped column on each
    side (and, with a box, its seam is put opposite the box), a regional grid across 180° runs past 180.
    """
    norm = (lon + 180.0) % 360.0 - 180.0
    order = np.argsort(norm, kind="stable")
    s = norm[order]
    keep = np.concatenate(([True], np.diff(s) > 0))  # drop a repeated column (e.g. both -180 and 180)
    order, s = order[keep], s[keep]
    if s.size < 2:
        return order, s, False
    gaps = np.diff(np.append(s, s[0] + 360.0))
    periodic = bool(gaps[-1] <= 1.5 * gaps[:-1].max())
    centre = None if box is None else 0.5 * (box[0] + box[2])
    if periodic:
        seam = -180.0 if centre is None else centre - 180.0
        m = seam + (s - seam) % 360.0
        o2 = np.argsort(m, kind="stable")
        order, m = order[o2], m[o2]
        idx = np.concatenate((order[-1:], order, order[:1]))
        axis = np.concatenate((m[-1:] - 360.0, m, m[:1] + 360.0))
    else:
        k = int(np.argmax(gaps))  # the data start after the largest gap
        if gaps[-1] >= gaps[k]:
            idx, axis = order, s
        else:  # a regional grid across 180°: run on past 180
            idx = np.roll(order, -(k + 1))
            axis = np.concatenate((s[k + 1 :], s[: k + 1] + 360.0))
    if centre is not None and not (periodic and box[2] - box[0] + 2.0 * margin >= 360.0):  # type: ignore[index]
        centre += 360.0 * np.round((0.5 * (axis[0] + axis[-1]) - centre) / 360.0)  # box centre near the axis'
        half = 0.5 * (box[2] - box[0]) + margin  # type: ignore[index]
        plan = _sorted_plan(axis, (centre - half, centre + half), 0.0)
        if plan is None:
            return None
        idx, axis, periodic = idx[plan[0]], plan[1] - 360.0 * np.floor((plan[1][0] + 180.0) / 360.0), False
    return idx, axis, periodic


def _sorted_plan(
    values: npt.NDArray[Any], window: tuple[Any, Any] | None, margin: float
) -> tuple[IntArray, npt.NDArray[Any]] | None:
    """Indices (sorted by value) of the values inside window +- margin plus one bracketing value each side."""
    order = np.argsort(values, kind="stable")
    s = values[order]
    if window is None:
        return order, s
    lo, hi = window[0] - margin, window[1] + margin
    if s[-1] < lo or s[0] > hi:
        return None
    a = max(int(np.searchsorted(s, lo, side="left")) - 1, 0)
    b = min(int(np.searchsorted(s, hi, side="right")) + 1, s.size)
    return order[a:b], s[a:b]


def _convert_units(
    values: npt.NDArray[np.float32], attrs: Mapping[Hashable, Any], name: str, where: str
) -> npt.NDArray[np.float32]:
    kind = _KIND[name]
    raw = attrs.get("units")
    key = "".join(ch for ch in str(raw if raw is not None else "").strip().lower() if ch not in " *^_.")
    if key in _MISSING_UNITS:
        key = "".join(ch for ch in _DEFAULT_UNITS[kind].lower() if ch != " ")
        if kind == "speed" and not where.startswith("weather file '<"):  # a file's (a dataset made in code, e.g.
            # weather_from_dataset's "<dataset>", states its own): m/s and knots differ by half (issue 34: no word)
            warnings.warn(
                f'{where} has no units attribute: read as m/s; if it holds knots, give it units = "knots"',
                WeatherWarning,
                stacklevel=2,
            )
    table = _UNITS[kind]
    if key not in table:
        accepted = (
            ", ".join(sorted({"m s-1", "m/s", "knots", "kt", "kn", "cm/s", "km/h"}))
            if kind == "speed"
            else ", ".join(sorted(table))
        )
        raise WeatherError(f"{where} has units {raw!r}, not a {kind} (expected one of: {accepted})")
    factor = table[key]
    if name == "tws_kn":
        factor *= KN_PER_MS
    if factor != 1.0:
        values = values * np.float32(factor)
    return values


def _normalise_direction(
    values: npt.NDArray[np.float32], attrs: Mapping[Hashable, Any], name: str
) -> npt.NDArray[np.float32]:
    """Directions [deg] into [0, 360), *from* (a ``*_to_direction`` variable turned round); other fields as given."""
    if _KIND[name] != "direction":
        return values
    values = np.mod(values, np.float32(360.0))
    if "to_direction" in str(attrs.get("standard_name", "")):
        values = np.mod(values + np.float32(180.0), np.float32(360.0))
    return values


def _join_in_time(name: str, parts: list[WeatherField]) -> WeatherField:
    """The same field from several files on one grid -> one field along time."""
    if len(parts) == 1:
        return parts[0]
    first = parts[0]
    for p in parts[1:]:
        same = p.lon.shape == first.lon.shape and p.lat.shape == first.lat.shape
        if not (same and np.allclose(p.lon, first.lon) and np.allclose(p.lat, first.lat)) or p.time is None:
            raise WeatherError(
                f"field {name!r} is given by both '{first.source}' (variable '{first.variable}') and "
                f"'{p.source}' (variable '{p.variable}') on different grids or without times; remove one "
                f"file or choose with variables={{'{name}': ...}}"
            )
    parts = sorted(parts, key=lambda p: p.time[0])  # type: ignore[index]
    for a, b in zip(parts, parts[1:], strict=False):
        if b.time[0] <= a.time[-1]:  # type: ignore[index]
            raise WeatherError(
                f"field {name!r}: '{a.source}' and '{b.source}' overlap in time ({iso_minute(b.time[0])} <= "  # type: ignore[index]
                f"{iso_minute(a.time[-1])}); give files with disjoint times"  # type: ignore[index]
            )
    values = np.concatenate([p.values for p in parts], axis=0)  # type: ignore[misc]
    time = np.concatenate([p.time for p in parts])  # type: ignore[misc]
    return replace(first, values=values, time=time, source=" + ".join(p.source for p in parts))


def _speed_direction_to_uv(fields: dict[str, WeatherField]) -> None:
    """Replace tws_kn/twd_deg (speed [kn], direction from [deg]) by wind_u_ms/wind_v_ms [m/s] in place."""
    if "tws_kn" not in fields and "twd_deg" not in fields:
        return
    speed, direction = fields.pop("tws_kn", None), fields.pop("twd_deg", None)
    if speed is None or direction is None or speed.values is None or direction.values is None:
        have: Any = speed or direction
        raise WeatherError(
            f"weather file '{have.source}' variable '{have.variable}': give both wind speed and direction"
        )
    if speed.values.shape != direction.values.shape or not np.array_equal(speed.lat, direction.lat):
        raise WeatherError(f"wind speed '{speed.variable}' and direction '{direction.variable}' must share one grid")
    rad = np.deg2rad(direction.values)
    ms = speed.values / np.float32(KN_PER_MS)
    fields["wind_u_ms"] = replace(speed, name="wind_u_ms", values=(-ms * np.sin(rad)).astype(np.float32))
    fields["wind_v_ms"] = replace(speed, name="wind_v_ms", values=(-ms * np.cos(rad)).astype(np.float32))


# ----------------------------------------------------------------------------------------------- helpers


def _check_bbox(bbox: Sequence[float] | None) -> tuple[float, float, float, float] | None:
    if bbox is None:
        return None
    try:
        west, south, east, north = (float(v) for v in bbox)
    except (TypeError, ValueError):
        raise WeatherError(f"bbox must be (west, south, east, north) [deg] (got {brief(bbox)})") from None
    if not all(np.isfinite((west, south, east, north))) or not -90.0 <= south <= north <= 90.0:
        raise WeatherError(f"bbox must be finite (west, south, east, north) with south <= north [deg] (got {bbox!r})")
    if east < west:
        east += 360.0
    return west, south, east, north
