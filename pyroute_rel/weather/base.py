"""The weather interface: what the router asks of any weather source, and what it gets back.

A weather source answers one question, vectorised: *what are the wind and waves at these points and
times?* (:meth:`WeatherSource.sample`). The cost function, the solver and the route builder only ever call the
methods of :class:`WeatherSource`, so a uniform control field with patches (:mod:`pyroute_rel.weather.uniform`)
and gridded, time-varying reanalysis or forecast data (:mod:`pyroute_rel.weather.gridded`, read by
:mod:`pyroute_rel.weather.io.readers`) plug into the same solver.

Conventions
-----------
- Positions are longitude/latitude [deg], longitude in [-180, 180).
- Times are ``numpy.datetime64`` (UTC).
- Wind and wave directions are *from*, clockwise from true north [deg], in [0, 360).
- Currents are the velocity the water moves *to*: ``current_u_ms`` east, ``current_v_ms`` north [m/s].
- A value that is unknown at a point (land in an ocean model, outside a file) is NaN; the cost function
  forbids arcs through NaN weather rather than treating it as calm.
- Every quantity has a plausible range (:data:`RANGES`, with the reason for each bound); uniform and gridded
  weather refuse values outside it (gridded files may ask for them to be treated as missing instead).
"""

from __future__ import annotations

from collections.abc import Callable, Collection
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np
import numpy.typing as npt

from pyroute_rel.errors import WeatherError, check_numbers
from pyroute_rel.times import to_datetime64

__all__ = [
    "Boundaries",
    "Variation",
    "Conditions",
    "WeatherSource",
    "WeatherBase",
    "WEATHER_MEMBERS",
    "FIELDS",
    "RANGES",
    "Range",
    "sample_points",
]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class Range:
    """The physically plausible values of one weather quantity, and why.

    Attributes
    ----------
    label : What the quantity is, with its unit, e.g. ``"significant wave height [m]"``.
    lo, hi : Smallest and largest plausible value (closed interval), in the quantity's unit.
    why : Where the bounds come from (observed extremes they clear).
    """

    label: str
    lo: float
    hi: float
    why: str

    def describe(self) -> str:
        """``"[lo, hi] unit"``, e.g. ``"[0, 30] m"``: the range in messages."""
        unit = self.label[self.label.rfind("[") :] if "[" in self.label else ""
        return f"[{self.lo:g}, {self.hi:g}] {unit.strip('[]')}".strip()


_WIND = (
    "the strongest surface winds measured are below 100 m/s (Hurricane Patricia, 2015: 95 m/s sustained, "
    "Kimberlain et al. 2016, NHC Tropical Cyclone Report EP202015; gust record 113 m/s, Barrow Island 1996, WMO)"
)
_DIRECTION = (
    "a direction, from, clockwise from north; files write [0, 360) or [-180, 180), normalised to [0, 360) after "
    "the check"
)

#: Plausible range of every weather quantity, uniform or gridded: the one table both check against. A value
#: outside is refused (a gridded file may ask to treat it as missing instead: ``out_of_range = "missing"``).
#: These bounds also catch fill values a file does not declare (the netCDF default fill 9.97e36, 1e20, -9999).
RANGES: dict[str, Range] = {
    "tws_kn": Range("true wind speed [kn]", 0.0, 200.0, _WIND + "; 200 kn = 103 m/s"),
    "twd_deg": Range("true wind direction, from [deg]", -180.0, 360.0, _DIRECTION),
    "hs_m": Range(
        "significant wave height [m]",
        0.0,
        30.0,
        "the highest significant wave height measured is 19 m (buoy K5, North Atlantic, 4 February 2013, "
        "WMO Archive of Weather and Climate Extremes); hindcasts of the worst storms stay below 25 m",
    ),
    "wave_dir_deg": Range("mean wave direction, from [deg]", -180.0, 360.0, _DIRECTION),
    "wave_period_s": Range(
        "wave period [s]",
        0.0,
        40.0,
        "ocean swell periods stay below 30 s (WAVEWATCH III's and ERA5's wave spectra end near 0.035 Hz, about 29 s)",
    ),
    "current_u_ms": Range(
        "eastward current, to [m/s]",
        -10.0,
        10.0,
        "open-ocean currents stay below about 3 m/s (the Gulf Stream's core); only the fastest tidal races "
        "(Saltstraumen, Norway: about 10 m/s) reach this bound",
    ),
    "current_v_ms": Range("northward current, to [m/s]", -10.0, 10.0, "as current_u_ms"),
    "wind_u_ms": Range("eastward 10 m wind, to [m/s]", -100.0, 100.0, _WIND),
    "wind_v_ms": Range("northward 10 m wind, to [m/s]", -100.0, 100.0, _WIND),
}

