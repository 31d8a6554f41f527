"""Gridded, time-varying weather from files (ERA5, GFS, WAVEWATCH III, CMEMS) as a :class:`WeatherSource`.

Reading (:func:`open_weather`, :meth:`GriddedWeather.from_dataset`) and sampling
(:meth:`GriddedWeather.sample`) are kept apart: files are read once, cut to the route's box and time
window, normalised (longitude in [-180, 180), latitude ascending, units converted) and kept as numpy
arrays on (time, lat, lon); sampling is index arithmetic, linear in time, latitude and longitude.

Each field of :data:`VARIABLES` is found by name (ERA5 ``u10 v10 swh mwd pp1d``, GFS via cfgrib ``u10 v10``,
WAVEWATCH III ``HTSGW DIRPW PERPW``, CMEMS ``VHM0 VMDR VTPK``, ``utotal vtotal`` or ``uo vo``), then by CF
``standard_name``; ``variables={field: file_variable}`` overrides the search. Each field keeps its own grid
and time axis; the same field in several files on one grid is joined along time (monthly ERA5 files, one
GRIB file per GFS step). Units come from the ``units`` attribute; a missing, empty or ``"unknown"`` one
means m/s, degrees, m or s by the field's kind; a unit not recognised for the kind (``K`` for wind) is an error.

Wind is interpolated as (u, v), then turned into speed [kn] and direction *from* [deg]; wave direction
as a unit vector; currents as (u, v) *to* [m/s]. A point outside a field's loaded box or times, or with
NaN in a grid value it draws on, gives NaN. Absent currents are 0 [m/s]; absent waves and periods NaN
(see :attr:`GriddedWeather.fields`). A file without time is steady; one with a single time covers that instant.

References
----------
Hersbach, H. et al. (2020). The ERA5 global reanalysis. Q. J. R. Meteorol. Soc. 146, 1999-2049.
https://doi.org/10.1002/qj.3803
"""

from __future__ import annotations

import datetime as _dt
import os
from collections.abc import Hashable, Iterable, Mapping, Sequence
from dataclasses import dataclass, replace
from importlib.util import find_spec
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import xarray as xr

from .errors import ScenarioError, WeatherCoverageError, WeatherError
from .geodesy import bearing_deg
from .weather import Conditions

__all__ = [
    "BBOX_MARGIN_DEG",
    "GRIB_FILTERS",
    "KNOTS_PER_MS",
    "VARIABLES",
    "GriddedWeather",
    "PreparedPoints",
    "WeatherField",
    "open_weather",
    "weather_from_mapping",
]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.intp]

#: Knots per metre per second (1 kn = 1852 m / 3600 s).
KNOTS_PER_MS = 3600.0 / 1852.0

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
_SPEED = {"ms-1": 1.0, "m/s": 1.0, "m/sec": 1.0, "mps": 1.0, "cm/s": 0.01, "cms-1": 0.01}
for _m in ("meter", "meters", "metre", "metres"):
    _SPEED.update({f"{_m}/second": 1.0, f"{_m}persecond": 1.0, f"{_m}second-1": 1.0, f"{_m}s-1": 1.0})
_SPEED.update(dict.fromkeys(("knots", "knot", "kt", "kts", "kn"), 1.0 / KNOTS_PER_MS))
_SPEED.update(dict.fromkeys(("km/h", "kmh-1", "kph"), 1.0 / 3.6))
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
#: Fields a :class:`GriddedWeather` stores (wind speed/direction files are converted to u/v on load).
_GRID_FIELDS = tuple(k for k in VARIABLES if k not in ("tws_kn", "twd_deg"))


@dataclass(frozen=True)
class WeatherField:
    """One field on its own (time, lat, lon) grid, in the units of :data:`VARIABLES`.

    Attributes
    ----------
    name : Field name, one of ``wind_u_ms``, ``wind_v_ms``, ``hs_m``, ``wave_dir_deg``, ``wave_period_s``,
        ``current_u_ms``, ``current_v_ms``.
    values : Array (n_time, n_lat, n_lon) (n_time = 1 for a steady field); NaN where unknown. ``None``
        in the metadata a :class:`GriddedWeather` keeps (its data live in the sampler's blocks).
    lon : Strictly increasing longitudes [deg]; contiguous (a box across 180° runs past 180).
    lat : Strictly increasing latitudes [deg].
    time : Strictly increasing ``datetime64[ns]`` times, or ``None`` for a field steady in time.
    source : File (or ``"<dataset>"``) the field was read from, for messages.
    variable : Variable name in that file.
    periodic : True when ``lon`` wraps around the whole globe (one duplicated column on each side).
    """

    name: str
    values: npt.NDArray[np.floating] | None
    lon: FloatArray
    lat: FloatArray
    time: npt.NDArray[np.datetime64] | None
    source: str = "<dataset>"
    variable: str = ""
    periodic: bool = False

    def describe(self) -> str:
        """The field's extent, e.g. ``"lon [-70, 0], lat [5, 55] [deg], time 2018-06-01T00:00 .. ..."``."""
        t = "any time" if self.time is None else f"time {_iso(self.time[0])} .. {_iso(self.time[-1])}"
        lon = "all longitudes" if self.periodic else f"lon [{self.lon[0]:g}, {self.lon[-1]:g}]"
        return f"{lon}, lat [{self.lat[0]:g}, {self.lat[-1]:g}] [deg], {t}"


