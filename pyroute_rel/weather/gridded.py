"""Gridded weather in memory, and sampling it: the :class:`~pyroute_rel.weather.WeatherSource` files become.

:mod:`pyroute_rel.weather.io.readers` reads files into :class:`WeatherField` objects (numpy arrays on (time, lat, lon),
longitude contiguous, latitude ascending, units normalised); :class:`GriddedWeather` keeps them and samples
them, linear in time, latitude and longitude.

Wind is interpolated as (u, v), then turned into speed [kn] and direction *from* [deg]; wave direction
as a unit vector; currents as (u, v) *to* [m/s]. A point outside a field's loaded box or times, or with
NaN in a grid value it draws on, gives NaN. Absent currents are 0 [m/s]; absent waves and periods NaN
(see :attr:`GriddedWeather.fields`). A field without time is steady; one with a single time covers that instant
(the readers turn files whose fields each have one time into steady fields). Values outside their plausible range
(:data:`~pyroute_rel.weather.base.RANGES`) are refused, or with ``out_of_range="missing"`` made NaN.

Sampling is the router's hot path (millions of points per route, scattered over a field of a gigabyte), so
it runs in small compiled kernels (numba, ``nogil``: the cost kernel's threads run them side by side). Fields
sharing a grid are stored interleaved, (lat, lon, time, field), so one corner of a point's cell, every field
at both times, is one run of memory.
"""

from __future__ import annotations

import functools
import math
import warnings
import weakref
from collections.abc import Collection, Iterable, Mapping
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from pyroute_rel._kernels import sampling
from pyroute_rel.errors import WeatherCoverageError, WeatherError, WeatherWarning, brief, check_numbers
from pyroute_rel.settings import get_settings
from pyroute_rel.times import iso_minute, to_datetime64
from pyroute_rel.units import KN_PER_MS
from pyroute_rel.weather.base import RANGES, Boundaries, Conditions, Variation, WeatherBase, sample_points

if TYPE_CHECKING:
    pass

__all__ = [
    "GRID_FIELDS",
    "OUT_OF_RANGE",
    "GriddedWeather",
    "PreparedPoints",
    "WeatherField",
    "check_plausible",
    "MemberStack",
    "stack_members",
    "CodedValues",
]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.intp]

#: What to do with values outside their plausible range (:data:`~pyroute_rel.weather.base.RANGES`): ``"error"``
#: refuses the data (the default); ``"missing"`` treats them as missing (NaN: arcs through them are forbidden).
OUT_OF_RANGE = ("error", "missing")

#: Fields a :class:`GriddedWeather` stores (files holding wind speed and direction are converted to u/v on load).
GRID_FIELDS = ("wind_u_ms", "wind_v_ms", "hs_m", "wave_dir_deg", "wave_period_s", "current_u_ms", "current_v_ms")

#: Stored columns each :class:`~pyroute_rel.weather.Conditions` field is computed from.
_NEEDS: dict[str, tuple[str, ...]] = {
    "tws_kn": ("wind_u_ms", "wind_v_ms"),
    "twd_deg": ("wind_u_ms", "wind_v_ms"),
    "hs_m": ("hs_m",),
    "wave_dir_deg": ("_wave_sin", "_wave_cos"),
    "wave_period_s": ("wave_period_s",),
    "current_u_ms": ("current_u_ms", "current_v_ms"),
    "current_v_ms": ("current_u_ms", "current_v_ms"),
}


@dataclass(frozen=True)
class WeatherField:
    """One field on its own (time, lat, lon) grid, in the units of :data:`~pyroute_rel.weather.io.readers.VARIABLES`.

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
    coded : Optionally, ``values`` as a lookup (:class:`CodedValues`: a file's packed integers and the field's value
        for each), so that :class:`GriddedWeather` transforms each distinct value once (a wave direction's sine and
        cosine). Used only while it describes this field's ``values`` array itself (a copy with other values made
        by :func:`dataclasses.replace` is stored from its values).
    """

    name: str
    values: npt.NDArray[np.floating] | None
    lon: FloatArray
    lat: FloatArray
    time: npt.NDArray[np.datetime64] | None
    source: str = "<dataset>"
    variable: str = ""
    periodic: bool = False
    coded: CodedValues | None = field(default=None, repr=False, compare=False)

    def describe(self) -> str:
        """The field's extent, e.g. ``"lon [-70, 0], lat [5, 55] [deg], time 2018-06-01T00:00 .. ..."``."""
        t = "any time" if self.time is None else f"time {iso_minute(self.time[0])} .. {iso_minute(self.time[-1])}"
        lon = "all longitudes" if self.periodic else f"lon [{self.lon[0]:g}, {self.lon[-1]:g}]"
        return f"{lon}, lat [{self.lat[0]:g}, {self.lat[-1]:g}] [deg], {t}"


@dataclass(frozen=True)
class CodedValues:
    """A field's values as a lookup: ``values`` is ``table[codes]``, element by element.

    Attributes
    ----------
    values : The values described (the array of the :class:`WeatherField`, (n_time, n_lat, n_lon)).
    codes : Unsigned integers of the same shape (e.g. a file's packed 16-bit values).
    table : Float32 value of each code.
    """

    values: npt.NDArray[np.floating]
    codes: npt.NDArray[np.unsignedinteger]
    table: npt.NDArray[np.float32]