#: Fields a control scenario (uniform value or patch) may set, with their units and valid range (from
#: :data:`RANGES`): the fields of :class:`Conditions`.
FIELDS: dict[str, tuple[str, float, float]] = {
    name: (RANGES[name].label, RANGES[name].lo, RANGES[name].hi)
    for name in ("tws_kn", "twd_deg", "hs_m", "wave_dir_deg", "wave_period_s", "current_u_ms", "current_v_ms")
}


@dataclass(frozen=True)
class Conditions:
    """Wind, waves and current at a set of points; every array has the shape of the query.

    Attributes
    ----------
    tws_kn : True wind speed [kn].
    twd_deg : True wind direction, from, clockwise from north [deg].
    hs_m : Significant wave height [m].
    wave_dir_deg : Mean wave direction, from, clockwise from north [deg].
    wave_period_s : Wave period [s]; NaN where the source has none.
    current_u_ms : Eastward current velocity (to) [m/s]; 0 where the source has none.
    current_v_ms : Northward current velocity (to) [m/s]; 0 where the source has none.
    """

    tws_kn: FloatArray
    twd_deg: FloatArray
    hs_m: FloatArray
    wave_dir_deg: FloatArray
    wave_period_s: FloatArray
    current_u_ms: FloatArray
    current_v_ms: FloatArray

    @property
    def has_current(self) -> bool:
        """True when any current is non-zero."""
        return bool(np.any(self.current_u_ms) or np.any(self.current_v_ms))


#: The :class:`Conditions` fields, in order.
_FIELD_NAMES = ("tws_kn", "twd_deg", "hs_m", "wave_dir_deg", "wave_period_s", "current_u_ms", "current_v_ms")


@dataclass(frozen=True)
class Variation:
    """A bound on how much a field changes between two points: ``|f(p) - f(q)| <= fixed + per_lon * |dlon| +
    per_lat * |dlat| + per_h * |dt|`` (longitude and latitude differences [deg], time [h]; a direction's change in
    [deg]). Gridded sources give it (:meth:`~pyroute_rel.weather.GriddedWeather.variation`)."""

    per_lon: float
    per_lat: float
    per_h: float
    fixed: float = 0.0


@dataclass(frozen=True)
class Boundaries:
    """Where a weather source's conditions can change abruptly or bend.

    Attributes
    ----------
    lon_deg : Meridians [deg], sorted.
    lat_deg : Parallels [deg], sorted.
    boxes : ``(n, 4)`` rows ``(lon_min, lon_max, lat_min, lat_max)`` [deg] outside which conditions do not change
        (None: anywhere).
    continuous : True when fields are continuous across the lines (interpolated grids), False when they jump there
        (patches).
    """

    lon_deg: FloatArray
    lat_deg: FloatArray
    boxes: FloatArray | None = None
    continuous: bool = True


