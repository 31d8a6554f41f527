"""Times: numpy ``datetime64`` in UTC throughout, ISO 8601 text in files and messages.

>>> str(hours_after(np.datetime64("2018-06-01T00:00"), np.array([1.5]))[0])
'2018-06-01T01:30:00.000'
>>> iso_utc(np.datetime64("2018-06-01T01:30:00.4"))
'2018-06-01T01:30:00Z'
"""

from __future__ import annotations

import datetime as _dt
from typing import Any

import numpy as np
import numpy.typing as npt

from pyroute_rel.errors import WeatherError, brief

__all__ = ["hours_after", "iso_utc", "iso_minute", "to_datetime64"]


def hours_after(departure: np.datetime64, time_h: npt.ArrayLike) -> npt.NDArray[np.datetime64]:
    """The instants ``time_h`` [h] after ``departure`` (to the millisecond; a non-finite time reads as 0 h)."""
    time_h = np.asarray(time_h, dtype=np.float64)
    ms = np.where(np.isfinite(time_h), time_h, 0.0) * 3.6e6
    return np.asarray(departure).astype("datetime64[ms]") + ms.astype("timedelta64[ms]")


def iso_utc(t: np.datetime64) -> str:
    """An instant as ISO 8601 UTC to the second, with a ``Z``."""
    return str(np.datetime_as_string(np.asarray(t).astype("datetime64[s]"), unit="s")) + "Z"


def iso_minute(t: np.datetime64) -> str:
    """An instant as ISO 8601 to the minute, for messages."""
    return str(np.datetime_as_string(t, unit="m"))


def to_datetime64(value: Any, what: str) -> np.datetime64:
    """A time (datetime64, datetime, ISO 8601 string with optional 'Z') -> datetime64[ns] (UTC)."""
    try:
        if isinstance(value, _dt.datetime) and value.tzinfo is not None:
            value = value.astimezone(_dt.UTC).replace(tzinfo=None)
        if isinstance(value, str):
            value = value.strip().removesuffix("Z").removesuffix("+00:00")
        out = np.datetime64(value, "ns")  # type: ignore[call-overload]
    except (TypeError, ValueError, OverflowError):
        raise WeatherError(
            f"{what}: expected a time (datetime64 or ISO 8601 string, UTC) (got {brief(value)})"
        ) from None
    if np.isnat(out):
        raise WeatherError(f"{what}: expected a time, got NaT")
    return out