class _Block:
    """Fields sharing one grid, stored as (n_lat, n_lon, n_time, n_fields) float32.

    Fields, then time, are the innermost axes: everything a point needs from one corner of its cell (every
    field, at the two times it lies between) sits in one run of ``2 n_fields`` floats, so interpolating a point
    touches four places in memory, not forty.
    """

    def __init__(self, fields: list[WeatherField]):
        ref = fields[0]
        nt, ny, nx = ref.values.shape  # type: ignore[union-attr]
        # wave direction is stored as (sin, cos) of the angle: a unit vector interpolates across north
        cols = [(f, op) for f in fields for op in ((np.sin, np.cos) if f.name == "wave_dir_deg" else (None,))]
        self.names = [{np.sin: "_wave_sin", np.cos: "_wave_cos"}.get(op, f.name) for f, op in cols]  # type: ignore[arg-type]
        nf = len(cols)
        self.data = np.empty((ny, nx, nt, nf), dtype=np.float32)
        rows = max(1, (1 << 22) // max(1, nt * nx))
        for j, (f, op) in enumerate(cols):
            values: npt.NDArray[Any] | None = f.values  # the field's values, or its codes looked up in ``table``
            table = None
            if f.coded is not None and f.coded.values is values and op is not None:  # each code's sine (cosine)
                values, table, op = f.coded.codes, op(np.deg2rad(f.coded.table.astype(np.float32))), None  # looked up
            if op is None and _fill_column(self.data, j, values, table):
                continue
            for y0 in range(0, ny, rows):  # in bands of latitude: no full-size temporaries
                band = np.asarray(values[:, y0 : y0 + rows, :])  # type: ignore[index]
                chunk = np.moveaxis(band if table is None else np.take(table, band), 0, -1)
                self.data[y0 : y0 + rows, :, :, j] = chunk if op is None else op(np.deg2rad(chunk.astype(np.float32)))
        self.flat = self.data.reshape(-1)
        self.n_fields = nf
        self.lon, self.lat = ref.lon, ref.lat
        self.t0 = ref.time[0] if ref.time is not None else np.datetime64("NaT", "ns")
        self.time = ref.time
        self.time_s = _NO_TIME if ref.time is None else (ref.time - self.t0) / np.timedelta64(1, "s")
        self.lon_mid = 0.5 * (self.lon[0] + self.lon[-1])
        self.strides = (nf, nx * nt * nf, nt * nf)  # time, lat, lon
        self._plans: dict[tuple[frozenset[str] | None, bool], _SamplingPlan] = {}

    def locate(self, lon: FloatArray, lat: FloatArray) -> _Where:
        """Where points (1-D arrays) fall on this block's grid (reused by every time at which they are sampled)."""
        inside = (lon >= self.lon[0]) & (lon <= self.lon[-1])
        if not inside.all():  # the equivalent longitude (+- 360) nearest to the grid's middle
            lon = np.where(inside, lon, (lon - self.lon_mid + 180.0) % 360.0 - 180.0 + self.lon_mid)
        ix, wx, sx, ok = _locate(self.lon, lon, self.strides[2])
        iy, wy, sy, ok_y = _locate(self.lat, lat, self.strides[1])
        ok &= ok_y
        ix *= self.strides[2]
        iy *= self.strides[1]
        iy += ix
        return _Where(base=iy, sx=sx, sy=sy, wx=wx, wy=wy, ok=ok)

    def interpolate_at(
        self,
        where: _Where,
        origin: np.datetime64,
        offset: FloatArray,
        columns: IntArray,
        scale: float = 1.0,
        convert: tuple[int, int, int, int] = (-1, -1, -1, -1),
    ) -> FloatArray:
        """The stored ``columns`` at located points and times ``origin + offset * scale`` [s] (``offset`` 1-D,
        contiguous; ``scale`` [s] per its unit) -> (len(columns), n_points), NaN outside. The kernel computes each
        point's time on the block's axis, ``offset * scale + (origin - t0)`` (rounded after each operation).

        ``convert``: rows (of the output; -1: none) of wind u and v, and of the wave direction's sine and cosine,
        turned into speed [kn] and direction [deg] (the wind: in its u and v rows) and the wave direction [deg] (in
        its sine's row) as each point is interpolated (:func:`sampling.interpolate`): what :func:`sampling.vectors`
        makes of the rows afterwards, without a second pass over them."""
        shift = (origin - self.t0) / np.timedelta64(1, "s") if self.time_s.size else 0.0  # steady: any time will do
        out = np.empty((columns.size, where.base.size))
        sampling.interpolate(
            self.flat,
            self.n_fields,
            columns,
            where.base,
            where.sx,
            where.sy,
            where.wx,
            where.wy,
            where.ok,
            offset,
            float(scale),
            float(shift),
            self.time_s,
            *convert,
            KN_PER_MS,
            out,
        )
        return out

    def plan(self, wanted: frozenset[str] | None, convert: bool) -> _SamplingPlan:
        """How :meth:`GriddedWeather._interpolate_at` samples the columns ``wanted`` (None: all): the columns' indices,
        the rows :meth:`interpolate_at` turns (``convert``: :func:`_pair_rows`, else none) and the name of each row
        it keeps (a turned pair's fields in place of its columns: :data:`_TURNED`); kept per set."""
        key = (wanted, convert)
        kept = self._plans.get(key)
        if kept is None:
            names = [name for name in self.names if wanted is None or name in wanted]
            index = np.asarray([self.names.index(name) for name in names], dtype=np.intp)
            rows = _pair_rows(names) if convert else (-1, -1, -1, -1)
            named = {name: row for row, name in enumerate(names)}
            for (a, b), (ra, rb), fields in zip(_PAIRS, (rows[:2], rows[2:]), _TURNED, strict=True):
                if ra >= 0:
                    del named[a], named[b]
                    named.update(zip(fields, (ra, rb)[: len(fields)], strict=True))
            kept = self._plans[key] = (index, rows, list(named.items()))
        return kept


#: A block's sampling plan (:meth:`_Block.plan`): the stored columns' indices, the rows turned, each row's name.
_SamplingPlan = tuple[IntArray, tuple[int, int, int, int], list[tuple[str, int]]]


def _fill_column(data: npt.NDArray[np.float32], j: int, values: Any, table: npt.NDArray[np.float32] | None) -> bool:
    """Column ``j`` of a block's (lat, lon, time, field) data set to ``table[values]``, ``values`` 8- or 16-bit codes
    (n_time, n_lat, n_lon), in one compiled pass (no full-size temporary); False (nothing done) for anything else
    (:class:`_Block` copies it with numpy, which copies float32 values as fast: the same numbers)."""
    if table is None or not isinstance(values, np.ndarray) or values.ndim != 3 or data.dtype != np.float32:
        return False
    if values.dtype in (np.uint8, np.uint16) and table.dtype == np.float32:
        if table.size < 1 << (8 * values.dtype.itemsize):
            return False
        sampling.fill_codes(data, j, np.moveaxis(values, 0, -1), table)
        return True
    return False


#: Stored column pairs turned into :class:`Conditions` fields (:data:`_TURNED`) as they are interpolated.
_PAIRS = (("wind_u_ms", "wind_v_ms"), ("_wave_sin", "_wave_cos"))
_TURNED = (("tws_kn", "twd_deg"), ("wave_dir_deg",))
_TURNED_FIELDS = ("tws_kn", "twd_deg", "wave_dir_deg")


def _pair_rows(names: list[str]) -> tuple[int, int, int, int]:
    """Rows of ``names`` (a block's columns picked) holding each pair of :data:`_PAIRS` (-1, -1 where the block does
    not hold both)."""
    rows: list[int] = []
    for a, b in _PAIRS:
        rows += [names.index(a), names.index(b)] if a in names and b in names else [-1, -1]
    return rows[0], rows[1], rows[2], rows[3]


#: :class:`Conditions` fields :meth:`GriddedWeather._conditions` takes as the columns give them.
_DIRECT_FIELDS = (*_TURNED_FIELDS, "hs_m", "wave_period_s", "current_u_ms", "current_v_ms")


def _wanted_columns(fields: Collection[str]) -> frozenset[str]:
    """The stored columns :class:`Conditions` fields ``fields`` are made of."""
    unknown = sorted(set(fields) - set(_NEEDS))
    if unknown:
        raise WeatherError(f"'fields' must be Conditions fields {sorted(_NEEDS)} (got {unknown})")
    return frozenset(col for name in fields for col in _NEEDS[name])


#: Time axis of a block steady in time (any time is valid).
_NO_TIME = np.zeros(0)


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
    owner: weakref.ref[Any]  # the GriddedWeather that located them (a reference: its id may be a dead one's)
    grid: tuple[Any, ...] = ()  # its grids (GriddedWeather.grid_key): sources with an equal key may reuse them


def _locate(axis: FloatArray, x: FloatArray, stride: int) -> tuple[IntArray, FloatArray, IntArray, Any]:
    """Cell index, weight of the upper neighbour, index step to it and in-range mask, per point.

    The cell is the one a binary search finds (``searchsorted(axis, x, "right") - 1``, clipped to the axis);
    the weight is 0 on the last grid line; the step is 0 where the weight is not positive (on a grid line, or
    outside), so a NaN neighbour that does not contribute never spoils the result.
    """
    # contiguous, writable float64: one compiled signature (a read-only array would be another)
    axis = np.require(axis, np.float64, ("C", "W"))
    x = np.require(x, np.float64, ("C", "W"))
    i = np.empty(x.shape, dtype=np.intp)
    w = np.empty(x.shape)
    step = np.empty(x.shape, dtype=np.intp)
    ok = np.empty(x.shape, dtype=np.bool_)
    sampling.locate(axis, x.reshape(-1), int(stride), i.reshape(-1), w.reshape(-1), step.reshape(-1), ok.reshape(-1))
    return i, w, step, ok


# ----------------------------------------------------------------------------------------------- kernels
# Compiled with numba (cached on disk after the first run); they release the GIL. Excluded from coverage.


@functools.cache
def _load_kernels() -> None:
    """Load (or, the first time ever, compile) the kernels by calling each once on a tiny input."""
    axis = np.array([0.0, 1.0])
    i, w, step, ok = _locate(axis, np.array([0.5]), 1)
    out = np.empty((1, 1))
    sampling.interpolate(
        np.zeros(8, np.float32),
        1,
        np.zeros(1, np.intp),
        i,
        step,
        step,
        w,
        w,
        ok,
        w,
        1.0,
        0.0,
        axis,
        -1,
        -1,
        -1,
        -1,
        1.0,
        out,
    )
    sampling.vectors(w, w, 1.0, 1.0, np.empty(1), np.empty(1))


class GriddedWeather(WeatherBase):
    """Gridded, time-varying weather: a :class:`~pyroute_rel.weather.WeatherSource` over numpy arrays.

    Build it with :func:`~pyroute_rel.weather.io.readers.open_weather` (files) or
    :func:`~pyroute_rel.weather.io.readers.weather_from_dataset` (an in-memory :class:`xarray.Dataset`); the
    constructor takes ready :class:`WeatherField` objects. The source is :attr:`steady` when no field has a time axis
    (readers give files whose fields each have a single time that way).

    Parameters
    ----------
    fields : Fields on their own grids; ``wind_u_ms`` and ``wind_v_ms`` are required. Their arrays
        are copied into float32 blocks (fields on the same grid share one block).
    out_of_range : ``"error"`` (default) refuses a value outside its plausible range
        (:data:`~pyroute_rel.weather.base.RANGES`); ``"missing"`` treats it as missing (see :func:`check_plausible`).

    Building one also loads the compiled sampling kernels: about half a second the first time in a process
    (numba's start-up), a few seconds once after installing (compiling them; the result is cached on disk).
    """

    def __init__(self, fields: Iterable[WeatherField], *, out_of_range: str = "error"):
        if not isinstance(out_of_range, str) or out_of_range not in OUT_OF_RANGE:
            raise WeatherError(f"out_of_range must be one of {list(OUT_OF_RANGE)} (got {brief(out_of_range)})")
        if isinstance(fields, (str, bytes, Mapping)) or not isinstance(fields, Iterable):
            raise WeatherError(f"fields must be a list of WeatherField objects (got {brief(fields)})")
        fields = list(fields)
        for f in fields:
            if not isinstance(f, WeatherField):
                raise WeatherError(f"fields must be WeatherField objects (got {brief(f)}, a {type(f).__name__})")
        names = [f.name for f in fields]
        for k, f in enumerate(fields):
            if not isinstance(f, WeatherField):
                raise WeatherError(f"fields must be WeatherField objects (got {type(f).__name__})")
            if f.name not in GRID_FIELDS:
                raise WeatherError(f"field name must be one of {list(GRID_FIELDS)} (got {f.name!r})")
            if names.count(f.name) > 1:
                raise WeatherError(f"field {f.name!r} is given more than once")
            _check_field(f)
            fields[k] = check_plausible(f, out_of_range=out_of_range)
        if "wind_u_ms" not in names or "wind_v_ms" not in names:
            srcs = sorted({f.source for f in fields}) or ["<no field>"]
            raise WeatherError(
                f"no 10 m wind (u and v components) found in {', '.join(map(repr, srcs))}; wind is required "
                f"(name the variables with variables={{'wind_u_ms': ..., 'wind_v_ms': ...}})"
            )
        if ("current_u_ms" in names) != ("current_v_ms" in names):
            raise WeatherError(
                "currents need both components, current_u_ms and current_v_ms "
                f"(got only {'current_u_ms' if 'current_u_ms' in names else 'current_v_ms'})"
            )
        self._info: dict[str, WeatherField] = {f.name: replace(f, values=None, coded=None) for f in fields}
        groups: dict[tuple[bytes, bytes, bytes | None], list[WeatherField]] = {}
        for f in fields:
            key = (f.lon.tobytes(), f.lat.tobytes(), None if f.time is None else f.time.tobytes())
            groups.setdefault(key, []).append(f)
        self._blocks = [_Block(group) for group in groups.values()]
        self._steady = all(f.time is None for f in fields)
        self._variations: dict[str, Variation | None] = {}
        _load_kernels()  # numba's first call in a process costs half a second: pay it with the file, not the route

    @property
    def steady(self) -> bool:
        """True when no field has a time axis (the data hold at any time: the router samples each arc once); False
        otherwise (every point is sampled at its own time)."""
        return self._steady

    @functools.cached_property
    def time_steps(self) -> npt.NDArray[np.datetime64] | None:
        """Every field's times together (``datetime64[ns]``, increasing): between two of them each field is linear
        in time. None when steady."""
        times = [b.time.astype("datetime64[ns]") for b in self._blocks if b.time is not None]
        if self._steady or not times:
            return None
        return np.unique(np.concatenate(times))

    @property
    def fields(self) -> frozenset[str]:
        """Names of :class:`~pyroute_rel.weather.Conditions` fields the data actually provide."""
        out = {"tws_kn", "twd_deg"}
        out.update(n for n in ("hs_m", "wave_dir_deg", "wave_period_s") if n in self._info)
        if "current_u_ms" in self._info and "current_v_ms" in self._info:
            out.update(("current_u_ms", "current_v_ms"))
        return frozenset(out)

    @functools.cached_property
    def boundaries(self) -> Boundaries:
        """The grid lines of every field (meridians and parallels [deg]): fields are bilinear within a cell and bend
        across its edges. Used to judge arcs on every cell they cross (:mod:`pyroute_rel.reliability.crossings`)."""
        lons = np.unique(np.concatenate([np.asarray(b.lon, dtype=float) for b in self._blocks]))
        lats = np.unique(np.concatenate([np.asarray(b.lat, dtype=float) for b in self._blocks]))
        return Boundaries(lons, lats, None, continuous=True)

    def variation(self, field: str) -> Variation | None:
        """A bound on how much a :class:`~pyroute_rel.weather.Conditions` field changes between two points (None:
        not in the data, or no bound).

        A bilinear (in time, trilinear) interpolant's slope along each axis is a weighted mean of the differences
        between neighbouring nodes, so ``hs_m`` and ``wave_period_s`` change by at most the largest neighbour
        difference per grid step along each axis; ``tws_kn``, the length of the interpolated wind, by at most the
        sum of its components'. A direction (``twd_deg``, ``wave_dir_deg``) interpolated from vectors stays within
        the angular hull of its cell's corners (when they span less than 180 deg), so it changes by at most the
        corners' spread (the sum of the largest angles between neighbours along each axis) per cell entered: four
        (the cells of both points, and one more along each axis at worst) plus one per grid step travelled.
        Computed once per field and cached.
        """
        cached = self._variations.get(field)
        if cached is None and field not in self._variations:
            cached = self._variations[field] = _variation(self._blocks, field)
        return cached

    @property
    def field_info(self) -> Mapping[str, WeatherField]:
        """Per stored field: grid axes, source file and variable (``values`` is ``None``)."""
        return dict(self._info)

    @functools.cached_property
    def max_current_ms(self) -> float:
        """A bound on the current's speed anywhere in the data [m/s]: the largest |u| and |v| combined (0 without
        currents; NaN cells ignored)."""
        big = [0.0, 0.0]
        for block in self._blocks:
            for j, name in enumerate(block.names):
                if name in ("current_u_ms", "current_v_ms"):
                    m = float(np.nanmax(np.abs(block.data[..., j]), initial=0.0))
                    big[name == "current_v_ms"] = max(big[name == "current_v_ms"], m)
        return math.hypot(big[0], big[1])

    @property
    def nbytes(self) -> int:
        """Memory held by the gridded data [bytes]."""
        return sum(b.data.nbytes for b in self._blocks)

    def _interpolate(self, lon: FloatArray, lat: FloatArray, time: npt.NDArray[np.datetime64]) -> dict[str, FloatArray]:
        return self._interpolate_at(tuple(b.locate(lon, lat) for b in self._blocks), *_offsets(time))

    def _interpolate_at(
        self,
        where: tuple[_Where, ...],
        origin: np.datetime64,
        offset: FloatArray,
        wanted: frozenset[str] | None = None,
        scale: float = 1.0,
        convert: bool = False,
    ) -> dict[str, FloatArray]:
        """The stored columns ``wanted`` (None: all) at located points and times ``origin + offset * scale`` [s].

        ``convert``: the wind and the wave direction stored in one block come as :class:`Conditions` fields
        (``tws_kn``, ``twd_deg``; ``wave_dir_deg``) turned as they are interpolated (:meth:`_Block.interpolate_at`),
        in place of their stored columns (:attr:`~pyroute_rel.settings.Settings.fused_sampling`: one compiled loop,
        no arrays of components; False: the components are interpolated, then turned by :func:`sampling.vectors`)."""
        out: dict[str, FloatArray] = {}
        for block, w in zip(self._blocks, where, strict=True):
            index, rows, named = block.plan(wanted, convert)
            if named:
                values = block.interpolate_at(w, origin, offset, index, scale, rows)
                out.update((name, values[row]) for name, row in named)
        return out

    def prepare(self, lon_deg: npt.ArrayLike, lat_deg: npt.ArrayLike) -> PreparedPoints:
        """Locate points on the data's grids once, for :meth:`sample_at` at several times (the cost kernel samples
        the same arc points at the departure time and again at the times the boat gets there).

        >>> import xarray as xr
        >>> from pyroute_rel.weather.io.readers import weather_from_dataset
        >>> ds = xr.Dataset({"u10": (("latitude", "longitude"), np.ones((2, 2))),
        ...                  "v10": (("latitude", "longitude"), np.zeros((2, 2)))},
        ...                 coords={"latitude": [40.0, 50.0], "longitude": [-20.0, -10.0]})
        >>> w = weather_from_dataset(ds)
        >>> p = w.prepare([-15.0, -12.0], 45.0)
        >>> float(w.sample_at(p, np.datetime64("2018-06-01")).twd_deg[1])
        270.0
        """
        lon = np.asarray(lon_deg, dtype=np.float64)
        lat = np.asarray(lat_deg, dtype=np.float64)
        shape = np.broadcast_shapes(lon.shape, lat.shape)
        lon_f, lat_f = (np.broadcast_to(a, shape).ravel() for a in (lon, lat))
        return PreparedPoints(
            shape=shape,
            lon=lon_f,
            lat=lat_f,
            owner=weakref.ref(self),
            where=tuple(b.locate(lon_f, lat_f) for b in self._blocks),
            grid=self.grid_key,
        )

    @functools.cached_property
    def grid_key(self) -> tuple[Any, ...]:
        """What points located by :meth:`prepare` depend on: per block of fields sharing a grid, its longitudes and
        latitudes (as bytes), its memory layout (the index steps along time, latitude and longitude) and its size.
        Two sources with equal keys locate every point alike (members of one file, a file and its ensemble mean)."""
        return tuple((b.lon.tobytes(), b.lat.tobytes(), b.strides, b.flat.size) for b in self._blocks)

    def reuse(self, prepared: PreparedPoints) -> PreparedPoints | None:
        """Points another source's :meth:`prepare` located, for this source's :meth:`sample_at`: the same points
        (nothing is located again) when that source's :attr:`grid_key` equals this one's, else None.

        The cost kernel keeps the points of each arc geometry it costs and reuses them in every source on the same
        grid (:func:`pyroute_rel.routing.cost.geometry_costs`): locating them is a tenth of a route over time-varying
        gridded weather.
        """
        key = self.grid_key
        if not (prepared.grid is key or prepared.grid == key):
            return None
        return prepared if prepared.owner() is self else replace(prepared, owner=weakref.ref(self))

    def take(self, prepared: PreparedPoints, index: npt.NDArray[np.intp]) -> PreparedPoints:
        """The points ``index`` (flat indices, C order) of points located by :meth:`prepare`, as a 1-D set: the same
        numbers from :meth:`sample_at` as those points in the whole set (the march samples the arcs still sailing)."""
        if prepared.owner() is not self:
            raise WeatherError("these points were prepared for another weather source: use its prepare()")
        where = tuple(
            _Where(w.base[index], w.sx[index], w.sy[index], w.wx[index], w.wy[index], w.ok[index])
            for w in prepared.where
        )
        return replace(
            prepared, shape=(int(index.size),), lon=prepared.lon[index], lat=prepared.lat[index], where=where
        )

    def sample_at(
        self,
        prepared: PreparedPoints,
        departure: npt.ArrayLike,
        *,
        offset_h: npt.ArrayLike | None = None,
        fields: Collection[str] | None = None,
    ) -> Conditions:
        """:meth:`sample` at points located by :meth:`prepare`.

        Parameters
        ----------
        prepared : From :meth:`prepare`.
        departure : Times (``datetime64``, UTC), broadcast to the points' shape; or, with ``offset_h``, one origin.
        offset_h : Hours after ``departure`` [h], broadcast to the points' shape (NaN gives NaN conditions); the
            cost kernel's departure times, passed without building an array of datetimes.
        fields : :class:`~pyroute_rel.weather.Conditions` fields wanted (default all); the others are not
            interpolated and come back NaN (the cost kernel's timing pass needs only wind and current).
        """
        if prepared.owner() is not self:
            raise WeatherError("these points were prepared for another weather source: use its prepare()")
        t = np.asarray(departure)
        if t.dtype.kind != "M":
            raise WeatherError(f"'departure' must be datetime64 (got dtype {t.dtype})")
        wanted = None if fields is None else _wanted_columns(fields if isinstance(fields, tuple) else tuple(fields))
        if offset_h is None:
            origin, offset = _offsets(np.broadcast_to(t.astype("datetime64[ns]"), prepared.shape).ravel())
            scale = 1.0
        else:
            if t.ndim:
                raise WeatherError(f"with 'offset_h', 'departure' must be one origin (got shape {t.shape})")
            origin = np.datetime64(t.astype("datetime64[ns]").item(), "ns")
            # hours, turned into seconds in the kernel (offset_h * 3600, then the block's origin added); a contiguous
            # float64 array of the points' shape (the cost kernel's) is passed as it is
            if (
                isinstance(offset_h, np.ndarray)
                and offset_h.dtype == np.float64
                and offset_h.shape == prepared.shape
                and offset_h.flags.c_contiguous
            ):
                offset = offset_h
            else:
                offset = np.ascontiguousarray(np.broadcast_to(np.asarray(offset_h, dtype=np.float64), prepared.shape))
            offset = offset.reshape(-1)
            scale = 3600.0
        fused = get_settings().fused_sampling
        values = self._interpolate_at(prepared.where, origin, offset, wanted, scale, convert=fused)
        return self._conditions(prepared.shape, values, fields)

    def interpolate(self, name: str, lon_deg: npt.ArrayLike, lat_deg: npt.ArrayLike, time: npt.ArrayLike) -> FloatArray:
        """One stored field (e.g. ``"wind_u_ms"`` [m/s]) at broadcast points; NaN where unknown."""
        if name not in self._info:
            raise WeatherError(f"'name' must be one of {sorted(self._info)} (got {name!r})")
        shape, lon, lat, t = _points(lon_deg, lat_deg, time)
        values = self._interpolate(lon, lat, t)
        if name == "wave_dir_deg":
            out = np.empty(values["_wave_sin"].size)
            sampling.vectors(values["_wave_sin"], values["_wave_cos"], 1.0, 1.0, _NO_TIME, out)
            return out.reshape(shape)
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

    def _conditions(
        self, shape: tuple[int, ...], v: dict[str, FloatArray], fields: Collection[str] | None = None
    ) -> Conditions:
        n = math.prod(shape)
        out = {name: v[name] for name in _DIRECT_FIELDS if name in v}  # stored, or turned as they were interpolated
        if "wind_u_ms" in v:
            out["tws_kn"], out["twd_deg"] = np.empty(n), np.empty(n)
            sampling.vectors(v["wind_u_ms"], v["wind_v_ms"], -1.0, KN_PER_MS, out["tws_kn"], out["twd_deg"])
        if "_wave_sin" in v:
            out["wave_dir_deg"] = np.empty(n)
            sampling.vectors(v["_wave_sin"], v["_wave_cos"], 1.0, 1.0, _NO_TIME, out["wave_dir_deg"])
        if len(out) < len(_NEEDS):
            nan = np.full(n, np.nan)  # one array for every field not sampled
            for name in _NEEDS:
                if name not in out:
                    none = name.startswith("current") and (fields is None or name in fields)
                    out[name] = np.zeros(n) if none else nan  # no current in the data
        return Conditions(**{k: a.reshape(shape) for k, a in out.items()})

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
        lon_range, lat_range = (_pair(r, name) for r, name in ((lon_range, "lon_range"), (lat_range, "lat_range")))
        if not isinstance(time_range, (list, tuple, np.ndarray)) or len(time_range) != 2:
            raise WeatherError(f"time_range must be a pair (first, last) of times (got {brief(time_range)})")
        lo, hi = lon_range
        if hi < lo:
            hi += 360.0
        t0, t1 = (to_datetime64(t, "time_range") for t in time_range)
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
                    f"time {iso_minute(t0)} .. {iso_minute(t1)} ({' and '.join(short)} not covered)"
                )