@runtime_checkable
class WeatherSource(Protocol):
    """What the router asks of weather: every member the cost function, the solver and the route builder use.

    A new source (another file format, a model coupled at run time, a test double) implements ``steady``,
    ``fields``, ``max_current_ms``, ``time_steps``, ``sample`` and ``check_coverage``, and subclasses
    :class:`WeatherBase` for the rest: prepared sampling and the capabilities (what a source may offer beyond
    sampling: boundaries, variation bounds, ...), each declared here with its default there, so that the router
    asks for them by name and never probes. :class:`~pyroute_rel.weather.uniform.UniformWeather` and
    :class:`~pyroute_rel.weather.gridded.GriddedWeather` are the two shipped implementations. The protocol is
    ``runtime_checkable``: ``isinstance(x, WeatherSource)`` checks that the members exist (not their types); a
    :class:`~pyroute_rel.routing.solve.RoutingProblem` refuses a source that lacks some, naming them.

    Conventions of the methods: positions are longitude/latitude [deg] (any longitude convention), times
    ``numpy.datetime64`` (UTC), and every array argument is broadcast with the others.
    """

    @property
    def steady(self) -> bool:
        """True when the conditions do not change with time: the router then samples every arc once, at the
        departure time, and skips the timing pass (see :mod:`pyroute_rel.routing.cost`). False makes the router sample
        each point at the time the craft gets there; it is always correct, only slower."""
        ...

    @property
    def fields(self) -> frozenset[str]:
        """Names of the :class:`Conditions` fields the source defines (keys of :data:`FIELDS`); ``tws_kn`` and
        ``twd_deg`` always. A field not listed comes back NaN (waves) or 0 [m/s] (currents) from :meth:`sample`. The
        router refuses a failure model needing a field not listed, and takes the fast wind-only cost path when
        neither ``current_u_ms`` nor ``current_v_ms`` is listed."""
        ...

    @property
    def max_current_ms(self) -> float:
        """An upper bound on the current's speed anywhere, at any time [m/s] (0 without currents). The solver's
        pruning bound is the polar's top speed plus this; a bound too small would make pruning inexact."""
        ...

    @property
    def time_steps(self) -> npt.NDArray[np.datetime64] | None:
        """The times (``datetime64[ns]``, UTC, increasing) at which the source's conditions may change their rate in
        time: a file's time steps, between which every field is linear in time. The cost function cuts each arc's
        march where the craft crosses one (:mod:`pyroute_rel.routing.cost`), so that no step is timed across a change of
        the weather's trend. None: no such times (a steady source; or a source smooth in time, whose march steps are
        then bounded by :data:`~pyroute_rel.routing.cost.MAX_STEP_H` instead)."""
        ...

    def sample(
        self,
        lon_deg: npt.ArrayLike,
        lat_deg: npt.ArrayLike,
        time: npt.ArrayLike,
    ) -> Conditions:
        """Wind, waves and current at points and times.

        Parameters
        ----------
        lon_deg : Longitudes [deg].
        lat_deg : Latitudes [deg].
        time : Times (``datetime64``, UTC); ignored by a steady source.

        Returns
        -------
        Conditions
            Arrays of the broadcast shape of the three inputs; NaN where the source knows nothing.
        """
        ...

    def check_coverage(
        self,
        lon_range: tuple[float, float],
        lat_range: tuple[float, float],
        time_range: tuple[np.datetime64, np.datetime64],
    ) -> None:
        """Raise :class:`~pyroute_rel.errors.WeatherCoverageError` unless the source covers the request.

        Parameters
        ----------
        lon_range : (west, east) [deg]; east < west means the box crosses 180 deg.
        lat_range : (south, north) [deg].
        time_range : (first, last) time needed (``datetime64``, UTC).
        """
        ...

    def prepare(self, lon_deg: npt.ArrayLike, lat_deg: npt.ArrayLike) -> object:
        """Points made ready for :meth:`sample_at` at several times (e.g. located on the source's grids once).

        Parameters
        ----------
        lon_deg : Longitudes [deg].
        lat_deg : Latitudes [deg], broadcast with ``lon_deg``.

        Returns
        -------
        object
            An opaque handle that only this source's :meth:`sample_at` reads.
        """
        ...

    def sample_at(
        self,
        prepared: Any,
        departure: npt.ArrayLike,
        *,
        offset_h: npt.ArrayLike | None = None,
        fields: Collection[str] | None = None,
    ) -> Conditions:
        """:meth:`sample` at points made ready by :meth:`prepare`, giving the same numbers.

        Parameters
        ----------
        prepared : The handle :meth:`prepare` returned.
        departure : Times (``datetime64``, UTC) broadcast to the points' shape; with ``offset_h``, one origin.
        offset_h : Hours after ``departure`` [h], broadcast to the points' shape (NaN gives NaN conditions).
        fields : :class:`Conditions` fields wanted (default all); a source may leave the others NaN.

        Returns
        -------
        Conditions
            Arrays of the prepared points' shape.
        """
        ...

    # --- capabilities: what a source may offer beyond sampling (WeatherBase gives each its default) ---------------

    @property
    def boundaries(self) -> Boundaries | None:
        """Where conditions change abruptly or bend (grid lines, patch edges): arcs are judged on every piece
        between them (:mod:`pyroute_rel.reliability.crossings`). None: nowhere known; arcs are judged on their
        samples."""
        ...

    def variation(self, field: str) -> Variation | None:
        """A bound on how much a :class:`Conditions` field changes between two points (None: no bound known): lets
        the judge on pieces skip arcs that cannot reach a criterion's edge
        (:func:`pyroute_rel.reliability.crossings.needs_pieces`)."""
        ...

    @property
    def rows_aligned(self) -> bool:
        """True when the source answers each row (first axis) of a query from its own run or member (Monte Carlo's
        perturbed wind, ensemble members sailed side by side): a block of arcs is then never split between threads."""
        ...

    @property
    def nbytes(self) -> int:
        """Memory the source's data take [bytes] (0: little or unknown): ensembles stack members within a budget."""
        ...

    @property
    def take_rows(self) -> Callable[..., Any] | None:
        """``take_rows(rows)``: the same weather for queries made of rows ``rows`` (sorted) of the rows it answers (a
        :attr:`rows_aligned` source), or None: the source answers every row alike."""
        ...

    @property
    def reuse(self) -> Callable[..., Any] | None:
        """``reuse(prepared)``: points another source's :meth:`prepare` located, made ready for this source's
        :meth:`sample_at` without locating them again (None returned: they do not fit), or None: the source cannot."""
        ...

    @property
    def compiled_source(self) -> Callable[..., Any] | None:
        """``compiled_source()``: the gridded source the compiled march samples for this one (its prepared points
        index that source's data), or None: the compiled march samples the source itself when it can."""
        ...

    def wind_errors(self) -> tuple[Any, FloatArray | None, FloatArray | None]:
        """The source this one offsets the wind of, and the offsets east and north per row [kn] (None: no offset):
        how the compiled march samples a perturbed source (:class:`pyroute_rel.analysis.monte_carlo.PerturbedWind`). A
        source that offsets nothing returns itself and None, None."""
        ...


