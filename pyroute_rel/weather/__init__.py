"""Weather: the :class:`WeatherSource` interface, uniform control weather, gridded fields and their file readers.

=====================  =======================================================================
module                 holds
=====================  =======================================================================
``weather.base``       :class:`Conditions`, the :class:`WeatherSource` protocol, physical ranges
``weather.uniform``    :class:`UniformWeather` and :class:`Patch` (the paper's control weather)
``weather.gridded``    :class:`GriddedWeather`: time-varying fields on lon/lat grids
``weather.io``         :func:`open_weather`: ERA5, GFS, WAVEWATCH III and CMEMS files (NetCDF, GRIB)
=====================  =======================================================================

The gridded sampler and the readers load numba and xarray; they are imported on first use.
"""

from __future__ import annotations

import importlib
from typing import Any

from pyroute_rel.weather.base import FIELDS, RANGES, Conditions, Range, WeatherBase, WeatherSource
from pyroute_rel.weather.uniform import Patch, UniformWeather

__all__ = [
    "FIELDS",
    "RANGES",
    "Range",
    "Conditions",
    "WeatherSource",
    "WeatherBase",
    "Patch",
    "UniformWeather",
    "GriddedWeather",
    "WeatherField",
    "open_weather",
]

_LAZY = {"GriddedWeather": ".gridded", "WeatherField": ".gridded", "open_weather": ".io.readers"}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name], __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