class MemberStack:
    """Gridded weathers on one grid (the members of an ensemble file) laid end to end, so that one query samples
    them all: row ``r`` (first axis) of a query is answered by ``sources[member[r]]``, with the numbers that source's
    own :meth:`GriddedWeather.sample_at` gives (the same compiled kernel, each point's cell index moved to its
    member's data). Built by :func:`stack_members`; it holds a copy of the sources' data (:attr:`nbytes`), or of the
    part of it within ``box`` (``lon_min, lon_max, lat_min, lat_max`` [deg]: the cells of every point that may be
    queried; a point outside it is refused).

    Used to sail many tracks in many members at once (:func:`pyroute_rel.analysis.evaluate.sail_in_members`): one call
    per leg instead of one per member.
    """

    def __init__(self, sources: list[GriddedWeather], box: tuple[float, float, float, float] | None = None) -> None:
        first = sources[0]
        joined = object.__new__(GriddedWeather)  # the first source's grids, over every source's data
        joined._info = dict(first._info)
        joined._steady = first._steady
        joined._variations = {}
        joined._blocks = []
        self._sizes = []
        self._box = box
        for k, block in enumerate(first._blocks):
            x = y = slice(None)
            if box is not None:  # longitudes only when the box is within the grid's (no point moved by 360 deg)
                y = _crop(block.lat, box[2:])
                x = _crop(block.lon, box[:2]) if block.lon[0] <= box[0] and box[1] <= block.lon[-1] else x
            b = object.__new__(_Block)
            b.__dict__.update(block.__dict__)  # lon_mid kept: points are moved across 360 deg as the source moves them
            b.lon, b.lat = block.lon[x], block.lat[y]
            shape = (b.lat.size, b.lon.size, *block.data.shape[2:])
            b.strides = (shape[3], shape[1] * shape[2] * shape[3], shape[2] * shape[3])
            size = int(np.prod(shape))
            b.flat = np.empty(size * len(sources), dtype=block.data.dtype)
            for m, src in enumerate(sources):
                b.flat[m * size : (m + 1) * size].reshape(shape)[...] = src._blocks[k].data[y, x]
            del b.data  # sampling reads ``flat`` only
            joined._blocks.append(b)
            self._sizes.append(size)
        self._joined = joined
        self.n_members = len(sources)

    @property
    def nbytes(self) -> int:
        """Memory held by the stacked data [bytes]."""
        return sum(b.flat.nbytes for b in self._joined._blocks)

    @property
    def joined(self) -> GriddedWeather:
        """The first source's grids over every source's data: what points located by :meth:`prepare` index (the
        compiled march, :mod:`pyroute_rel._kernels.march`, reads it)."""
        return self._joined

    def prepare(self, lon_deg: npt.ArrayLike, lat_deg: npt.ArrayLike, member: npt.ArrayLike) -> PreparedPoints:
        """Locate points (as :meth:`GriddedWeather.prepare`) whose rows (first axis) are in members ``member``
        (one index per row), for :meth:`sample_at`."""
        p = self._joined.prepare(lon_deg, lat_deg)
        if self._box is not None:  # cells outside it were not stacked
            x, y = p.lon[np.isfinite(p.lon)], p.lat[np.isfinite(p.lat)]
            lon_min, lon_max, lat_min, lat_max = self._box
            if x.size and not (lon_min <= x.min() and x.max() <= lon_max and lat_min <= y.min() and y.max() <= lat_max):
                raise WeatherError(f"points outside the stacked members' box {list(self._box)} [deg] (lon, lat)")
        rows = np.asarray(member, dtype=np.intp)
        if rows.shape != p.shape[:1] or (rows.size and not 0 <= rows.min() <= rows.max() < self.n_members):
            raise WeatherError(
                f"member must give one member index in [0, {self.n_members - 1}] per row ({p.shape[:1]}) "
                f"(got {brief(member)})"
            )
        per_row = int(np.prod(p.shape[1:], dtype=np.int64))
        where = tuple(
            replace(w, base=w.base + np.repeat(rows * size, per_row))
            for w, size in zip(p.where, self._sizes, strict=True)
        )
        return replace(p, where=where)

    def sample_at(
        self,
        prepared: PreparedPoints,
        departure: npt.ArrayLike,
        *,
        offset_h: npt.ArrayLike | None = None,
        fields: Collection[str] | None = None,
    ) -> Conditions:
        """:meth:`GriddedWeather.sample_at` at points located by :meth:`prepare`, each row in its member."""
        return self._joined.sample_at(prepared, departure, offset_h=offset_h, fields=fields)


