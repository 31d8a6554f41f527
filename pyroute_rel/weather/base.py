"""The weather interface: what the router asks of any weather source, and what it gets back.

A weather source answers one question, vectorised: *what are the wind and waves at these points and
times?* (:meth:`WeatherSource.sample`). The cost function, the solver and the route builder only ever call the
methods of :class:`WeatherSource`, so a uniform control field with patches (:mod:`pyroute_rel.weather.uniform`)
and gridded, time-varying reanalysis or forecast data (:mod:`pyroute_rel.weather.gridded`, read by
:mod:`pyroute_rel.weather.readers`) plug into the same solver.

Conventions
-----------
- Positions are longitude/latitude [deg], longitude in [-180, 180).
- Times are ``numpy.datetime64`` (UTC).
- Wind and wave directions are *from*, clockwise from true north [deg], in [0, 360).
- Currents are the velocity the water moves *to*: ``current_u_ms`` east, ``current_v_ms`` north [m/s].
- A value that is unknown at a point (land in an ocean model, outside a file) is NaN; the cost function
  forbids arcs through NaN weather rather than treating it as calm.
"""

from __future__ import annotations

from collections.abc import Collection
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np
import numpy.typing as npt

__all__ = ["Conditions", "WeatherSource", "FIELDS"]

FloatArray = npt.NDArray[np.float64]

#: Fields a control scenario (uniform value or patch) may set, with their units and valid range.
FIELDS: dict[str, tuple[str, float, float]] = {
    "tws_kn": ("true wind speed [kn]", 0.0, 200.0),
    "twd_deg": ("true wind direction, from [deg]", 0.0, 360.0),
    "hs_m": ("significant wave height [m]", 0.0, 30.0),
    "wave_dir_deg": ("mean wave direction, from [deg]", 0.0, 360.0),
    "wave_period_s": ("wave period [s]", 0.0, 40.0),
    "current_u_ms": ("eastward current, to [m/s]", -10.0, 10.0),
    "current_v_ms": ("northward current, to [m/s]", -10.0, 10.0),
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


@runtime_checkable
class WeatherSource(Protocol):
    """What the router asks of weather: every member the cost function, the solver and the route builder use.

    A new source (another file format, a model coupled at run time, a test double) implements these members and
    nothing else; :class:`~pyroute_rel.weather.uniform.UniformWeather` and
    :class:`~pyroute_rel.weather.gridded.GriddedWeather` are the two shipped implementations. The protocol is
    ``runtime_checkable``: ``isinstance(x, WeatherSource)`` checks that the members exist (not their types).

    Conventions of the methods: positions are longitude/latitude [deg] (any longitude convention), times
    ``numpy.datetime64`` (UTC), and every array argument is broadcast with the others.
    """

    @property
    def steady(self) -> bool:
        """True when the conditions do not change with time: the router then samples every arc once, at the
        departure time, and skips the timing pass (see :mod:`pyroute_rel.cost`). False makes the router sample each
        point at the time the craft gets there; it is always correct, only slower."""
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