#: Every member of :class:`WeatherSource`, in the order documented there.
WEATHER_MEMBERS = (
    "steady", "fields", "max_current_ms", "time_steps", "sample", "check_coverage", "prepare", "sample_at",
    "boundaries", "variation", "rows_aligned", "nbytes", "take_rows", "reuse", "compiled_source", "wind_errors",
)  # fmt: skip


class WeatherBase:
    """The defaults of the :class:`WeatherSource` capabilities, for a source to inherit: no boundaries, no variation
    bound, rows answered alike, nothing reused, no compiled twin, no wind offset; :meth:`prepare` and
    :meth:`sample_at` by :meth:`sample` (the same numbers). A source implements ``steady``, ``fields``,
    ``max_current_ms``, ``time_steps``, ``sample`` and ``check_coverage`` and overrides what it can do better."""

    take_rows: Any = None
    reuse: Any = None
    compiled_source: Any = None

    @property
    def boundaries(self) -> Boundaries | None:
        """None: no boundaries known."""
        return None

    def variation(self, field: str) -> Variation | None:
        """None: no bound known."""
        return None

    @property
    def rows_aligned(self) -> bool:
        """False: every row is answered alike."""
        return False

    @property
    def nbytes(self) -> int:
        """0: little or unknown."""
        return 0

    def wind_errors(self) -> tuple[Any, FloatArray | None, FloatArray | None]:
        """This source, without offsets."""
        return self, None, None

    def prepare(self, lon_deg: npt.ArrayLike, lat_deg: npt.ArrayLike) -> object:
        """The points, broadcast together (:meth:`sample_at` samples them with :meth:`sample`)."""
        lon, lat = np.broadcast_arrays(np.asarray(lon_deg, dtype=float), np.asarray(lat_deg, dtype=float))
        return lon, lat

    def sample_at(
        self,
        prepared: Any,
        departure: npt.ArrayLike,
        *,
        offset_h: npt.ArrayLike | None = None,
        fields: Collection[str] | None = None,
    ) -> Conditions:
        """``sample`` at the prepared points, at ``departure`` (plus ``offset_h`` hours); every field."""
        lon, lat = prepared
        time = np.asarray(departure, dtype="datetime64[ns]")
        if offset_h is not None:
            ns = np.round(np.asarray(offset_h, dtype=float) * 3.6e12)
            time = time + np.where(np.isfinite(ns), ns, 0).astype("timedelta64[ns]")
            cond = self.sample(lon, lat, time)  # type: ignore[attr-defined]
            lost = ~np.isfinite(np.broadcast_to(np.asarray(offset_h, dtype=float), np.shape(cond.tws_kn)))
            if lost.any():  # NaN hours: NaN conditions
                nan = np.where(lost, np.nan, 0.0)
                cond = Conditions(**{k: np.asarray(getattr(cond, k), dtype=float) + nan for k in _FIELD_NAMES})
            return cond
        return self.sample(lon, lat, time)  # type: ignore[attr-defined, no-any-return]