def _crop(axis: FloatArray, span: tuple[float, float]) -> slice:
    """The grid lines of ``axis`` (increasing) whose cells hold every point of ``span`` [deg] (clipped to the axis)."""
    i0 = max(int(np.searchsorted(axis, span[0], side="right")) - 1, 0)
    i1 = min(int(np.searchsorted(axis, span[1], side="left")), axis.size - 1)
    return slice(i0, max(i1, i0) + 1)


def stack_members(
    sources: Iterable[Any], *, box: tuple[float, float, float, float] | None = None
) -> MemberStack | None:
    """A :class:`MemberStack` of weather sources, or None unless they are all :class:`GriddedWeather` with the same
    fields on the same grids and times (as the members of one file are). ``box``: ``lon_min, lon_max, lat_min,
    lat_max`` [deg] holding every point to be sampled (within the grids' longitudes, as they are given: not moved
    across 360 deg), to stack the cells there only (None: all)."""
    sources = list(sources)
    if not sources or not all(type(s) is GriddedWeather for s in sources):
        return None
    first = sources[0]
    for s in sources[1:]:
        if s._steady != first._steady or list(s._info) != list(first._info) or len(s._blocks) != len(first._blocks):
            return None
        for a, b in zip(s._blocks, first._blocks, strict=True):
            same = (
                a.names == b.names
                and a.flat.shape == b.flat.shape
                and a.strides == b.strides
                and np.array_equal(a.lon, b.lon)
                and np.array_equal(a.lat, b.lat)
                and np.array_equal(a.time_s, b.time_s)
                and (a.t0 == b.t0 or (np.isnat(a.t0) and np.isnat(b.t0)))
            )
            if not same:
                return None
    return MemberStack(sources, box)


