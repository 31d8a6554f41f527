"""Uniform weather with rectangular patches: the paper's control scenario.

:class:`UniformWeather` is one value of each field everywhere, overridden inside :class:`Patch` boxes; it does
not vary in time. It implements :class:`~pyroute_rel.weather.base.WeatherSource`.

References
----------
Dickson, T., Blake, J. and Sear, D. (2018). Reliability informed routing for Autonomous Sailing Craft.
Proc. International Robotic Sailing Conference 2018, section 3.2 (control weather scenario).
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from pyroute_rel.errors import ScenarioError, WeatherError, brief
from pyroute_rel.weather.base import FIELDS, Boundaries, Conditions, WeatherBase, sample_points

__all__ = ["Patch", "PreparedUniform", "UniformWeather"]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class Patch:
    """A rectangular lon/lat box [deg] that overrides some fields of a control scenario.

    The box is closed: a point on its edge is inside. ``lon`` and ``lat`` are ``(min, max)``.
    ``values`` maps field names of :data:`FIELDS` to the value inside the box.
    """

    lon: tuple[float, float]
    lat: tuple[float, float]
    values: Mapping[str, float]
    name: str = ""

    def __post_init__(self) -> None:
        if not isinstance(self.name, str):
            raise ScenarioError(f"Patch.name must be a string (got {brief(self.name)})")
        where = f"Patch {self.name!r}" if self.name else "Patch"
        object.__setattr__(self, "lon", _range(self.lon, f"{where}.lon", -180.0, 180.0))
        object.__setattr__(self, "lat", _range(self.lat, f"{where}.lat", -90.0, 90.0))
        if not isinstance(self.values, Mapping) or not self.values:
            raise ScenarioError(
                f"{where}.values must be a non-empty mapping of field -> value (fields: "
                f"{', '.join(FIELDS)}) (got {brief(self.values)})"
            )
        bad = [k for k in self.values if k not in FIELDS]
        if bad:
            raise ScenarioError(f"{where}.values: unknown field {bad[0]!r} (expected one of {', '.join(FIELDS)})")
        object.__setattr__(self, "values", {k: _checked_value(k, v, f"{where}.values") for k, v in self.values.items()})
        if not isinstance(self.name, str):
            raise ScenarioError(f"{where}.name must be a string (got {brief(self.name)})")

    def contains(self, lon_deg: FloatArray, lat_deg: FloatArray) -> npt.NDArray[np.bool_]:
        """Boolean mask of the points inside the box."""
        return (lon_deg >= self.lon[0]) & (lon_deg <= self.lon[1]) & (lat_deg >= self.lat[0]) & (lat_deg <= self.lat[1])


@dataclass(frozen=True)
class PreparedUniform:
    """Points made ready by :meth:`UniformWeather.prepare`: longitudes and latitudes [deg] of one shape."""

    lon_deg: FloatArray
    lat_deg: FloatArray


@dataclass(frozen=True)
class UniformWeather(WeatherBase):
    """The paper's control scenario: uniform, steady wind and waves, overridden inside patches.

    Parameters
    ----------
    tws_kn : True wind speed [kn].
    twd_deg : True wind direction, from [deg].
    hs_m : Significant wave height [m].
    wave_dir_deg : Mean wave direction, from [deg].
    wave_period_s : Wave period [s] (NaN: unknown).
    current_u_ms, current_v_ms : Uniform current, to [m/s].
    patches : Rectangular overrides, applied in order (a later patch wins where two overlap).

    Examples
    --------
    >>> w = UniformWeather(tws_kn=15.0, twd_deg=0.0, hs_m=1.0, wave_dir_deg=0.0,
    ...                    patches=(Patch(lon=(-45.0, -35.0), lat=(28.0, 38.0), values={"hs_m": 4.0}),))
    >>> c = w.sample([-40.0, -20.0], [33.0, 33.0], np.datetime64("2018-06-01T00:00"))
    >>> c.hs_m.tolist(), c.tws_kn.tolist()
    ([4.0, 1.0], [15.0, 15.0])
    """

    tws_kn: float
    twd_deg: float
    hs_m: float = 0.0
    wave_dir_deg: float = 0.0
    wave_period_s: float = float("nan")
    current_u_ms: float = 0.0
    current_v_ms: float = 0.0
    patches: tuple[Patch, ...] = field(default_factory=tuple)

    def __post_init__(self) -> None:
        for name in FIELDS:
            value = getattr(self, name)
            if name == "wave_period_s" and isinstance(value, float) and math.isnan(value):
                continue  # unknown
            object.__setattr__(self, name, _checked_value(name, value, "UniformWeather"))
        patches = self.patches
        if (
            isinstance(patches, Patch)
            or not isinstance(patches, Sequence)
            or isinstance(patches, str)
            or not all(isinstance(p, Patch) for p in patches)
        ):
            raise ScenarioError(f"UniformWeather.patches must be a sequence of Patch (got {brief(patches)})")
        object.__setattr__(self, "patches", tuple(patches))

    @property
    def steady(self) -> bool:
        """True: a control field does not change with time."""
        return True

    @property
    def time_steps(self) -> None:
        """None: a control field does not change with time."""
        return None

    @property
    def fields(self) -> frozenset[str]:
        """Every field of :class:`~pyroute_rel.weather.base.Conditions` (all are defined everywhere)."""
        return frozenset(FIELDS)

    @property
    def boundaries(self) -> Boundaries | None:
        """Where conditions change: the patches' edges (meridians and parallels) within their boxes (None without
        patches). Used to judge arcs on every patch they cross (:mod:`pyroute_rel.reliability.crossings`)."""
        if not self.patches:
            return None
        lons = sorted({v for p in self.patches for v in p.lon})
        lats = sorted({v for p in self.patches for v in p.lat})
        boxes = np.array([[p.lon[0], p.lon[1], p.lat[0], p.lat[1]] for p in self.patches], dtype=float)
        return Boundaries(np.array(lons, float), np.array(lats, float), boxes, continuous=False)

    @property
    def max_current_ms(self) -> float:
        """The strongest current anywhere [m/s] (a bound on each component taken separately)."""
        cu = [abs(self.current_u_ms)] + [abs(p.values.get("current_u_ms", 0.0)) for p in self.patches]
        cv = [abs(self.current_v_ms)] + [abs(p.values.get("current_v_ms", 0.0)) for p in self.patches]
        return float(math.hypot(max(cu), max(cv)))

    def wind_boxes(self) -> tuple[float, float, FloatArray, FloatArray]:
        """The wind alone, for samplers in compiled code: what :meth:`sample` gives for ``tws_kn`` and ``twd_deg``
        is the first two values, overridden at a point by each of the boxes holding it (closed; in order) that sets
        them.

        Returns
        -------
        The speed [kn] and direction (from) [deg] outside the patches; the patches that set either, as rows
        ``(lon_min, lon_max, lat_min, lat_max)`` [deg], shape (n, 4), and their ``(tws_kn, twd_deg)``, shape (n, 2)
        (NaN: the patch leaves that one as it is).

        Examples
        --------
        >>> w = UniformWeather(tws_kn=15.0, twd_deg=0.0, patches=(
        ...     Patch(lon=(-45.0, -35.0), lat=(28.0, 38.0), values={"hs_m": 4.0}),
        ...     Patch(lon=(-43.0, -37.0), lat=(30.0, 36.0), values={"twd_deg": 240.0})))
        >>> tws, twd, boxes, values = w.wind_boxes()
        >>> tws, twd, boxes.tolist(), values.tolist()
        (15.0, 0.0, [[-43.0, -37.0, 30.0, 36.0]], [[nan, 240.0]])
        """
        wind = [p for p in self.patches if "tws_kn" in p.values or "twd_deg" in p.values]
        boxes = np.array([[*p.lon, *p.lat] for p in wind], dtype=float).reshape(-1, 4)
        values = np.array(
            [[p.values.get("tws_kn", np.nan), p.values.get("twd_deg", np.nan)] for p in wind], dtype=float
        ).reshape(-1, 2)
        return float(self.tws_kn), float(self.twd_deg), boxes, values

    def sample(self, lon_deg: npt.ArrayLike, lat_deg: npt.ArrayLike, time: npt.ArrayLike) -> Conditions:
        """Sample the control field at points; ``time`` is accepted for the protocol and ignored.

        Parameters
        ----------
        lon_deg : Longitudes [deg] in [-180, 180] (the patches' convention).
        lat_deg : Latitudes [deg].
        time : Times (``datetime64``, UTC); only their shape counts (broadcast with the points).
        """
        lon, lat, _ = sample_points(lon_deg, lat_deg, np.datetime64(0, "s"))  # time is ignored, but for its shape
        try:
            shape = np.broadcast_shapes(lon.shape, np.shape(time))
        except ValueError:
            raise WeatherError(
                f"time must broadcast with the points (got shapes {np.shape(time)}, {lon.shape})"
            ) from None
        lon = np.broadcast_to(lon, shape)
        lat = np.broadcast_to(lat, shape)
        out = {name: np.full(shape, float(getattr(self, name))) for name in FIELDS}
        for patch in self.patches:
            inside = patch.contains(lon, lat)
            if not inside.any():
                continue
            for name, value in patch.values.items():
                out[name][inside] = value
        return Conditions(**out)

    def prepare(self, lon_deg: npt.ArrayLike, lat_deg: npt.ArrayLike) -> PreparedUniform:
        """The points as float arrays of their broadcast shape, for :meth:`sample_at` (nothing to locate).

        Parameters
        ----------
        lon_deg : Longitudes [deg].
        lat_deg : Latitudes [deg], broadcast with ``lon_deg``.
        """
        lon, lat = np.broadcast_arrays(np.asarray(lon_deg, dtype=float), np.asarray(lat_deg, dtype=float))
        return PreparedUniform(lon_deg=lon, lat_deg=lat)

    def sample_at(
        self,
        prepared: PreparedUniform,
        departure: npt.ArrayLike,
        *,
        offset_h: npt.ArrayLike | None = None,
        fields: Collection[str] | None = None,
    ) -> Conditions:
        """:meth:`sample` at points from :meth:`prepare` (the same numbers: the field is steady).

        Parameters
        ----------
        prepared : From :meth:`prepare`.
        departure : Times (``datetime64``, UTC), or with ``offset_h`` one origin; ignored but for its shape.
        offset_h : Hours after ``departure`` [h]; ignored (steady), except that it is broadcast to the points.
        fields : Fields wanted; all are given (they cost nothing).
        """
        time = departure if offset_h is None else np.broadcast_to(np.asarray(departure), np.shape(offset_h))
        return self.sample(prepared.lon_deg, prepared.lat_deg, time)

    def check_coverage(
        self,
        lon_range: tuple[float, float],
        lat_range: tuple[float, float],
        time_range: tuple[np.datetime64, np.datetime64],
    ) -> None:
        """A control field covers everything."""
        return None

    @classmethod
    def from_mapping(cls, table: Mapping[str, Any], *, where: str = "[weather]") -> UniformWeather:
        """Build from a scenario's ``[weather]`` table (``kind = "uniform"``) with ``[[weather.patch]]``.

        Raises :class:`~pyroute_rel.errors.ScenarioError` naming the field on any bad value.
        """
        values: dict[str, float] = {}
        for key, value in table.items():
            if key in ("kind", "patch"):
                continue
            if key not in FIELDS:
                raise ScenarioError(
                    f"{where}: unknown key {key!r} (expected one of {', '.join(['kind', 'patch', *FIELDS])})"
                )
            values[key] = _checked_value(key, value, where)
        for required in ("tws_kn", "twd_deg"):
            if required not in values:
                raise ScenarioError(f"{where}: missing {required!r} ({FIELDS[required][0]})")
        raw_patches = table.get("patch", [])
        if not isinstance(raw_patches, Sequence) or isinstance(raw_patches, str):
            raise ScenarioError(f"{where}.patch must be an array of tables ([[weather.patch]])")
        patches = tuple(_parse_patch(p, f"{where}.patch[{i}]") for i, p in enumerate(raw_patches))
        return cls(**values, patches=patches)  # type: ignore[arg-type]


def _checked_value(key: str, value: Any, where: str) -> float:
    label, lo, hi = FIELDS[key]
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ScenarioError(f"{where}.{key} must be a number ({label}) (got {value!r})")
    try:
        v = float(value)
    except OverflowError:
        raise ScenarioError(f"{where}.{key} must be in [{lo:g}, {hi:g}] ({label}) (got {brief(value)})") from None
    if not np.isfinite(v) or not lo <= v <= hi:
        raise ScenarioError(f"{where}.{key} must be in [{lo:g}, {hi:g}] ({label}) (got {value!r})")
    if key.endswith("_deg"):
        v = v % 360.0
    return v


def _range(value: Any, where: str, lo: float, hi: float) -> tuple[float, float]:
    if (
        not isinstance(value, Sequence)
        or isinstance(value, str)
        or len(value) != 2
        or not all(isinstance(v, numbers.Real) and not isinstance(v, bool) for v in value)
    ):
        raise ScenarioError(f"{where} must be a pair [min, max] of numbers [deg] (got {value!r})")
    try:
        a, b = float(value[0]), float(value[1])
    except OverflowError:
        raise ScenarioError(f"{where} must satisfy {lo:g} <= min < max <= {hi:g} [deg] (got a huge number)") from None
    if not (lo <= a < b <= hi):
        raise ScenarioError(f"{where} must satisfy {lo:g} <= min < max <= {hi:g} [deg] (got {value!r})")
    return a, b


def _parse_patch(raw: Any, where: str) -> Patch:
    if not isinstance(raw, Mapping):
        raise ScenarioError(f"{where} must be a table with lon, lat and field values (got {raw!r})")
    values: dict[str, float] = {}
    name = ""
    for key, value in raw.items():
        if key in ("lon", "lat"):
            continue
        if key == "name":
            name = str(value)
            continue
        if key not in FIELDS:
            raise ScenarioError(f"{where}: unknown key {key!r} (expected lon, lat, name or one of {', '.join(FIELDS)})")
        values[key] = _checked_value(key, value, where)
    if "lon" not in raw or "lat" not in raw:
        raise ScenarioError(f"{where} needs both lon = [min, max] and lat = [min, max] [deg]")
    if not values:
        raise ScenarioError(f"{where} overrides no field (give at least one of {', '.join(FIELDS)})")
    return Patch(
        lon=_range(raw["lon"], f"{where}.lon", -180.0, 180.0),
        lat=_range(raw["lat"], f"{where}.lat", -90.0, 90.0),
        values=values,
        name=name,
    )