def sample_points(
    lon_deg: npt.ArrayLike, lat_deg: npt.ArrayLike, time: npt.ArrayLike
) -> tuple[FloatArray, FloatArray, npt.NDArray[np.datetime64]]:
    """The arguments of :meth:`WeatherSource.sample` checked: longitudes and latitudes [deg] as float arrays (NaN
    is a missing point, an infinity or a non-number is a :class:`~pyroute_rel.errors.WeatherError`), times as
    ``datetime64[ns]`` (``datetime64`` values, ``datetime`` objects or ISO 8601 strings; numbers are refused, as
    their unit is unknown), broadcast together.
    """
    lon = check_numbers(lon_deg, "lon_deg", WeatherError, unit="deg")
    lat = check_numbers(lat_deg, "lat_deg", WeatherError, unit="deg")
    t = time if isinstance(time, np.ndarray) else np.asarray(time) if not isinstance(time, (dict, set)) else None
    if t is None or t.dtype.kind not in "MUSO":
        raise WeatherError(f"time must be datetime64 values or ISO 8601 strings, UTC (got {type(time).__name__})")
    if t.dtype.kind != "M":
        t = np.asarray(np.vectorize(lambda v: to_datetime64(v, "time"), otypes=["datetime64[ns]"])(t))
    t = t.astype("datetime64[ns]")
    try:
        shape = np.broadcast_shapes(lon.shape, lat.shape, t.shape)
    except ValueError:
        raise WeatherError(
            f"lon_deg, lat_deg and time must broadcast together (got shapes {lon.shape}, {lat.shape}, {t.shape})"
        ) from None
    return np.broadcast_to(lon, shape), np.broadcast_to(lat, shape), np.broadcast_to(t, shape)