def _pair(value: Any, name: str) -> tuple[float, float]:
    """A (low, high) pair of finite numbers [deg], or WeatherError naming ``name``."""
    pair = check_numbers(value, name, WeatherError, missing=False, unit="deg")
    if pair.shape != (2,):
        raise WeatherError(f"{name} must be a pair of numbers [deg] (got {brief(value)})")
    return float(pair[0]), float(pair[1])


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


def check_plausible(f: WeatherField, *, out_of_range: str = "error") -> WeatherField:
    """The field with its values checked against their plausible range (:data:`~pyroute_rel.weather.base.RANGES`).

    NaN is missing and always allowed. A value outside the range (an infinity, a fill value the file does not
    declare such as the netCDF default 9.97e36, a negative wave height) is refused with a
    :class:`~pyroute_rel.errors.WeatherError` naming the file, the variable, how many values and where the first one
    lies; with ``out_of_range="missing"`` such values become NaN instead (arcs through them are forbidden, never
    read as calm), with a :class:`~pyroute_rel.errors.WeatherWarning` saying how many.

    Parameters
    ----------
    f : A field, its values in the units of its name (directions may still be in [-180, 180)).
    out_of_range : ``"error"`` or ``"missing"`` (:data:`OUT_OF_RANGE`).

    Returns
    -------
    WeatherField
        ``f`` itself when every value is plausible; a copy with NaN in place of the others (``"missing"``).

    Examples
    --------
    >>> hs = np.array([[[1.0, 2.0], [-5.0, 3.0]]])
    >>> f = WeatherField("hs_m", hs, np.array([0.0, 1.0]), np.array([50.0, 51.0]), None, "waves.nc", "swh")
    >>> try:
    ...     check_plausible(f)
    ... except WeatherError as exc:
    ...     print(str(exc)[:75])
    ...     print(str(exc)[76:].split(";")[0])
    weather file 'waves.nc' variable 'swh': 1 value outside the plausible range
    [0, 30] m of significant wave height (e.g. -5 at lon 0, lat 51, any time)
    """
    if not isinstance(out_of_range, str) or out_of_range not in OUT_OF_RANGE:
        raise WeatherError(f"out_of_range must be one of {list(OUT_OF_RANGE)} (got {brief(out_of_range)})")
    rng = RANGES[f.name]
    values = np.asarray(f.values)
    if values.size == 0 or values.dtype.kind not in "fiu":
        return f
    lo, hi = np.fmin.reduce(values, axis=None), np.fmax.reduce(values, axis=None)  # NaN only when all NaN
    if not (lo < rng.lo or hi > rng.hi):
        return f
    bad = (values < rng.lo) | (values > rng.hi)  # False at NaN
    count = int(np.count_nonzero(bad))
    it, iy, ix = np.unravel_index(int(np.argmax(bad)), values.shape)
    when = "any time" if f.time is None else iso_minute(f.time[it])
    lon = (float(f.lon[ix]) + 180.0) % 360.0 - 180.0
    what = (
        f"weather file '{f.source}' variable '{f.variable or f.name}': {count} value{'s' * (count != 1)} outside the "
        f"plausible range {rng.describe()} of {rng.label[: rng.label.rfind(' [')]} "
        f"(e.g. {float(values[it, iy, ix]):.6g} at lon {lon:g}, lat {float(f.lat[iy]):g}, {when})"
    )
    if out_of_range == "error":
        raise WeatherError(
            f"{what}; a fill value the file does not declare? Declare it as _FillValue, or set [weather] "
            f'out_of_range = "missing" to treat such values as missing'
        )
    warnings.warn(f"{what} treated as missing: arcs through them are forbidden", WeatherWarning, stacklevel=2)
    cleaned = np.where(bad, np.nan, values)
    return replace(f, values=cleaned.astype(values.dtype, copy=False) if values.dtype.kind == "f" else cleaned)


