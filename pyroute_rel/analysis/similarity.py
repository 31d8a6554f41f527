"""How close two tracks are: cross-track distances of one from the other, and the difference of their arrivals.

The measure the DQN study of the Vendée Globe used against the skippers' GPS tracks (Mannocci & Bologna 2021), for
any two tracks: a planner's against the DP's, or a route against a sailed track. Track B is densified along its
great-circle legs (points at most ``step_km`` apart); each point's distance to track A is its great-circle
distance to the nearest point of A's legs (the cross-track distance where the foot of the perpendicular falls
within a leg, else the distance to the nearer end).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from pyroute_rel import geodesy
from pyroute_rel.errors import CoordinateError, TrackError, brief, check_numbers
from pyroute_rel.units import KM_PER_NM

__all__ = ["TrackSimilarity", "track_similarity", "distance_to_track_km"]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class TrackSimilarity:
    """Track B measured against track A.

    Attributes
    ----------
    mean_cross_track_nm : Mean distance of B's (densified) points from A [nm].
    max_cross_track_nm : Largest distance of B's points from A [nm].
    hausdorff_nm : The larger of B's largest distance from A and A's largest distance from B [nm].
    arrival_difference_h : B's arrival minus A's [h] (None unless both tracks have times).
    """

    mean_cross_track_nm: float
    max_cross_track_nm: float
    hausdorff_nm: float
    arrival_difference_h: float | None

    def as_dict(self) -> dict[str, Any]:
        """The figures by name (the JSON of ``pyroute-rel compare --json``)."""
        return asdict(self)


def _checked(lon: Any, lat: Any, name: str) -> tuple[FloatArray, FloatArray]:
    lo = check_numbers(lon, f"{name} lon", CoordinateError, infinite=True, unit="deg")
    la = check_numbers(lat, f"{name} lat", CoordinateError, infinite=True, unit="deg")
    if lo.ndim != 1 or lo.shape != la.shape or lo.size < 2:
        raise CoordinateError(f"{name} must have at least two points, as 1-D lon and lat arrays [deg] of one length")
    if not (np.isfinite(lo).all() and np.isfinite(la).all()) or np.any(np.abs(la) > 90.0):
        raise CoordinateError(f"{name} must have finite longitudes and latitudes in [-90, 90] [deg]")
    return lo, la


def distance_to_track_km(lon_deg: npt.ArrayLike, lat_deg: npt.ArrayLike, track_lon: Any, track_lat: Any) -> FloatArray:
    """Great-circle distance of points from a track of great-circle legs [km].

    >>> d = distance_to_track_km([5.0, 12.0], [1.0, 0.0], [0.0, 10.0], [0.0, 0.0])
    >>> [round(float(x), 3) for x in d]  # 1 deg north of the leg's middle; 2 deg east of its end
    [111.195, 222.39]
    """
    p_lon = np.asarray(lon_deg, dtype=float).ravel()[:, None]
    p_lat = np.asarray(lat_deg, dtype=float).ravel()[:, None]
    a_lon, a_lat = np.asarray(track_lon, dtype=float)[:-1], np.asarray(track_lat, dtype=float)[:-1]
    b_lon, b_lat = np.asarray(track_lon, dtype=float)[1:], np.asarray(track_lat, dtype=float)[1:]
    ends = np.minimum(geodesy.distance_km(p_lon, p_lat, a_lon, a_lat), geodesy.distance_km(p_lon, p_lat, b_lon, b_lat))
    along = geodesy.along_track_km(a_lon, a_lat, b_lon, b_lat, p_lon, p_lat)
    length = geodesy.distance_km(a_lon, a_lat, b_lon, b_lat)
    across = np.abs(geodesy.cross_track_km(a_lon, a_lat, b_lon, b_lat, p_lon, p_lat))
    within = (along >= 0.0) & (along <= length)
    return np.min(np.where(within, np.minimum(across, ends), ends), axis=1)


def _dense(lon: FloatArray, lat: FloatArray, step_km: float) -> tuple[FloatArray, FloatArray]:
    x, y, _ = geodesy.gc_densify(lon[:-1], lat[:-1], lon[1:], lat[1:], max_step_km=step_km)
    return geodesy.wrap_lon(x), y


def _arrival(value: Any, name: str) -> np.datetime64 | None:
    """An arrival time (UTC) as ``datetime64[s]``, or None; a number, a word or objects are a TrackError."""
    if value is None:
        return None
    if not isinstance(value, str | np.datetime64) or isinstance(value, np.ndarray):
        raise TrackError(
            f"{name} must be a UTC time (numpy datetime64 or ISO 8601 string) or None (got {brief(value)})"
        )
    try:
        t = np.datetime64(value, "s")  # type: ignore[call-overload]  # numpy's stubs have no datetime64(datetime64, unit) overload
    except (TypeError, ValueError, OverflowError):
        t = np.datetime64("NaT")
    if np.isnat(t):
        raise TrackError(
            f"{name} must be a UTC time (numpy datetime64 or ISO 8601 string) or None (got {brief(value)})"
        )
    return t


def track_similarity(
    lon_a: npt.ArrayLike,
    lat_a: npt.ArrayLike,
    lon_b: npt.ArrayLike,
    lat_b: npt.ArrayLike,
    *,
    arrival_a: np.datetime64 | None = None,
    arrival_b: np.datetime64 | None = None,
    step_km: float = 5.0,
) -> TrackSimilarity:
    """Track B measured against track A (see the module notes).

    Parameters
    ----------
    lon_a, lat_a, lon_b, lat_b : The tracks' points [deg].
    arrival_a, arrival_b : Their arrival times (UTC), for the arrival difference.
    step_km : Largest spacing of the points B (and A, for the Hausdorff distance) is densified to [km].

    Examples
    --------
    >>> s = track_similarity([0.0, 10.0], [0.0, 0.0], [0.0, 5.0, 10.0], [0.0, 1.0, 0.0])
    >>> round(s.max_cross_track_nm, 2), round(s.hausdorff_nm, 2), s.arrival_difference_h
    (60.04, 60.04, None)
    """
    la, pa = _checked(lon_a, lat_a, "track A")
    lb, pb = _checked(lon_b, lat_b, "track B")
    arrivals = [_arrival(t, name) for t, name in ((arrival_a, "arrival_a"), (arrival_b, "arrival_b"))]
    if isinstance(step_km, bool) or not (isinstance(step_km, int | float) and 0.01 <= step_km <= 1000.0):
        raise CoordinateError(f"step_km must be in [0.01, 1000] [km] (got {step_km!r})")
    xb, yb = _dense(lb, pb, step_km)
    xa, ya = _dense(la, pa, step_km)
    b_from_a = distance_to_track_km(xb, yb, la, pa) / KM_PER_NM
    a_from_b = distance_to_track_km(xa, ya, lb, pb) / KM_PER_NM
    diff = None
    if arrivals[0] is not None and arrivals[1] is not None:
        diff = float((arrivals[1] - arrivals[0]) / np.timedelta64(1, "s")) / 3600.0
    return TrackSimilarity(
        mean_cross_track_nm=float(b_from_a.mean()),
        max_cross_track_nm=float(b_from_a.max()),
        hausdorff_nm=float(max(b_from_a.max(), a_from_b.max())),
        arrival_difference_h=diff,
    )