class _Block:
    """Fields sharing one grid, stored field-major as (n_fields, n_lat, n_lon, n_time) float32.

    Time is the innermost axis: the two times a point is interpolated between sit side by side in memory, so
    of the eight corners of its cell only four cost a trip to main memory (routing samples millions of points
    scattered over a field of a gigabyte; the gathers, not the arithmetic, set the pace).
    """

    def __init__(self, fields: list[WeatherField]):
        ref = fields[0]
        nt, ny, nx = ref.values.shape  # type: ignore[union-attr]
        # wave direction is stored as (sin, cos) of the angle: a unit vector interpolates across north
        cols = [(f, op) for f in fields for op in ((np.sin, np.cos) if f.name == "wave_dir_deg" else (None,))]
        self.names = [{np.sin: "_wave_sin", np.cos: "_wave_cos"}.get(op, f.name) for f, op in cols]  # type: ignore[arg-type]
        self.data = np.empty((len(cols), ny, nx, nt), dtype=np.float32)
        rows = max(1, (1 << 22) // max(1, nt * nx))
        for j, (f, op) in enumerate(cols):
            values = f.values
            for y0 in range(0, ny, rows):  # in bands of latitude: no full-size temporaries
                chunk = np.moveaxis(np.asarray(values[:, y0 : y0 + rows, :]), 0, -1)  # type: ignore[index]
                self.data[j, y0 : y0 + rows] = chunk if op is None else op(np.deg2rad(chunk.astype(np.float32)))
        self.flat = self.data.reshape(len(cols), -1)
        self.lon, self.lat = ref.lon, ref.lat
        self.t0 = ref.time[0] if ref.time is not None else np.datetime64("NaT", "ns")
        self.time_s = None if ref.time is None else (ref.time - self.t0) / np.timedelta64(1, "s")
        self.lon_mid = 0.5 * (self.lon[0] + self.lon[-1])
        self.strides = (1, nx * nt, nt)  # time, lat, lon

    def interpolate(self, lon: FloatArray, lat: FloatArray, time: npt.NDArray[np.datetime64]) -> FloatArray:
        """Trilinear interpolation at points (1-D arrays) -> (n_points, n_fields), NaN outside."""
        return self.interpolate_at(self.locate(lon, lat), time)

    def locate(self, lon: FloatArray, lat: FloatArray) -> _Where:
        """Where points (1-D arrays) fall on this block's grid (reused by every time at which they are sampled)."""
        inside = (lon >= self.lon[0]) & (lon <= self.lon[-1])
        if not inside.all():  # the equivalent longitude (+- 360) nearest to the grid's middle
            lon = np.where(inside, lon, (lon - self.lon_mid + 180.0) % 360.0 - 180.0 + self.lon_mid)
        ix, wx, sx, ok = _locate(self.lon, lon, self.strides[2])
        iy, wy, sy, ok_y = _locate(self.lat, lat, self.strides[1])
        return _Where(base=iy * self.strides[1] + ix * self.strides[2], sx=sx, sy=sy, wx=wx, wy=wy, ok=ok & ok_y)

    def interpolate_at(self, where: _Where, time: npt.NDArray[np.datetime64]) -> FloatArray:
        """Interpolation at located points and times (1-D) -> (n_points, n_fields), NaN outside."""
        ok = where.ok
        wx, wy = where.wx, where.wy
        if self.time_s is None or self.time_s.size == 1:
            base, st, wt = where.base, None, None
            if self.time_s is not None:
                ok = ok & (time == self.t0)
        else:
            t = (time - self.t0) / np.timedelta64(1, "s")
            it, wt, st, ok_t = _locate(self.time_s, t, self.strides[0])
            ok = ok & ok_t
            base = where.base + it
        # corner indices (k, n) and weights; a step is 0 where its weight is 0, so a NaN neighbour that does
        # not contribute never spoils the result
        sx, sy = where.sx, where.sy
        idx = [base, base + sx, base + sy, base + sx + sy]
        w = [(1.0 - wx) * (1.0 - wy), wx * (1.0 - wy), (1.0 - wx) * wy, wx * wy]
        if st is not None and wt is not None:
            idx = idx + [i + st for i in idx]
            w = [c * (1.0 - wt) for c in w] + [c * wt for c in w]
        gathered = np.take(self.flat, np.stack(idx), axis=1)  # (n_fields, k, n)
        out = np.einsum("kn,fkn->nf", np.stack(w), gathered)
        out[~ok] = np.nan
        return out


@dataclass(frozen=True)
class _Where:
    """Points located on a block's (lat, lon) grid: lower-left cell index, steps to the neighbours, weights."""

    base: IntArray
    sx: IntArray
    sy: IntArray
    wx: FloatArray
    wy: FloatArray
    ok: npt.NDArray[np.bool_]


@dataclass(frozen=True)
class PreparedPoints:
    """Points located once on every grid of a :class:`GriddedWeather` (see :meth:`GriddedWeather.prepare`)."""

    shape: tuple[int, ...]
    lon: FloatArray
    lat: FloatArray
    where: tuple[_Where, ...]
    owner: int  # id of the GriddedWeather that located them


def _locate(axis: FloatArray, x: FloatArray, stride: int) -> tuple[IntArray, FloatArray, IntArray, Any]:
    """Cell index, weight of the upper neighbour, index step to it and in-range mask, per point.

    The step is 0 where the weight is 0 (a point on a grid line, or on the last one), so a NaN
    neighbour that does not contribute never spoils the result. Regular axes find the cell by
    arithmetic, corrected against the axis values so the result equals a binary search.
    """
    n = axis.size
    step0 = (axis[-1] - axis[0]) / (n - 1) if n > 1 else 0.0
    with np.errstate(invalid="ignore"):
        if n > 2 and np.all(np.abs(np.diff(axis) - step0) <= 1e-9 * abs(step0)):
            f = np.nan_to_num((x - axis[0]) / step0, nan=0.0, posinf=n, neginf=0.0)
            i = np.clip(f, 0, n - 1).astype(np.intp)
            i -= (axis[i] > x) & (i > 0)
            i += (axis[np.minimum(i + 1, n - 1)] <= x) & (i < n - 1)
        else:
            i = np.clip(np.searchsorted(axis, x, side="right") - 1, 0, n - 1)
        gap = np.append(np.diff(axis), np.inf)
        w = (x - axis[i]) / gap[i]
        step = np.where(w > 0, stride, 0)
        ok = (x >= axis[0]) & (x <= axis[-1])
    return i, w, step, ok


class GriddedWeather:
    """Gridded, time-varying weather: a :class:`~pyroute_rel.weather.WeatherSource` over numpy arrays.

    Build it with :func:`open_weather` (files) or :meth:`from_dataset` (an in-memory
    :class:`xarray.Dataset`); the constructor takes ready :class:`WeatherField` objects.

    Parameters
    ----------
    fields : Fields on their own grids; ``wind_u_ms`` and ``wind_v_ms`` are required. Their arrays
        are copied into float32 blocks (fields on the same grid share one block).

    Examples
    --------
    >>> import xarray as xr
    >>> ds = xr.Dataset(
    ...     {"u10": (("latitude", "longitude"), np.ones((2, 2)), {"units": "m s**-1"}),
    ...      "v10": (("latitude", "longitude"), np.zeros((2, 2)), {"units": "m s**-1"})},
    ...     coords={"latitude": [50.0, 40.0], "longitude": [340.0, 350.0]})
    >>> w = GriddedWeather.from_dataset(ds)
    >>> c = w.sample(-15.0, 45.0, np.datetime64("2018-06-01T00:00"))
    >>> round(float(c.tws_kn), 4), float(c.twd_deg), sorted(w.fields)
    (1.9438, 270.0, ['twd_deg', 'tws_kn'])
    """

    def __init__(self, fields: Iterable[WeatherField]):
        fields = list(fields)
        names = [f.name for f in fields]
        for f in fields:
            if f.name not in _GRID_FIELDS:
                raise WeatherError(f"field name must be one of {list(_GRID_FIELDS)} (got {f.name!r})")
            if names.count(f.name) > 1:
                raise WeatherError(f"field {f.name!r} is given more than once")
            _check_field(f)
        if "wind_u_ms" not in names or "wind_v_ms" not in names:
            srcs = sorted({f.source for f in fields}) or ["<no field>"]
            raise WeatherError(
                f"no 10 m wind (u and v components) found in {', '.join(map(repr, srcs))}; wind is required "
                f"(name the variables with variables={{'wind_u_ms': ..., 'wind_v_ms': ...}})"
            )
        self._info: dict[str, WeatherField] = {f.name: replace(f, values=None) for f in fields}
        groups: dict[tuple[bytes, bytes, bytes | None], list[WeatherField]] = {}
        for f in fields:
            key = (f.lon.tobytes(), f.lat.tobytes(), None if f.time is None else f.time.tobytes())
            groups.setdefault(key, []).append(f)
        self._blocks = [_Block(group) for group in groups.values()]

    @property
    def fields(self) -> frozenset[str]:
        """Names of :class:`~pyroute_rel.weather.Conditions` fields the data actually provide."""
        out = {"tws_kn", "twd_deg"}
        out.update(n for n in ("hs_m", "wave_dir_deg", "wave_period_s") if n in self._info)
        if "current_u_ms" in self._info and "current_v_ms" in self._info:
            out.update(("current_u_ms", "current_v_ms"))
        return frozenset(out)

    @property
    def field_info(self) -> Mapping[str, WeatherField]:
        """Per stored field: grid axes, source file and variable (``values`` is ``None``)."""
        return dict(self._info)

    @property
    def nbytes(self) -> int:
        """Memory held by the gridded data [bytes]."""
        return sum(b.data.nbytes for b in self._blocks)

    def _interpolate(self, lon: FloatArray, lat: FloatArray, time: npt.NDArray[np.datetime64]) -> dict[str, FloatArray]:
        return self._interpolate_at(tuple(b.locate(lon, lat) for b in self._blocks), time)

    def _interpolate_at(self, where: tuple[_Where, ...], time: npt.NDArray[np.datetime64]) -> dict[str, FloatArray]:
        out: dict[str, FloatArray] = {}
        for block, w in zip(self._blocks, where, strict=True):
            values = block.interpolate_at(w, time)
            out.update((name, values[:, j]) for j, name in enumerate(block.names))
        return out

    def prepare(self, lon_deg: npt.ArrayLike, lat_deg: npt.ArrayLike) -> PreparedPoints:
        """Locate points on the data's grids once, for :meth:`sample_at` at several times (the cost kernel samples
        the same arc points at the departure time and again at the times the boat gets there).

        >>> import xarray as xr
        >>> ds = xr.Dataset({"u10": (("latitude", "longitude"), np.ones((2, 2))),
        ...                  "v10": (("latitude", "longitude"), np.zeros((2, 2)))},
        ...                 coords={"latitude": [40.0, 50.0], "longitude": [-20.0, -10.0]})
        >>> w = GriddedWeather.from_dataset(ds)
        >>> p = w.prepare([-15.0, -12.0], 45.0)
        >>> float(w.sample_at(p, np.datetime64("2018-06-01")).twd_deg[1])
        270.0
        """
        lon = np.asarray(lon_deg, dtype=np.float64)
        lat = np.asarray(lat_deg, dtype=np.float64)
        shape = np.broadcast_shapes(lon.shape, lat.shape)
        lon_f, lat_f = (np.broadcast_to(a, shape).ravel() for a in (lon, lat))
        return PreparedPoints(shape=shape, lon=lon_f, lat=lat_f, owner=id(self),
                              where=tuple(b.locate(lon_f, lat_f) for b in self._blocks))

    def sample_at(self, points: PreparedPoints, time: npt.ArrayLike) -> Conditions:
        """:meth:`sample` at points located by :meth:`prepare` (``time`` broadcasts to their shape)."""
        if points.owner != id(self):
            raise WeatherError("these points were prepared for another weather source: use its prepare()")
        t = np.asarray(time)
        if t.dtype.kind != "M":
            raise WeatherError(f"'time' must be datetime64 (got dtype {t.dtype})")
        t = np.broadcast_to(t.astype("datetime64[ns]"), points.shape).ravel()
        return self._conditions(points.shape, self._interpolate_at(points.where, t))

    def interpolate(self, name: str, lon_deg: npt.ArrayLike, lat_deg: npt.ArrayLike, time: npt.ArrayLike) -> FloatArray:
        """One stored field (e.g. ``"wind_u_ms"`` [m/s]) at broadcast points; NaN where unknown."""
        if name not in self._info:
            raise WeatherError(f"'name' must be one of {sorted(self._info)} (got {name!r})")
        shape, lon, lat, t = _points(lon_deg, lat_deg, time)
        values = self._interpolate(lon, lat, t)
        if name == "wave_dir_deg":
            return bearing_deg(values["_wave_sin"], values["_wave_cos"]).reshape(shape)
        return values[name].reshape(shape)

    def sample(self, lon_deg: npt.ArrayLike, lat_deg: npt.ArrayLike, time: npt.ArrayLike) -> Conditions:
        """Wind, waves and current at points and times (broadcast together).

        Parameters
        ----------
        lon_deg : Longitudes [deg] (any convention; mapped onto each field's grid).
        lat_deg : Latitudes [deg].
        time : Times (``datetime64``, UTC).

        Returns
        -------
        Conditions
            ``tws_kn`` = hypot(u, v) x 3600/1852 [kn], ``twd_deg`` = atan2(-u, -v) (from) [deg]; wave
            direction from the interpolated unit vector; NaN outside the data or next to NaN cells.
        """
        shape, lon, lat, t = _points(lon_deg, lat_deg, time)
        return self._conditions(shape, self._interpolate(lon, lat, t))

    def _conditions(self, shape: tuple[int, ...], v: dict[str, FloatArray]) -> Conditions:
        u_w, v_w = v["wind_u_ms"], v["wind_v_ms"]
        n = u_w.size
        nan = np.full(n, np.nan)
        out = {
            "tws_kn": np.hypot(u_w, v_w) * KNOTS_PER_MS,
            "twd_deg": bearing_deg(-u_w, -v_w),
            "hs_m": v.get("hs_m", nan),
            "wave_dir_deg": bearing_deg(v["_wave_sin"], v["_wave_cos"]) if "_wave_sin" in v else nan,
            "wave_period_s": v.get("wave_period_s", nan),
            "current_u_ms": v.get("current_u_ms", np.zeros(n)),
            "current_v_ms": v.get("current_v_ms", np.zeros(n)),
        }
        return Conditions(**{k: np.asarray(a, dtype=np.float64).reshape(shape) for k, a in out.items()})

    def check_coverage(
        self,
        lon_range: tuple[float, float],
        lat_range: tuple[float, float],
        time_range: tuple[np.datetime64, np.datetime64],
    ) -> None:
        """Raise :class:`~pyroute_rel.errors.WeatherCoverageError` unless every field covers the request.

        Parameters
        ----------
        lon_range : (west, east) [deg]; east < west means the box crosses 180°.
        lat_range : (south, north) [deg].
        time_range : (first, last) time needed (``datetime64``, UTC).
        """
        lo, hi = float(lon_range[0]), float(lon_range[1])
        if hi < lo:
            hi += 360.0
        t0, t1 = (_to_datetime64(t, "time_range") for t in time_range)
        for f in self._info.values():
            short = []
            if not f.periodic:
                mid = 0.5 * (f.lon[0] + f.lon[-1])
                shift = 360.0 * np.round((mid - 0.5 * (lo + hi)) / 360.0)
                if lo + shift < f.lon[0] or hi + shift > f.lon[-1]:
                    short.append("lon")
            if lat_range[0] < f.lat[0] or lat_range[1] > f.lat[-1]:
                short.append("lat")
            if f.time is not None and (t0 < f.time[0] or t1 > f.time[-1]):
                short.append("time")
            if short:
                raise WeatherCoverageError(
                    f"weather file '{f.source}' variable '{f.variable}' covers (as loaded) {f.describe()}; requested "
                    f"lon [{lon_range[0]:g}, {lon_range[1]:g}], lat [{lat_range[0]:g}, {lat_range[1]:g}] [deg], "
                    f"time {_iso(t0)} .. {_iso(t1)} ({' and '.join(short)} not covered)"
                )

    @classmethod
    def from_dataset(
        cls,
        ds: xr.Dataset,
        *,
        variables: Mapping[str, str] | None = None,
        bbox: Sequence[float] | None = None,
        time_window: Sequence[Any] | None = None,
        member: int | None = None,
        margin_deg: float = BBOX_MARGIN_DEG,
        source: str = "<dataset>",
    ) -> GriddedWeather:
        """Build from an in-memory :class:`xarray.Dataset` laid out like one of the supported files.

        Options as for :func:`open_weather`; ``source`` names the dataset in messages.
        """
        return cls(_read_fields([(source, [ds])], variables, bbox, time_window, member, margin_deg))


def open_weather(
    paths: str | os.PathLike[str] | Sequence[str | os.PathLike[str]],
    *,
    variables: Mapping[str, str] | None = None,
    bbox: Sequence[float] | None = None,
    time_window: Sequence[Any] | None = None,
    member: int | None = None,
    margin_deg: float = BBOX_MARGIN_DEG,
) -> GriddedWeather:
    """Read NetCDF/GRIB weather files into a :class:`GriddedWeather`.

    Files are opened lazily (dask chunks for NetCDF) and only the box and time window are read.

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
        (equal to the member number for ERA5 and GEFS). Required when a file holds several members:
        an ensemble is never reduced silently.
    margin_deg : Margin around ``bbox`` [deg].

    Raises
    ------
    WeatherError
        A file is missing or unreadable, a variable has wrong units or is all NaN, wind is missing.
    WeatherCoverageError
        A file does not reach into ``bbox``, or no file of a field reaches into ``time_window``.
    """
    if isinstance(paths, str | os.PathLike):
        paths = [paths]
    if not paths:
        raise WeatherError("no weather file given (expected at least one path)")
    opened: list[tuple[str, list[xr.Dataset]]] = []
    try:
        for p in paths:
            opened.append((str(p), _open_file(Path(p))))
        return GriddedWeather(_read_fields(opened, variables, bbox, time_window, member, margin_deg))
    finally:
        for _, datasets in opened:
            for ds in datasets:
                ds.close()


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
    optional ``variables = {hs_m = "VHM0", ...}`` and ``member = 0``. ``bbox`` and ``time_window`` are
    passed on to :func:`open_weather` (the route's box and voyage window).

    Raises :class:`~pyroute_rel.errors.ScenarioError` naming the key on a malformed table.
    """
    allowed = ("kind", "paths", "variables", "member")
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
    if member is not None and (isinstance(member, bool) or not isinstance(member, int) or member < 0):
        raise ScenarioError(f"{where}.member must be an integer >= 0 (got {member!r})")
    base = Path(base_dir)
    paths = [p if p.is_absolute() else base / p for p in (Path(s).expanduser() for s in raw)]
    return open_weather(paths, variables=variables, bbox=bbox, time_window=time_window, member=member)


# ----------------------------------------------------------------------------------------------- reading


def _open_file(path: Path) -> list[xr.Dataset]:
    if not path.is_file():
        raise WeatherError(f"weather file '{path}' does not exist")
    try:
        with open(path, "rb") as fh:
            head = fh.read(8)
    except OSError as exc:
        raise WeatherError(f"cannot read weather file '{path}': {exc}") from exc
    if head.startswith(b"GRIB") or path.suffix.lower() in _GRIB_SUFFIXES:
        return _open_grib(path)
    if not (head.startswith(b"CDF") or head.startswith(b"\x89HDF\r\n\x1a\n")):
        raise WeatherError(f"weather file '{path}' is not a NetCDF or GRIB file (starts with {head[:4]!r})")
    try:
        engine = "netcdf4" if find_spec("netCDF4") else ("scipy" if head.startswith(b"CDF") else "h5netcdf")
        return [xr.open_dataset(path, engine=engine, chunks={}, decode_timedelta=False)]
    except Exception as exc:  # netCDF4/HDF5 raise many types for damaged files
        raise WeatherError(f"cannot read weather file '{path}': {type(exc).__name__}: {exc}") from exc


def _open_grib(path: Path) -> list[xr.Dataset]:
    try:
        import cfgrib  # noqa: F401
    except (ImportError, RuntimeError) as exc:  # RuntimeError: eccodes library not found
        raise WeatherError(
            f"reading GRIB file '{path}' needs cfgrib and eccodes: pip install 'pyroute_rel[grib]' ({exc})"
        ) from exc
    out = []
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
    return out


def _read_fields(
    files: list[tuple[str, list[xr.Dataset]]],
    variables: Mapping[str, str] | None,
    bbox: Sequence[float] | None,
    time_window: Sequence[Any] | None,
    member: int | None,
    margin_deg: float,
) -> list[WeatherField]:
    """Find, cut, convert and merge every field of every file."""
    variables = dict(variables or {})
    for key, name in variables.items():
        if key not in VARIABLES:
            raise WeatherError(f"variables: field must be one of {list(VARIABLES)} (got {key!r})")
        if not any(name in ds.data_vars for _, dss in files for ds in dss):
            where = ", ".join(f"'{s}'" for s, _ in files)
            raise WeatherError(f"variables[{key!r}] = {name!r}: no such variable in {where}")
    box = _check_bbox(bbox)
    window = None
    if time_window is not None:
        if isinstance(time_window, str) or len(time_window) != 2:
            raise WeatherError(f"time_window must be a pair (first, last) (got {time_window!r})")
        window = (_to_datetime64(time_window[0], "time_window"), _to_datetime64(time_window[1], "time_window"))
        if window[1] < window[0]:
            raise WeatherError(f"time_window must have first <= last (got {time_window!r})")
    if not np.isfinite(margin_deg) or margin_deg < 0:
        raise WeatherError(f"margin_deg must be a finite number >= 0 [deg] (got {margin_deg!r})")
    parts: dict[str, list[WeatherField]] = {}
    dropped: dict[str, list[str]] = {}
    used_member = False
    for source, datasets in files:
        found = _detect(source, datasets, variables)
        for name, (ds, var) in found.items():
            field, had_members = _extract(ds[var], name, source, var, box, window, member, margin_deg)
            used_member |= had_members
            if field is None:
                covered = ""
                tname = next((c for c in ("time", "valid_time") if c in ds[var].coords), None)
                if tname is not None and ds[var][tname].size:
                    tv = np.asarray(ds[var][tname].values).astype("datetime64[m]")
                    covered = f" (it covers {_iso(tv.min())} .. {_iso(tv.max())})"
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
                f"{_iso(window[0])} .. {_iso(window[1])}"  # type: ignore[index]
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
    return list(merged.values())


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
    da: xr.DataArray,
    name: str,
    source: str,
    var: str,
    box: tuple[float, float, float, float] | None,
    window: tuple[np.datetime64, np.datetime64] | None,
    member: int | None,
    margin: float,
) -> tuple[WeatherField | None, bool]:
    """Cut one variable to the box and window, load it, convert units -> (field or None, had members)."""
    where = f"weather file '{source}' variable '{var}'"
    kinds = {d: _dim_kind(da, d) for d in da.dims}
    had_members = False
    for dim, kind in kinds.items():
        n = da.sizes[dim]
        if kind == "member":
            had_members = True
            if member is None and n > 1:
                raise WeatherError(
                    f"{where} has {n} ensemble members (dimension '{dim}'); choose one with member=<0..{n - 1}>"
                )
            index = 0 if member is None else member
            if not 0 <= index < n:
                raise WeatherError(f"{where}: member must be in [0, {n - 1}] (got {member})")
            da = da.isel({dim: index})
        elif kind == "depth":
            depth = np.asarray(da[dim].values, dtype=float) if dim in da.coords else np.arange(n, dtype=float)
            da = da.isel({dim: int(np.nanargmin(np.abs(depth)))})  # the shallowest level
        elif kind == "other" and str(dim).lower() == "expver":  # ERA5 + ERA5T: each time is in one of them
            parts = [da.isel({dim: k}).drop_vars([dim], errors="ignore") for k in range(n)]
            da = parts[0]
            for part in parts[1:]:
                da = da.fillna(part)
        elif kind == "other":
            if n != 1:
                raise WeatherError(
                    f"{where} has an unexpected dimension '{dim}' of size {n} "
                    f"(expected time, latitude, longitude and optionally number and depth)"
                )
            da = da.isel({dim: 0})
    lon_dim = [d for d in da.dims if kinds[d] == "lon"]
    lat_dim = [d for d in da.dims if kinds[d] == "lat"]
    time_dims = [d for d in da.dims if kinds[d] == "time"]
    if len(lon_dim) != 1 or len(lat_dim) != 1 or lon_dim[0] not in da.coords or lat_dim[0] not in da.coords:
        raise WeatherError(
            f"{where} is not on a regular longitude/latitude grid (dimensions {list(da.dims)}; expected 1-D "
            f"'longitude'/'lon' and 'latitude'/'lat' coordinates)"
        )
    lon_dim_, lat_dim_ = lon_dim[0], lat_dim[0]
    # time axis
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
        times: npt.NDArray[np.datetime64] | None = np.asarray(valid.values).astype("datetime64[ns]")
    else:
        tdim = "_time"
        da = da.expand_dims(tdim)
        times = None if valid is None else np.asarray([valid.values]).astype("datetime64[ns]")
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
    if times is not None:
        if np.isnat(times).any():
            raise WeatherError(f"{where} has missing (NaT) times")
        t_plan = _sorted_plan(
            times.astype(np.int64), window and (int(window[0].astype(np.int64)), int(window[1].astype(np.int64))), 0
        )
        if t_plan is None:
            return None, had_members
        if np.any(np.diff(np.sort(times.astype(np.int64))) == 0):
            raise WeatherError(f"{where} has repeated times")
        t_index, times = t_plan[0], t_plan[1].astype("datetime64[ns]")
    values = _load(da, (tdim, lat_dim_, lon_dim_), (t_index, lat_plan[0], lon_plan[0]), where)
    values = _convert_units(values, da.attrs, name, where)
    if not np.isfinite(values).any():
        raise WeatherError(f"{where} is all NaN{' inside the requested box and time window' if box or window else ''}")
    field = WeatherField(name, values, lon_plan[1], lat_plan[1], times, source, var, lon_plan[2])
    return field, had_members


def _load(
    da: xr.DataArray, dims: tuple[Hashable, Hashable, Hashable], index: tuple[IntArray, ...], where: str
) -> npt.NDArray[np.float32]:
    """Read only the needed rows/columns (sorted, unique; slices where contiguous), then reorder."""
    selectors: dict[Hashable, Any] = {}
    inverse: list[IntArray | None] = []
    for dim, idx in zip(dims, index, strict=True):
        uniq, inv = np.unique(idx, return_inverse=True)
        contiguous = uniq.size == uniq[-1] - uniq[0] + 1
        selectors[dim] = slice(int(uniq[0]), int(uniq[-1]) + 1) if contiguous else uniq
        inverse.append(None if np.array_equal(inv, np.arange(inv.size)) else inv)
    try:
        values = np.asarray(da.isel(selectors).transpose(*dims).values)
    except Exception as exc:
        raise WeatherError(f"cannot read {where}: {type(exc).__name__}: {exc}") from exc
    if values.dtype.kind not in "fiu":
        raise WeatherError(f"{where} is not numeric (dtype {values.dtype})")
    values = values.astype(np.float32, copy=False)
    for axis, order in enumerate(inverse):
        if order is not None:
            values = np.take(values, order, axis=axis)
    return values


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
    values: npt.NDArray[np.float32], attrs: Mapping[str, Any], name: str, where: str
) -> npt.NDArray[np.float32]:
    kind = _KIND[name]
    raw = attrs.get("units")
    key = "".join(ch for ch in str(raw if raw is not None else "").strip().lower() if ch not in " *^_.")
    if key in _MISSING_UNITS:
        key = "".join(ch for ch in _DEFAULT_UNITS[kind].lower() if ch != " ")
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
        factor *= KNOTS_PER_MS
    if factor != 1.0:
        values = values * np.float32(factor)
    if kind == "direction":
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
                f"field {name!r}: '{a.source}' and '{b.source}' overlap in time ({_iso(b.time[0])} <= "  # type: ignore[index]
                f"{_iso(a.time[-1])}); give files with disjoint times"  # type: ignore[index]
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
    ms = speed.values / np.float32(KNOTS_PER_MS)
    fields["wind_u_ms"] = replace(speed, name="wind_u_ms", values=(-ms * np.sin(rad)).astype(np.float32))
    fields["wind_v_ms"] = replace(speed, name="wind_v_ms", values=(-ms * np.cos(rad)).astype(np.float32))


def _check_field(f: WeatherField) -> None:
    where = f"field {f.name!r} ('{f.source}' variable '{f.variable}')"
    if f.values is None or np.ndim(f.values) != 3:
        raise WeatherError(f"{where}: values must be an array (time, lat, lon)")
    nt = 1 if f.time is None else len(f.time)
    if f.values.shape != (nt, len(f.lat), len(f.lon)):
        raise WeatherError(f"{where}: values have shape {f.values.shape}, axes give {(nt, len(f.lat), len(f.lon))}")
    for axis_name, axis in (("lon", f.lon), ("lat", f.lat), ("time", f.time)):
        if axis is not None and np.any(np.diff(axis.astype(np.int64) if axis_name == "time" else axis) <= 0):
            raise WeatherError(f"{where}: {axis_name} must be strictly increasing")


# ----------------------------------------------------------------------------------------------- helpers


def _check_bbox(bbox: Sequence[float] | None) -> tuple[float, float, float, float] | None:
    if bbox is None:
        return None
    try:
        west, south, east, north = (float(v) for v in bbox)
    except (TypeError, ValueError):
        raise WeatherError(f"bbox must be (west, south, east, north) [deg] (got {bbox!r})") from None
    if not all(np.isfinite((west, south, east, north))) or not -90.0 <= south <= north <= 90.0:
        raise WeatherError(f"bbox must be finite (west, south, east, north) with south <= north [deg] (got {bbox!r})")
    if east < west:
        east += 360.0
    return west, south, east, north


def _to_datetime64(value: Any, what: str) -> np.datetime64:
    """A time (datetime64, datetime, ISO 8601 string with optional 'Z') -> datetime64[ns] (UTC)."""
    try:
        if isinstance(value, _dt.datetime) and value.tzinfo is not None:
            value = value.astimezone(_dt.UTC).replace(tzinfo=None)
        if isinstance(value, str):
            value = value.strip().removesuffix("Z").removesuffix("+00:00")
        out = np.datetime64(value, "ns")  # type: ignore[call-overload]
    except (TypeError, ValueError):
        raise WeatherError(f"{what}: expected a time (datetime64 or ISO 8601 string, UTC) (got {value!r})") from None
    if np.isnat(out):
        raise WeatherError(f"{what}: expected a time, got NaT")
    return out


def _points(
    lon_deg: npt.ArrayLike, lat_deg: npt.ArrayLike, time: npt.ArrayLike
) -> tuple[tuple[int, ...], FloatArray, FloatArray, npt.NDArray[np.datetime64]]:
    lon = np.asarray(lon_deg, dtype=np.float64)
    lat = np.asarray(lat_deg, dtype=np.float64)
    t = np.asarray(time)
    if t.dtype.kind != "M":
        t = np.asarray(np.vectorize(lambda v: _to_datetime64(v, "time"), otypes=["datetime64[ns]"])(t))
    t = t.astype("datetime64[ns]")
    shape = np.broadcast_shapes(lon.shape, lat.shape, t.shape)
    flat = [np.broadcast_to(a, shape).ravel() for a in (lon, lat, t)]
    return shape, flat[0], flat[1], flat[2]


def _iso(t: np.datetime64) -> str:
    return str(np.datetime_as_string(t, unit="m"))