# ----------------------------------------------------------------------------------------------- helpers


def _points(
    lon_deg: npt.ArrayLike, lat_deg: npt.ArrayLike, time: npt.ArrayLike
) -> tuple[tuple[int, ...], FloatArray, FloatArray, npt.NDArray[np.datetime64]]:
    lon, lat, t = sample_points(lon_deg, lat_deg, time)
    return lon.shape, lon.ravel(), lat.ravel(), t.ravel()


def _offsets(time: npt.NDArray[np.datetime64]) -> tuple[np.datetime64, FloatArray]:
    """Times (1-D ``datetime64[ns]``) as an origin and contiguous float seconds after it, as the kernels take them."""
    origin = time[0] if time.size else np.datetime64(0, "ns")
    return origin, np.ascontiguousarray((time - origin) / np.timedelta64(1, "s"), dtype=np.float64)


#: Stored columns of the blocks behind each Conditions field whose variation can be bounded, and how: "scalar" (its
#: neighbour differences), "length" (of a vector: the sum of its components'), "angle" (of a vector).
_VARIATION_COLUMNS: dict[str, tuple[tuple[str, ...], str]] = {
    "hs_m": (("hs_m",), "scalar"),
    "wave_period_s": (("wave_period_s",), "scalar"),
    "tws_kn": (("wind_u_ms", "wind_v_ms"), "length"),
    "twd_deg": (("wind_u_ms", "wind_v_ms"), "angle"),
    "wave_dir_deg": (("_wave_sin", "_wave_cos"), "angle"),
}


