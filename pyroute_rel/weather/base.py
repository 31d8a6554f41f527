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

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

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
    """What the router needs from weather: vectorised sampling in space and time.

    ``sample`` must broadcast ``lon_deg``, ``lat_deg`` and ``time`` together and return
    :class:`Conditions` with arrays of the broadcast shape. Sources that do not vary in time ignore
    ``time``. ``check_coverage`` raises :class:`~pyroute_rel.errors.WeatherCoverageError` when the
    box or time window is not covered (a no-op for sources that cover everything).
    """

    def sample(
        self,
        lon_deg: npt.ArrayLike,
        lat_deg: npt.ArrayLike,
        time: npt.ArrayLike,
    ) -> Conditions: ...

    def check_coverage(
        self,
        lon_range: tuple[float, float],
        lat_range: tuple[float, float],
        time_range: tuple[np.datetime64, np.datetime64],
    ) -> None: ...