def _variation(blocks: list[_Block], field: str) -> Variation | None:
    """:meth:`GriddedWeather.variation` computed from the blocks' data (see there)."""
    spec = _VARIATION_COLUMNS.get(field)
    if spec is None:
        return None
    names, kind = spec
    block = next((b for b in blocks if all(n in b.names for n in names)), None)
    if block is None:
        return None
    cols = [block.names.index(n) for n in names]
    steps = [float(np.min(np.diff(block.lon))), float(np.min(np.diff(block.lat)))]
    steps.append(float(np.min(np.diff(block.time_s))) / 3600.0 if block.time_s.size > 1 else np.inf)
    # largest neighbour statistic along each axis of the data (lat, lon, time): axes 1, 0, 2
    if kind == "angle":  # the angles' sum, axis by axis: no bound once it reaches 90 deg (the rest only add)
        spread = 0.0
        for axis in (1, 0, 2):
            spread += _neighbour_max(block.data, cols, axis, kind)
            if not spread < 90.0:
                return None
        return Variation(spread / steps[0], spread / steps[1], spread / steps[2], fixed=4.0 * spread)
    worst = [_neighbour_max(block.data, cols, axis, kind) for axis in (1, 0, 2)]
    scale = KN_PER_MS if kind == "length" else 1.0
    return Variation(*(scale * w / s for w, s in zip(worst, steps, strict=True)))


def _neighbour_max(data: npt.NDArray[np.float32], cols: list[int], axis: int, kind: str) -> float:
    """Largest difference (sum over the columns, or angle between the vectors [deg]) between neighbours along
    ``axis`` of ``data`` (lat, lon, time, column); NaN ignored. One compiled pass over the data (an angle: cut
    short at the first one over 90 deg, which is then returned instead of the largest)."""
    if data.shape[axis] < 2:
        return 0.0
    c0, c1 = cols[0], cols[-1]
    if kind == "angle":
        worst_cos = sampling.neighbour_min_cos(data, c0, c1, axis, 0.0)
        return float(np.degrees(np.arccos(min(1.0, max(-1.0, worst_cos)))))
    return float(sampling.neighbour_max_diff(data, c0, c1 if len(cols) > 1 else -1, axis))
