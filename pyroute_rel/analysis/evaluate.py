"""Evaluate any track: sail a given line (a GPX track, a GeoJSON line, a CSV of points) in a scenario's weather.

The track's points are joined by great-circle legs, sailed one after the other from the departure, each leg costed
exactly as the router costs an arc (:func:`~pyroute_rel.routing.cost.arc_costs` through the scenario's
:class:`~pyroute_rel.routing.solve.RoutingProblem`: the same weather samples per leg, the same polar, currents and wave
loss) and described as a routed track's legs are (:func:`~pyroute_rel.routing.route.track_legs`: conditions at each
leg's midpoint, failure probability, exposure). Re-timing a routed track therefore gives the route's own figures.

Unlike the router, the evaluation does not refuse a leg: it reports why a leg would have been forbidden.

- A leg whose conditions have ``p_f > apf`` somewhere (``"p_f"``), that touches land or the coastal margin
  (``"land"``) or an exclusion zone active when it is sailed (``"zone"``) is still sailed and timed; the track is
  not ``feasible``.
- A leg the craft cannot sail at all stops the voyage there (its time and every later time are ``inf``): the polar
  gives no speed (``"no_speed"``), the current makes the course impossible to hold (``"current"``), or the weather
  is missing, e.g. beyond the data's last time (``"weather"``).

``reason`` names the first leg's problem; :attr:`Evaluation.leg_reasons` lists each leg's.

Times in a track file are not imposed: the first one is the departure (unless given), and the craft sails each leg as
fast as the weather lets it. It waits only where the track says so: a track's waits (:attr:`Track.wait_h`: a routed
track's ``leg_wait_h`` in its CSV or GeoJSON, or a point repeated with a later time, as a GPS log or the route's GPX
records a stay) delay the leg they stand before, as the router's waits do. A leg of zero length is never sailed: the
files' repeated points are merged (their times giving the wait), and a :class:`Track` refuses one.
"""

from __future__ import annotations

import csv
import functools
import io
import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from dataclasses import fields as dataclass_fields
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

import numpy as np
import numpy.typing as npt

from pyroute_rel import geodesy
from pyroute_rel.boat.manoeuvre import TrackManoeuvres, charge_manoeuvres
from pyroute_rel.errors import ScenarioError, TrackError, brief, check_numbers, check_path
from pyroute_rel.files import brief_path, read_regular_bytes
from pyroute_rel.reliability.exposure import combined_failure_probability
from pyroute_rel.routing.cost import REASONS, ArcCosts, ArcGeometry, arc_geometry, geometry_costs
from pyroute_rel.routing.route import Legs, Route, track_legs
from pyroute_rel.routing.solve import first_sample_wind
from pyroute_rel.times import iso_utc
from pyroute_rel.weather.base import Conditions, WeatherBase

if TYPE_CHECKING:
    from pyroute_rel.obstacles.zones import Zone
    from pyroute_rel.reliability.crossings import ArcPieces
    from pyroute_rel.routing.grid import Grid
    from pyroute_rel.routing.solve import RoutingProblem
    from pyroute_rel.scenario import Scenario
    from pyroute_rel.weather import WeatherSource

__all__ = [
    "Track",
    "Evaluation",
    "Sailed",
    "read_track",
    "as_track",
    "evaluate_track",
    "evaluation_route",
    "evaluation_problem",
    "sail_tracks",
    "sail_in_members",
    "member_figures",
    "MemberFigures",
    "BLOCK_REASONS",
    "TRACK_MAX_BYTES",
]

FloatArray = npt.NDArray[np.float64]

#: Largest track file read [bytes]: 100 MB, a million GPX points.
TRACK_MAX_BYTES = 100_000_000

#: Why a leg is blocked, in the order a leg's first reason is named: what stops the craft, then what forbids it.
BLOCK_REASONS = ("no_speed", "current", "weather", "land", "zone", "p_f")

_STOPS = {"no_speed": REASONS["polar"], "current": REASONS["current"], "weather": REASONS["weather"]}
_LON_NAMES = ("lon", "lon_deg", "longitude", "long", "x")
_LAT_NAMES = ("lat", "lat_deg", "latitude", "y")
_TIME_NAMES = ("time", "time_utc", "timestamp", "datetime", "date")
_WAIT_NAMES = ("leg_wait_h", "wait_h")


@dataclass(frozen=True)
class Track:
    """A line to sail: points [deg] and, optionally, a time at each point and a wait before each leg.

    Attributes
    ----------
    lon_deg, lat_deg : Points [deg], at least two, no two consecutive ones the same place.
    time : UTC time at each point (``datetime64[s]``, never decreasing), or None.
    wait_h : Time the craft waits at each point but the last before sailing on [h] (finite, >= 0), or None: no wait.
    """

    lon_deg: FloatArray
    lat_deg: FloatArray
    time: npt.NDArray[np.datetime64] | None = None
    wait_h: FloatArray | None = None

    def __post_init__(self) -> None:
        lon = check_numbers(self.lon_deg, "Track.lon_deg", TrackError, infinite=True, unit="deg")
        lat = check_numbers(self.lat_deg, "Track.lat_deg", TrackError, infinite=True, unit="deg")
        if lon.ndim != 1 or lon.shape != lat.shape or lon.size < 2:
            raise TrackError(f"a track needs two or more points, as 1-D lon and lat arrays (got {lon.shape})")
        if not (np.isfinite(lon).all() and np.isfinite(lat).all()):
            raise TrackError("a track's coordinates must be finite numbers [deg]")
        if np.any(np.abs(lat) > 90.0) or np.any(np.abs(lon) > 360.0):
            i = int(np.flatnonzero((np.abs(lat) > 90.0) | (np.abs(lon) > 360.0))[0])
            raise TrackError(
                f"track point {i} is off the globe (lon {lon[i]:g}, lat {lat[i]:g}): expected lon, lat [deg]"
            )
        same = np.flatnonzero((lon[1:] == lon[:-1]) & (lat[1:] == lat[:-1]))
        if same.size:
            i = int(same[0])
            raise TrackError(
                f"track points {i} and {i + 1} are the same place (lon {lon[i]:g}, lat {lat[i]:g}): a leg of zero "
                "length; drop one (a track file's repeated point is read as a wait there)"
            )
        object.__setattr__(self, "lon_deg", lon)
        object.__setattr__(self, "lat_deg", lat)
        if self.time is not None:
            t = _track_times(self.time)
            if t.shape != lon.shape or np.isnat(t).any():
                raise TrackError(f"a track's times must be one UTC time per point ({lon.size}) (got {t.shape})")
            object.__setattr__(self, "time", _forward(t))
        if self.wait_h is not None:
            w = check_numbers(self.wait_h, "Track.wait_h", TrackError, missing=False, unit="h")
            if w.shape != (lon.size - 1,) or (w < 0.0).any():
                raise TrackError(
                    f"Track.wait_h must be one wait >= 0 per leg ({lon.size - 1}) [h] (got {brief(self.wait_h)})"
                )
            object.__setattr__(self, "wait_h", w)

    @property
    def waits_h(self) -> FloatArray:
        """The wait before each leg [h] (zeros when the track has none)."""
        return np.zeros(self.lon_deg.size - 1) if self.wait_h is None else self.wait_h

    @property
    def points(self) -> FloatArray:
        """The points as an (N, 2) array of lon, lat [deg]."""
        return np.column_stack([self.lon_deg, self.lat_deg])


def _forward(t: npt.NDArray[np.datetime64]) -> npt.NDArray[np.datetime64]:
    """A track's times, refused when they run backwards (the first point that does named)."""
    back = np.flatnonzero(t[1:] < t[:-1])
    if back.size:
        i = int(back[0])
        raise TrackError(
            f"a track's times must not run backwards: point {i + 1} ({t[i + 1]}Z) is before point {i} ({t[i]}Z)"
        )
    return t


def _track_times(value: Any) -> npt.NDArray[np.datetime64]:
    """A track's times as ``datetime64[s]``; anything that is not times (a word, objects, a huge number) is a
    TrackError."""
    try:
        return np.asarray(value).astype("datetime64[s]")
    except (TypeError, ValueError, OverflowError):
        raise TrackError(
            f"Track.time must be UTC times (numpy datetime64 or ISO 8601 strings), one per point (got {brief(value)})"
        ) from None


def as_track(track: Track | npt.ArrayLike) -> Track:
    """A :class:`Track` from a Track or an (N, 2) array of lon, lat [deg]."""
    if isinstance(track, Track):
        return track
    if not isinstance(track, np.ndarray | list | tuple):
        raise TrackError(f"a track must be a Track or an (N, 2) array of lon, lat [deg] (got {brief(track)})")
    arr = check_numbers(track, "track", TrackError, infinite=True, unit="deg")
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise TrackError(f"a track must be a Track or an (N, 2) array of lon, lat [deg] (got shape {arr.shape})")
    return Track(arr[:, 0], arr[:, 1])


# ------------------------------------------------------------------------------------------------ reading


def read_track(path: str | Path) -> Track:
    """Read a track: a GPX track or route, a GeoJSON LineString, or a CSV of lon, lat[, time].

    The format follows the file's suffix (``.gpx``; ``.geojson`` or ``.json``; ``.csv`` or ``.txt``), else its first
    character. A GPX file gives its first track (all segments, in order), else its first route; a GeoJSON file a
    LineString, a Feature holding one, or a FeatureCollection with exactly one line feature (other features, such as
    the points :func:`~pyroute_rel.outputs.to_geojson` writes, are ignored; a MultiLineString split at the
    antimeridian is joined again); a CSV file the columns named ``lon``/``lat``/``time`` (or ``lon_deg``,
    ``longitude``, ``time_utc``, ...) after a header, or lon, lat[, time] in that order without one.

    Raises
    ------
    TrackError
        One line naming the file and what is wrong (no line in it, a bad number or time).
    """
    p = Path(check_path(path, "track file", TrackError))
    label = brief_path(p)
    data = read_regular_bytes(p, limit_bytes=TRACK_MAX_BYTES, error=TrackError, label=label, what="track file")
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise TrackError(f"{label}: track file is not UTF-8 text (expected GPX, GeoJSON or CSV)") from None
    suffix = p.suffix.lower()
    head = text.lstrip()[:1]
    try:
        if suffix == ".gpx" or (suffix not in (".geojson", ".json", ".csv", ".txt") and head == "<"):
            return _gpx_track(text)
        if suffix in (".geojson", ".json") or (suffix not in (".csv", ".txt") and head in "{["):
            return _geojson_track(text)
        return _csv_track(text)
    except TrackError as exc:
        raise TrackError(f"{label}: {exc}") from None


def _read_points(
    lon: FloatArray, lat: FloatArray, times: npt.NDArray[np.datetime64] | None, waits: FloatArray | None
) -> Track:
    """A :class:`Track` of points read from a file: a point repeated at once (the same place, as a GPS log or the
    route's GPX records a stay) is one point, where the craft waits from its first time to its last (plus the waits
    the file gives there); ``waits`` (one per point, the last ignored) are the file's own."""
    lon, lat = np.asarray(lon, dtype=float), np.asarray(lat, dtype=float)
    w = np.zeros(lon.size) if waits is None else np.asarray(waits, dtype=float).copy()
    keep = np.ones(lon.size, dtype=bool)
    keep[1:] = (lon[1:] != lon[:-1]) | (lat[1:] != lat[:-1])
    if keep.all() or lon.size < 2:
        return Track(lon, lat, times, None if waits is None else w[:-1])
    if times is not None:
        t = _forward(np.asarray(times, dtype="datetime64[s]"))
        stay_h = (t[1:] - t[:-1]).astype(float) / 3600.0
        w[:-1] += np.where(keep[1:], 0.0, stay_h)  # the time spent at a point before its repeat
    n = int(keep.sum())
    if n < 2:
        raise TrackError("a track needs two or more distinct points (all its points are the same place)")
    group = np.cumsum(keep) - 1  # the point each one is merged into
    wait = np.bincount(group[:-1], weights=w[:-1], minlength=n)[: n - 1].astype(np.float64)
    kept_times = None if times is None else np.asarray(times, dtype="datetime64[s]")[keep]
    return Track(lon[keep], lat[keep], kept_times, None if waits is None and not wait.any() else wait)


def _gpx_track(text: str) -> Track:
    import gpxpy
    import gpxpy.gpx

    try:
        gpx = gpxpy.parse(text)
    except (gpxpy.gpx.GPXException, ValueError) as exc:
        raise TrackError(f"not a readable GPX file ({' '.join(str(exc).split())[:200]})") from None
    points: list[Any] = []
    if gpx.tracks:
        points = [pt for seg in gpx.tracks[0].segments for pt in seg.points]
    if not points and gpx.routes:
        points = list(gpx.routes[0].points)
    if len(points) < 2:
        raise TrackError("GPX file has no track or route of two or more points")
    times = None
    if all(pt.time is not None for pt in points):
        times = np.array([_utc64(pt.time) for pt in points], dtype="datetime64[s]")
    return _read_points(
        np.array([pt.longitude for pt in points], dtype=float),
        np.array([pt.latitude for pt in points], dtype=float),
        times,
        None,
    )


def _utc64(t: Any) -> np.datetime64:
    if t.tzinfo is not None:
        import datetime as dt

        t = t.astimezone(dt.UTC).replace(tzinfo=None)
    return np.datetime64(t, "s")


def _geojson_track(text: str) -> Track:
    try:
        doc = json.loads(text)
    except (ValueError, RecursionError) as exc:  # (ValueError: JSON syntax, or a number of 4300+ digits)
        raise TrackError(f"not valid JSON ({exc})") from None
    lines = _lines(doc)
    if len(lines) != 1:
        raise TrackError(
            f"GeoJSON must hold one LineString (or a Feature or FeatureCollection with one) (found {len(lines)})"
        )
    geometry, props = lines[0]
    coords: Any = geometry.get("coordinates")  # (any JSON: checked as it is read)
    if geometry.get("type") == "MultiLineString":
        coords = _join_parts(coords)
    try:
        arr = np.array([[float(c[0]), float(c[1])] for c in coords], dtype=float)
    except (TypeError, ValueError, IndexError):
        raise TrackError("GeoJSON line coordinates must be [lon, lat] pairs of numbers") from None
    times = props.get("times") or props.get("coordTimes") if isinstance(props, dict) else None
    t = None
    if isinstance(times, list) and len(times) == len(arr):
        t = np.array([_parse_time(v, f"time {i}") for i, v in enumerate(times)], dtype="datetime64[s]")
    at_points, waits = _point_times(doc, len(arr))
    if t is None:
        t = at_points
    return _read_points(arr[:, 0], arr[:, 1], t, waits) if len(arr) >= 2 else Track(arr[:, 0], arr[:, 1])


def _point_times(doc: Any, n: int) -> tuple[npt.NDArray[np.datetime64] | None, FloatArray | None]:
    """The times and waits [h] of a route's GeoJSON (:func:`~pyroute_rel.outputs.to_geojson`): its Point features
    numbered ``index`` 0 to ``n - 1``, each with a ``time`` and (but the last) a ``leg_wait_h``; (None, None) when the
    file has not one such point per track point."""
    if not isinstance(doc, dict) or doc.get("type") != "FeatureCollection" or not isinstance(doc.get("features"), list):
        return None, None
    found: dict[int, dict[str, Any]] = {}
    for f in doc["features"]:
        geom = f.get("geometry") if isinstance(f, dict) else None
        props = f.get("properties") if isinstance(f, dict) else None
        if isinstance(geom, dict) and geom.get("type") == "Point" and isinstance(props, dict):
            i = props.get("index")
            if isinstance(i, int) and not isinstance(i, bool) and 0 <= i < n and "time" in props:
                found[i] = props
    if len(found) != n:
        return None, None
    times = np.array([_parse_time(found[i]["time"], f"point {i}'s time") for i in range(n)], dtype="datetime64[s]")
    waits = np.zeros(n)
    for i in range(n - 1):
        w = found[i].get("leg_wait_h", 0.0)
        if w is not None:
            try:
                value = math.nan if isinstance(w, bool) or not isinstance(w, int | float) else float(w)
            except OverflowError:  # (a whole number beyond the floats)
                value = math.inf
            waits[i] = _wait_h(value, w, f"point {i}'s leg_wait_h")
    return times, waits


def _wait_h(value: float, given: Any, where: str) -> float:
    """A wait read from a file [h]: a finite number >= 0, else a TrackError naming ``where`` and quoting ``given``."""
    if not (math.isfinite(value) and value >= 0.0):
        raise TrackError(f"{where}: expected the wait before the leg as a number of hours >= 0 (got {brief(given)})")
    return value


def _lines(doc: Any) -> list[tuple[dict[str, Any], Any]]:
    """(geometry, properties) of every LineString or MultiLineString in a GeoJSON object."""
    if not isinstance(doc, dict):
        return []
    kind = doc.get("type")
    if kind in ("LineString", "MultiLineString"):
        return [(doc, {})]
    if kind == "Feature" and isinstance(doc.get("geometry"), dict):
        return [(g, doc.get("properties") or {}) for g, _ in _lines(doc["geometry"])]
    if kind == "FeatureCollection" and isinstance(doc.get("features"), list):
        return [item for f in doc["features"] for item in _lines(f)]
    return []


def _join_parts(parts: Any) -> list[Any]:
    """The parts of a MultiLineString joined: where one part ends on +-180 and the next starts on the other side at
    the same latitude (a track split at the antimeridian), both crossing points are dropped."""
    if not isinstance(parts, list) or not parts:
        raise TrackError("GeoJSON MultiLineString coordinates must be a list of lines")
    out = list(parts[0])
    for part in parts[1:]:
        part = list(part)
        try:
            crossing = abs(float(out[-1][0])) == 180.0 and float(part[0][0]) == -float(out[-1][0])
            crossing = crossing and float(part[0][1]) == float(out[-1][1])
        except (TypeError, ValueError, IndexError):
            raise TrackError("GeoJSON line coordinates must be [lon, lat] pairs of numbers") from None
        out = out[:-1] + part[1:] if crossing else out + part
    return out


def _parse_time(value: Any, where: str) -> np.datetime64:
    try:
        text = str(value).strip().removesuffix("Z").removesuffix("+00:00")
        t = np.datetime64(text, "s")
    except ValueError:
        raise TrackError(f"{where}: expected an ISO 8601 UTC time (got {brief(value)})") from None
    if np.isnat(t):
        raise TrackError(f"{where}: expected an ISO 8601 UTC time (got {brief(value)})")
    return t


def _csv_track(text: str) -> Track:
    rows = [r for r in csv.reader(io.StringIO(text)) if r and any(c.strip() for c in r) and not r[0].startswith("#")]
    if not rows:
        raise TrackError("CSV file has no rows (expected lon, lat[, time] per line)")
    header = [c.strip().lower() for c in rows[0]]
    first_line = 1
    if any(_is_word(c) for c in header[:2]):  # a header names the columns; data start with two numbers
        cols = [_column(header, names) for names in (_LON_NAMES, _LAT_NAMES, _TIME_NAMES, _WAIT_NAMES)]
        if cols[0] is None or cols[1] is None:
            raise TrackError(f"CSV header needs lon and lat columns (got {', '.join(header)})")
        rows, first_line = rows[1:], 2
    else:
        cols = [0, 1, 2 if len(header) > 2 else None, None]
    lon, lat, times, waits = [], [], [], []
    for n, row in enumerate(rows, start=first_line):
        try:
            lon.append(float(row[cols[0]]))  # type: ignore[index]
            lat.append(float(row[cols[1]]))  # type: ignore[index]
        except (ValueError, IndexError):
            raise TrackError(f"CSV row {n}: expected numbers for lon and lat (got {brief(row)})") from None
        if cols[2] is not None:
            times.append(_parse_time(row[cols[2]] if cols[2] < len(row) else "", f"CSV row {n}"))
        if cols[3] is not None:
            waits.append(_wait_cell(row[cols[3]].strip() if cols[3] < len(row) else "", f"CSV row {n}"))
    if len(lon) < 2:
        raise TrackError(f"CSV file has {len(lon)} point(s) (a track needs two or more)")
    return _read_points(
        np.array(lon),
        np.array(lat),
        np.array(times, dtype="datetime64[s]") if times else None,
        np.array(waits) if waits else None,
    )


def _wait_cell(cell: str, where: str) -> float:
    """A CSV's wait before the leg [h]: empty (the last point's) is none."""
    if not cell:
        return 0.0
    try:
        w = float(cell)
    except ValueError:
        w = math.nan
    return _wait_h(w, cell, where)


def _is_word(cell: str) -> bool:
    try:
        float(cell)
    except ValueError:
        return bool(cell)
    return False


def _column(header: Sequence[str], names: Sequence[str]) -> int | None:
    return next((i for i, c in enumerate(header) if c in names), None)


# ------------------------------------------------------------------------------------------------ sailing


@dataclass(frozen=True)
class Sailed:
    """A track sailed leg after leg (:func:`sail_tracks`): the raw figures, before the legs are described.

    Attributes
    ----------
    lon_deg, lat_deg : The track's points [deg].
    elapsed_h : Time at each point [h after the departure]; ``inf`` from the first leg the craft cannot sail.
    costs : Each leg's :class:`~pyroute_rel.routing.cost.ArcCosts` (``time_h`` ``inf`` where it cannot be sailed,
        ``p_f`` and ``reason`` NaN and 0 after it).
    land, zone : Which legs touch land (or the coastal margin) and an exclusion zone active when they are sailed.
    apf : The acceptable probability of failure the legs' ``p_f`` is held to.
    wait_h : The wait before each leg [h] (the track's, :attr:`Track.wait_h`; zeros without).
    manoeuvres : The side of each leg and the tack or gybe at its start, with the time it cost
        (:class:`~pyroute_rel.boat.manoeuvre.TrackManoeuvres`; penalties zero unless the boat has them; after a leg that
        cannot be sailed: no manoeuvre).
    """

    lon_deg: FloatArray
    lat_deg: FloatArray
    elapsed_h: FloatArray
    costs: ArcCosts
    land: npt.NDArray[np.bool_]
    zone: npt.NDArray[np.bool_]
    apf: float
    manoeuvres: TrackManoeuvres | None = None
    wait_h: FloatArray | None = None

    @property
    def voyage_time_h(self) -> float:
        """Time to the last point [h] (``inf`` when a leg cannot be sailed)."""
        return float(self.elapsed_h[-1])

    @property
    def max_p_f(self) -> float:
        """Largest leg ``p_f`` of the legs sailed (0 when none has one)."""
        p = self.costs.p_f[np.isfinite(self.costs.p_f)]
        return float(p.max()) if p.size else 0.0

    def leg_reasons(self) -> list[tuple[str, ...]]:
        """Why each leg is blocked, names of :data:`BLOCK_REASONS` (empty where it is not)."""
        out = []
        with np.errstate(invalid="ignore"):
            over = self.costs.p_f > self.apf
        for i in range(self.costs.time_h.size):
            r = int(self.costs.reason[i])
            names = [n for n, bit in _STOPS.items() if r & bit]
            if self.land[i]:
                names.append("land")
            if self.zone[i]:
                names.append("zone")
            if over[i]:
                names.append("p_f")
            out.append(tuple(n for n in BLOCK_REASONS if n in names))
        return out

    @property
    def feasible(self) -> bool:
        """True when no leg is blocked."""
        return math.isfinite(self.voyage_time_h) and not any(self.leg_reasons())


def evaluation_problem(
    scenario: Scenario,
    *,
    departure: Any = None,
    apf: float | None = None,
    samples: int | None = None,
    weather: WeatherSource | None = None,
) -> RoutingProblem:
    """The routing problem a track is sailed in: the scenario's (on its grid: the same weather samples per leg as its
    route), without obstacle mask (legs are tested against land and zones one by one).

    Parameters
    ----------
    scenario : The scenario.
    departure : Departure time (UTC; default the scenario's).
    apf : Acceptable probability of failure (default the scenario's).
    samples : Weather samples per leg (default: as the scenario's route samples its arcs).
    weather : Weather source (default the scenario's).
    """
    problem = scenario.problem(blocked=None)
    changes: dict[str, Any] = {}
    if departure is not None:
        from pyroute_rel.scenario import parse_departure

        if isinstance(departure, np.datetime64):
            changes["departure"] = np.datetime64(departure, "s")  # type: ignore[call-overload]  # numpy's stubs have no datetime64(datetime64, unit) overload
        else:
            changes["departure"] = parse_departure(departure)
    if apf is not None:
        changes["apf"] = apf
    if samples is not None:
        changes["samples"] = samples
    if weather is not None:
        changes["weather"] = weather
    return replace(problem, **changes) if changes else problem


def sail_tracks(
    problem: RoutingProblem,
    tracks: Sequence[Track | npt.ArrayLike],
    *,
    avoid: Any = None,
    manoeuvres: bool | None = None,
) -> list[Sailed]:
    """Sail tracks leg after leg in a problem's weather, vectorised over the tracks (the k-th legs of every track
    are costed together).

    Each leg is costed as :func:`~pyroute_rel.routing.solve.leg_costs` costs a route's legs (the same arithmetic, the
    same departure times), with ``apf = 1`` so that no leg is refused for its ``p_f``; a leg the craft cannot sail stops
    its track.

    Parameters
    ----------
    problem : Weather, polar, failure model, samples per leg, departure; its ``apf`` is the bound reported against.
    tracks : Tracks (:class:`Track` or (N, 2) arrays of lon, lat [deg]).
    avoid : Land and zones to test the legs against (:class:`~pyroute_rel.obstacles.mask.Avoid`), or None.
    manoeuvres : Find the side of the wind of each leg and the tacks and gybes (:attr:`Sailed.manoeuvres`); None
        (default): only when the problem's boat has manoeuvre penalties, which then delay each leg's arrival as
        :func:`~pyroute_rel.routing.solve.leg_manoeuvres` delays a route's.

    Returns
    -------
    list of Sailed
        One per track, in order.
    """
    return sail_in_members([problem], tracks, avoid=avoid, manoeuvres=manoeuvres)[0]


def sail_in_members(
    problems: Sequence[RoutingProblem],
    tracks: Sequence[Track | npt.ArrayLike],
    *,
    avoid: Any = None,
    manoeuvres: bool | None = None,
) -> list[list[Sailed]]:
    """Sail every track in every problem's weather (e.g. every ensemble member's): ``out[j][i]`` is
    ``sail_tracks(problems[j], [tracks[i]])[0]``, the same numbers, computed together.

    The problems must differ in their weather only (the first's polar, failure model, samples, departure and apf are
    used). The k-th legs of every track in every weather are costed in one call (the weather answers each row from
    its own source); then each weather's legs are judged on every piece they cross
    (:func:`~pyroute_rel.reliability.crossings.arc_extremes`) in one call, all legs at once: the times do not depend on
    it (``apf = 1`` refuses no leg), only the legs' ``p_f``. Each leg's geometry, and its pieces, are computed once for
    every weather. ``manoeuvres``: as in :func:`sail_tracks`.
    """
    return [row for g in _member_groups(problems) for row in _sail_rows(g, tracks, avoid, manoeuvres).sailed()]


@dataclass(frozen=True)
class MemberFigures:
    """The figures of every track sailed in every weather (:func:`member_figures`), shape (tracks, weathers).

    Attributes
    ----------
    voyage_time_h : :attr:`Sailed.voyage_time_h` [h] (``inf`` where a leg cannot be sailed).
    max_p_f : :attr:`Sailed.max_p_f` [-].
    over_apf : Whether a leg sailed has ``p_f > apf`` (``"p_f"`` among its :meth:`Sailed.leg_reasons`).
    blocked : Whether the track is blocked otherwise: a leg cannot be sailed, or one touches land or an active zone.
    on_land : Whether a leg sailed touches land (or the coastal margin).
    """

    voyage_time_h: FloatArray
    max_p_f: FloatArray
    over_apf: npt.NDArray[np.bool_]
    blocked: npt.NDArray[np.bool_]
    on_land: npt.NDArray[np.bool_]

    @property
    def feasible(self) -> npt.NDArray[np.bool_]:
        """:attr:`Sailed.feasible` of each track in each weather."""
        return ~self.blocked & ~self.over_apf


def member_figures(
    problems: Sequence[RoutingProblem], tracks: Sequence[Track | npt.ArrayLike], *, avoid: Any = None
) -> MemberFigures:
    """The figures of :func:`sail_in_members` (``[[s for s in row] for row in sail_in_members(...)]``, transposed to
    (tracks, weathers)) without building a :class:`Sailed` per track and weather: the same numbers, as arrays."""
    parts = [_sail_rows(g, tracks, avoid, False).figures() for g in _member_groups(problems)]
    return MemberFigures(
        *(np.concatenate([getattr(p, f.name) for p in parts], axis=1) for f in dataclass_fields(MemberFigures))
    )


@dataclass(frozen=True)
class _Sailing:
    """Tracks sailed in weathers, one row per (weather ``j``, track ``i``): row ``j * len(tracks) + i``; arrays of
    (rows, legs) (``elapsed``: (rows, legs + 1)), NaN-padded after each track's last leg."""

    tracks: list[Track]
    problems: Sequence[RoutingProblem]
    n_legs: npt.NDArray[np.intp]
    elapsed: FloatArray
    time_h: FloatArray
    p_f: FloatArray
    reason: npt.NDArray[np.uint8]
    land: npt.NDArray[np.bool_]
    zone: npt.NDArray[np.bool_]
    man: _Manoeuvres | None
    #: Time-varying weather: when each leg's sub-segment ends are reached, (rows, legs, samples + 1); else None.
    marks: FloatArray | None = None
    #: The wait before each leg [h], (rows, legs).
    wait: FloatArray | None = None

    def sailed(self) -> list[list[Sailed]]:
        """Each row's :class:`Sailed`, ``out[j][i]``."""
        out: list[list[Sailed]] = []
        n_c, man = len(self.tracks), self.man
        for j, problem in enumerate(self.problems):
            out.append([])
            for i, t in enumerate(self.tracks):
                r, n = j * n_c + i, int(self.n_legs[i])
                sailed = _sailed(t, self.elapsed[r, : n + 1], self.time_h[r, :n], self.p_f[r, :n], self.reason[r, :n],
                                 self.land[r, :n], self.zone[r, :n], float(problem.apf),
                                 None if self.marks is None else self.marks[r, :n],
                                 None if self.wait is None else self.wait[r, :n])  # fmt: skip
                out[j].append(sailed if man is None else replace(sailed, manoeuvres=man.track(r, n, sailed.elapsed_h)))
        return out

    def figures(self) -> MemberFigures:
        """Each row's figures as :func:`sailed` gives them (a leg after one that cannot be sailed is not sailed)."""
        n_m, n_c = len(self.problems), len(self.tracks)
        n = np.tile(self.n_legs, n_m)
        rows = np.arange(n.size)
        point = np.arange(self.elapsed.shape[1])[None, :]
        bad = (point <= n[:, None]) & ~np.isfinite(self.elapsed)
        stop = np.where(bad.any(axis=1), np.argmax(bad, axis=1), n + 1)  # the first point not reached
        time = np.where(stop <= n, np.inf, self.elapsed[rows, n])
        sailed = (point[:, :-1] < stop[:, None]) & (point[:, :-1] < n[:, None])
        apf = np.repeat([float(p.apf) for p in self.problems], n_c)
        # (casts: any() along axis 1 of a 2-D array is an array, where numpy's stubs allow a scalar)
        with np.errstate(invalid="ignore"):
            over = cast("npt.NDArray[np.bool_]", (sailed & (self.p_f > apf[:, None])).any(axis=1))
        known = sailed & np.isfinite(self.p_f)
        top = np.where(known.any(axis=1), np.max(np.where(known, self.p_f, -np.inf), axis=1, initial=-np.inf), 0.0)
        land = cast("npt.NDArray[np.bool_]", (sailed & self.land).any(axis=1))
        stops = np.uint8(_STOPS["no_speed"] | _STOPS["current"] | _STOPS["weather"])
        blocked = ~np.isfinite(time) | (sailed & ((self.reason & stops) != 0)).any(axis=1)
        blocked |= land | (sailed & self.zone).any(axis=1)
        shape = (n_m, n_c)  # each figure per (weather, track), then transposed
        return MemberFigures(
            time.reshape(shape).T,
            top.reshape(shape).T,
            over.reshape(shape).T,
            blocked.reshape(shape).T,
            land.reshape(shape).T,
        )


def _sail_rows(
    problems: Sequence[RoutingProblem],
    tracks: Sequence[Track | npt.ArrayLike],
    avoid: Any,
    manoeuvres: bool | None,
) -> _Sailing:
    """:func:`sail_in_members` of one group of weathers, as rows."""
    tr = [as_track(t) for t in tracks]
    n_m, n_c = len(problems), len(tr)
    first = problems[0]
    n_legs = np.array([t.lon_deg.size - 1 for t in tr])
    width = int(n_legs.max()) if n_c else 0
    lon1, lat1 = np.full((n_c, width + 1), np.nan), np.full((n_c, width + 1), np.nan)
    for i, t in enumerate(tr):
        lon1[i, : t.lon_deg.size], lat1[i, : t.lat_deg.size] = t.lon_deg, t.lat_deg
    has1 = np.arange(width)[None, :] < n_legs[:, None]
    wait1 = np.zeros((n_c, width))
    for i, t in enumerate(tr):
        wait1[i, : t.lon_deg.size - 1] = t.waits_h
    # rows: track i in weather j is row j * n_c + i
    lon, lat, has = np.tile(lon1, (n_m, 1)), np.tile(lat1, (n_m, 1)), np.tile(has1, (n_m, 1))
    wait = np.tile(wait1, (n_m, 1))
    legs = np.tile(n_legs, n_m)
    elapsed = np.where(np.arange(width + 1)[None, :] <= legs[:, None], 0.0, np.nan)
    time_h, p_f = np.full(has.shape, np.nan), np.full(has.shape, np.nan)
    reason = np.zeros(has.shape, dtype=np.uint8)
    marks = None
    man = _Manoeuvres.of(first, has.shape, manoeuvres)
    if first.weather.steady and first.time_step_h is None:
        for j, problem in enumerate(problems):  # every leg at once, judged on its pieces in the same call
            rows = slice(j * n_c, (j + 1) * n_c)
            a, b, c_, d = lon1[:, :-1][has1], lat1[:, :-1][has1], lon1[:, 1:][has1], lat1[:, 1:][has1]
            c = replace(problem, apf=1.0, blocked=None).costs(a, b, c_, d, np.zeros(int(has1.sum())))
            fill = [(time_h, c.time_h), (p_f, c.p_f), (reason, c.reason)]
            if man is not None:  # the wind at each leg's first sample (steady: any time)
                g = arc_geometry(a, b, c_, d, samples=first.samples)
                fill += zip((man.side, man.twa, man.tws), first_sample_wind(problem, g, np.zeros(a.size)), strict=True)
            for arr, v in fill:
                block = arr[rows]
                block[has1] = v
                arr[rows] = block
        if man is None or man.penalties is None:
            elapsed[:, 1:] = np.where(has, np.cumsum(np.where(has, wait + time_h, 0.0), axis=1), np.nan)
        if man is not None:
            man.charge_tracks(has, time_h, elapsed, wait)
    else:
        legs1 = _Legs.of(lon1, lat1, has1, first.samples)
        make_stack = _member_stack(problems)
        stack = None if make_stack is None else make_stack(box=legs1.box())
        marks = np.full(has.shape + (first.samples + 1,), np.nan)
        _sail_legs(problems, legs1, stack, has, elapsed, time_h, p_f, reason, man, marks, wait)
        _judge_legs(problems, legs1, stack, elapsed[:, :-1] + wait, time_h, p_f, marks)
    land1 = None
    if avoid is not None and avoid.land:  # the same in every weather
        land1, _ = _obstacles(first, replace(avoid, zones=()), lon1, lat1, elapsed[:n_c, :-1], has1)
    zone = np.zeros(has.shape, dtype=bool)
    if avoid is not None and avoid.zones:
        _, zone = _obstacles(first, replace(avoid, land=False), lon, lat, elapsed[:, :-1] + wait, has)
    land = np.zeros(has.shape, dtype=bool) if land1 is None else np.tile(land1, (n_m, 1))
    return _Sailing(tr, problems, n_legs, elapsed, time_h, p_f, reason, land, zone, man, marks, wait)


@dataclass
class _Manoeuvres:
    """The side of the wind, true wind angle [deg] and wind speed [kn] at the first sample of every row's legs,
    and the manoeuvres charged (``kind``, ``penalty_h``), filled as the legs are sailed."""

    penalties: Any
    initial_side: int
    side: npt.NDArray[np.int8]
    twa: FloatArray
    tws: FloatArray
    kind: npt.NDArray[np.int8]
    penalty_h: FloatArray

    @classmethod
    def of(cls, problem: RoutingProblem, shape: tuple[int, int], wanted: bool | None) -> _Manoeuvres | None:
        """The arrays for legs of ``shape`` (rows, legs), or None when they are not wanted (``wanted`` None: only
        when the problem charges manoeuvres)."""
        if not (problem.sides if wanted is None else wanted):
            return None
        return cls(
            penalties=problem.manoeuvres if problem.sides else None,
            initial_side=-1 if problem.initial_side is None else int(problem.initial_side),
            side=np.zeros(shape, dtype=np.int8),
            twa=np.full(shape, np.nan),
            tws=np.full(shape, np.nan),
            kind=np.zeros(shape, dtype=np.int8),
            penalty_h=np.zeros(shape),
        )

    def charge(self, rows: npt.NDArray[np.intp], k: int) -> FloatArray:
        """Charge leg ``k`` of ``rows`` (its wind known, the previous leg's side too) and return the penalties [h]."""
        prev = self.side[rows, k - 1] if k else np.full(rows.size, self.initial_side, dtype=np.int8)
        kind, pen = charge_manoeuvres(self.side[rows, k], self.twa[rows, k], self.tws[rows, k], prev, self.penalties)
        self.kind[rows, k], self.penalty_h[rows, k] = kind, pen
        return pen

    def charge_tracks(
        self, has: npt.NDArray[np.bool_], time_h: FloatArray, elapsed: FloatArray, wait: FloatArray
    ) -> None:
        """Steady weather: charge every leg and, with penalties, chain the arrivals as the DP adds them
        ((departure after the wait + sailing) + penalty), in place."""
        for k in range(has.shape[1]):
            rows = np.flatnonzero(has[:, k])
            pen = self.charge(rows, k)
            if self.penalties is not None:
                elapsed[rows, k + 1] = ((elapsed[rows, k] + wait[rows, k]) + time_h[rows, k]) + pen

    def track(self, r: int, n: int, elapsed_h: FloatArray) -> TrackManoeuvres:
        """Row ``r``'s first ``n`` legs; legs from one that cannot be sailed on have no manoeuvre."""
        sailed = np.isfinite(elapsed_h[1:])
        return TrackManoeuvres(
            side=self.side[r, :n].copy(),
            kind=np.where(sailed, self.kind[r, :n], 0).astype(np.int8),
            penalty_h=np.where(sailed, self.penalty_h[r, :n], 0.0),
        )


def _sailed(
    t: Track,
    elapsed: FloatArray,
    time_h: FloatArray,
    p_f: FloatArray,
    reason: npt.NDArray[np.uint8],
    land: npt.NDArray[np.bool_],
    zone: npt.NDArray[np.bool_],
    apf: float,
    marks: FloatArray | None = None,
    wait: FloatArray | None = None,
) -> Sailed:
    """One track's :class:`Sailed` from its rows (copies), the legs after one that cannot be sailed cleared."""
    e = elapsed.copy()
    costs = ArcCosts(
        time_h=time_h.copy(), p_f=p_f.copy(), reason=reason.copy(), marks_h=None if marks is None else marks.copy()
    )
    hit_land, hit_zone = land.copy(), zone.copy()
    stop = np.flatnonzero(~np.isfinite(e))
    if stop.size:  # the legs after the one that cannot be sailed are not sailed
        e[stop[0] :] = np.inf
        costs.time_h[stop[0] :], costs.p_f[stop[0] :], costs.reason[stop[0] :] = np.nan, np.nan, 0
        hit_land[stop[0] :], hit_zone[stop[0] :] = False, False
    waits = np.zeros(time_h.size) if wait is None else wait.copy()
    return Sailed(t.lon_deg, t.lat_deg, e, costs, hit_land, hit_zone, apf, wait_h=waits)


@dataclass(frozen=True)
class _Legs:
    """The tracks' legs and their :class:`~pyroute_rel.routing.cost.ArcGeometry`, computed once for every weather they
    are sailed in (it depends on the points only): leg ``k`` of track ``i`` is ``geometry`` row ``index[i, k]`` (-1: the
    track has no such leg)."""

    geometry: ArcGeometry
    index: npt.NDArray[np.intp]

    @classmethod
    def of(cls, lon: FloatArray, lat: FloatArray, has: npt.NDArray[np.bool_], samples: int) -> _Legs:
        """The legs of tracks whose points are the rows of ``lon``, ``lat`` [deg] (``has``: which legs exist)."""
        index = np.full(has.shape, -1, dtype=np.intp)
        index[has] = np.arange(int(has.sum()))
        geometry = arc_geometry(lon[:, :-1][has], lat[:, :-1][has], lon[:, 1:][has], lat[:, 1:][has], samples=samples)
        return cls(geometry, index)

    def box(self) -> tuple[float, float, float, float] | None:
        """``lon_min, lon_max, lat_min, lat_max`` [deg] holding every point of every leg (as
        :func:`~pyroute_rel.routing.cost.arc_geometry` and :mod:`~pyroute_rel.reliability.crossings` place them,
        longitudes in [-180, 180]), or None when a leg crosses the antimeridian or comes within a degree of a pole.
        Longitude is monotonic along a minor arc that does not pass a pole, and every point of an arc is within half its
        central angle of an end."""
        g = self.geometry
        assert g.a_xyz is not None and g.b_xyz is not None
        if not g.a_xyz.size:
            return None
        lon0, lon1 = (np.degrees(np.arctan2(v[:, 1], v[:, 0])) for v in (g.a_xyz, g.b_xyz))
        lat0, lat1 = (np.degrees(np.arcsin(np.clip(v[:, 2], -1.0, 1.0))) for v in (g.a_xyz, g.b_xyz))
        d = g.a_xyz - g.b_xyz
        half = np.degrees(2.0 * np.arcsin(np.clip(np.sqrt(np.sum(d * d, axis=-1)) / 2.0, 0.0, 1.0))) / 2.0
        lat_lo, lat_hi = float(np.min(np.minimum(lat0, lat1) - half)), float(np.max(np.maximum(lat0, lat1) + half))
        if abs(lon1 - lon0).max() >= 180.0 or lat_lo < -89.0 or lat_hi > 89.0:
            return None
        pad = 1e-6  # rounding of the points placed along the arcs
        return (
            float(np.minimum(lon0, lon1).min()) - pad,
            float(np.maximum(lon0, lon1).max()) + pad,
            lat_lo - pad,
            lat_hi + pad,
        )

    def at(self, rows: npt.NDArray[np.intp], k: int | npt.NDArray[np.intp]) -> tuple[npt.NDArray[np.intp], ArcGeometry]:
        """Which legs rows ``rows`` sail as their ``k``-th (row ``r`` is track ``r % tracks``), and their samples'
        geometry (without the ends' unit vectors)."""
        i = self.index[rows % self.index.shape[0], k]
        g = self.geometry
        return i, ArcGeometry(g.lon_deg[i], g.lat_deg[i], g.course_deg[i], g.seg_nm[i])


def _sail_legs(
    problems: Sequence[RoutingProblem],
    legs: _Legs,
    stack: Any,
    has: npt.NDArray[np.bool_],
    elapsed: FloatArray,
    time_h: FloatArray,
    p_f: FloatArray,
    reason: npt.NDArray[np.uint8],
    man: _Manoeuvres | None = None,
    marks: FloatArray | None = None,
    wait: FloatArray | None = None,
) -> None:
    """Time-varying weather: the k-th legs of every row costed together (their samples' ``p_f``), leg after leg,
    filling the arrays in place; ``man``: each leg's side found at its departure and its manoeuvre charged. The
    members' weathers are sampled together (``stack``, :func:`~pyroute_rel.weather.gridded.stack_members`) where
    they can be."""
    first = problems[0]
    n_c = legs.index.shape[0]
    for k in range(has.shape[1]):
        go = has[:, k] & np.isfinite(elapsed[:, k])
        if not go.any():
            continue
        rows = np.flatnonzero(go)
        t0 = elapsed[rows, k] if wait is None else elapsed[rows, k] + wait[rows, k]  # leaving after its wait
        _, geom = legs.at(rows, k)  # samples only: pieces later
        weather = _rows_weather(problems, rows // n_c, stack)
        c = geometry_costs(
            geom,
            t0,
            departure=first.departure,
            weather=weather,
            polar=first.polar,
            failure=first.failure,
            apf=1.0,
            beyond=first.beyond,
            wave_loss=first.wave_loss,
            workers=1 if len(problems) > 1 else None,  # threads split rows: the weather's rows must stay whole
        )
        time_h[rows, k], p_f[rows, k], reason[rows, k] = c.time_h, c.p_f, c.reason
        if marks is not None and c.marks_h is not None:
            marks[rows, k] = c.marks_h
        if man is None:
            elapsed[rows, k + 1] = first.arrive(t0 + c.time_h)
        else:
            wind = first_sample_wind(replace(first, weather=weather), geom, t0)
            man.side[rows, k], man.twa[rows, k], man.tws[rows, k] = wind
            pen = man.charge(rows, k)
            elapsed[rows, k + 1] = first.arrive(t0 + c.time_h if man.penalties is None else (t0 + c.time_h) + pen)
        elapsed[has[:, k] & ~go, k + 1] = np.inf


#: Largest copy of the members' gridded data :func:`sail_in_members` makes to sample them together [bytes]; more
#: members are sailed in groups.
STACK_MAX_BYTES = 600_000_000


def _member_groups(problems: Sequence[RoutingProblem]) -> list[Sequence[RoutingProblem]]:
    """The problems in consecutive groups whose gridded data stacked take at most :data:`STACK_MAX_BYTES` (at
    least two a group)."""
    each = max((int(p.weather.nbytes) for p in problems), default=0)
    if len(problems) < 3 or problems[0].weather.steady or each * len(problems) <= STACK_MAX_BYTES:
        return [problems]
    size = max(2, STACK_MAX_BYTES // each)
    return [problems[g : g + size] for g in range(0, len(problems), size)]


def _member_stack(problems: Sequence[RoutingProblem]) -> Any:
    """How to stack the problems' weathers: :func:`~pyroute_rel.weather.gridded.stack_members` of them, called with
    the ``box`` of the points to be sampled (it gives None when the weathers are not gridded on one grid); None with
    one problem."""
    if len(problems) < 2:
        return None
    from pyroute_rel.weather.gridded import stack_members

    return functools.partial(stack_members, [p.weather for p in problems])


def _judge_legs(
    problems: Sequence[RoutingProblem],
    legs: _Legs,
    stack: Any,
    depart: FloatArray,
    time_h: FloatArray,
    p_f: FloatArray,
    marks: FloatArray | None = None,
) -> None:
    """Each weather's legs (leaving at ``depart`` [h], (rows, legs)) judged on every piece they cross, as the cost
    function judges an arc (:func:`~pyroute_rel.routing.cost.geometry_costs` with its end points): the legs sailed whose
    samples did not meet the table's largest ``p_f`` and that may need it
    (:func:`~pyroute_rel.reliability.crossings.needs_pieces`) get the largest ``p_f`` met anywhere along them (in
    place). With one weather, or the members' weathers on one grid (``stack``), each leg is cut into pieces once and
    every weather's legs are judged in one call."""
    first = problems[0]
    model = first.failure
    if model is None:
        return
    from pyroute_rel.reliability.crossings import arc_extremes, arc_pieces, cut_in_time, needs_pieces

    n_c = legs.index.shape[0]
    top = float(np.max(model.p_flat))
    picked = []
    for j, problem in enumerate(problems):
        rows = slice(j * n_c, (j + 1) * n_c)
        with np.errstate(invalid="ignore"):
            todo = np.isfinite(time_h[rows]) & (p_f[rows] < top)
        r, k = np.nonzero(todo)
        if not r.size:
            continue
        r = r + j * n_c
        i, geom = legs.at(r, k)
        near = needs_pieces(geom.lon_deg, geom.lat_deg, geom.course_deg, geom.seg_nm, depart[r, k], time_h[r, k],
                            weather=problem.weather, failure=model, departure=first.departure)  # fmt: skip
        pick = slice(None) if near is None else np.flatnonzero(near)
        picked.append((j, r[pick], k[pick], i[pick]))
    picked = [x for x in picked if x[1].size]
    if not picked:
        return
    g = legs.geometry
    assert g.a_xyz is not None and g.b_xyz is not None
    calls: list[tuple[npt.NDArray[np.intp], npt.NDArray[np.intp], npt.NDArray[np.intp], ArcPieces | None, Any]]
    if len(problems) == 1 or stack is not None:  # one call, each leg judged cut once
        r, k, i = (np.concatenate([x[n] for x in picked]) for n in (1, 2, 3))
        which, at = np.unique(i, return_inverse=True)
        cut = arc_pieces(g.a_xyz[which], g.b_xyz[which], first.weather.boundaries).take(at)
        if marks is not None:  # and where each row's craft crosses a time step of the weather
            cut = cut_in_time(cut, marks[r, k], first.weather.time_steps, first.departure)
        calls = [(r, k, i, cut, _rows_weather(problems, (r // n_c)[cut.arc], stack))]
    else:
        calls = [(r, k, i, None, problems[j].weather) for j, r, k, i in picked]
    for r, k, i, pieces, weather in calls:
        ext = arc_extremes(
            g.a_xyz[i],
            g.b_xyz[i],
            depart[r, k],
            time_h[r, k],
            departure=first.departure,
            weather=weather,
            polar=first.polar,
            failure=model,
            apf=1.0,
            beyond=first.beyond,
            speed_factor=None if first.wave_loss is None else first.wave_loss.factor,
            pieces=pieces,
            marks_h=None if marks is None else marks[r, k],
        )
        p_f[r, k] = np.maximum(p_f[r, k], ext.p_f)


def _rows_weather(problems: Sequence[RoutingProblem], member: npt.NDArray[np.intp], stack: Any = None) -> Any:
    """The weather of rows whose weather is ``problems[member[row]]`` (``member`` sorted): the one source when
    there is one, else :class:`_MemberRows` (sampling every member in one call through ``stack``, a
    :class:`~pyroute_rel.weather.gridded.MemberStack` of the problems' weathers, when there is one)."""
    if len(problems) == 1:
        return problems[0].weather
    cuts = np.searchsorted(member, np.arange(len(problems) + 1))
    return _MemberRows([p.weather for p in problems], cuts, None if stack is None else (stack, member))


class _MemberRows(WeatherBase):
    rows_aligned = True  # (each row from its member)

    """A weather source whose queries' rows (first axis) come from different sources: rows ``cuts[j]:cuts[j + 1]``
    are answered by ``sources[j]`` (the sources share their kind: all steady or all time-varying); with ``stack``
    (a :class:`~pyroute_rel.weather.gridded.MemberStack` of the sources and each row's source), prepared points are
    sampled in one call."""

    def __init__(self, sources: Sequence[Any], cuts: npt.NDArray[np.intp], stack: Any = None) -> None:
        self.parts = [(s, int(a), int(b)) for s, a, b in zip(sources, cuts[:-1], cuts[1:], strict=True) if b > a]
        self.steady = bool(sources[0].steady)
        steps = [s.time_steps for s in sources if s.time_steps is not None]
        self.time_steps = np.unique(np.concatenate(steps)) if steps else None
        self.fields = frozenset(sources[0].fields)
        self.max_current_ms = max(float(s.max_current_ms) for s in sources)
        self.stack = stack

    def take_rows(self, rows: npt.NDArray[np.intp]) -> _MemberRows:
        """The same weather for queries whose rows are rows ``rows`` (sorted) of this one's."""
        owner = np.repeat(np.arange(len(self.parts)), [b - a for _, a, b in self.parts])[rows]
        sources = [s for s, _, _ in self.parts]
        cuts = np.searchsorted(owner, np.arange(len(sources) + 1))
        stack = None if self.stack is None else (self.stack[0], self.stack[1][rows])
        return _MemberRows(sources, cuts, stack)

    def compiled_source(self) -> Any:
        """With the members stacked, the gridded source whose data points located by :meth:`prepare` index (the
        compiled march samples it there: :mod:`pyroute_rel._kernels.march`); else None."""
        return None if self.stack is None else self.stack[0].joined

    def prepare(self, lon_deg: Any, lat_deg: Any) -> Any:
        lon, lat = np.broadcast_arrays(np.asarray(lon_deg, dtype=float), np.asarray(lat_deg, dtype=float))
        if self.stack is not None:
            stack, member = self.stack
            return stack.prepare(lon, lat, member)
        return [s.prepare(lon[a:b], lat[a:b]) for s, a, b in self.parts]

    def sample_at(self, prepared: Any, departure: Any, *, offset_h: Any = None, fields: Any = None) -> Conditions:
        if self.stack is not None:
            return self.stack[0].sample_at(prepared, departure, offset_h=offset_h, fields=fields)
        off = None if offset_h is None else np.asarray(offset_h, dtype=float)
        return _join(
            [
                s.sample_at(p, departure, offset_h=None if off is None else off[a:b], fields=fields)
                for (s, a, b), p in zip(self.parts, prepared, strict=True)
            ]
        )

    def sample(self, lon_deg: Any, lat_deg: Any, time: Any) -> Conditions:
        lon, lat, t = np.broadcast_arrays(np.asarray(lon_deg, dtype=float), np.asarray(lat_deg, dtype=float), time)
        return _join([s.sample(lon[a:b], lat[a:b], t[a:b]) for s, a, b in self.parts])

    def check_coverage(self, lon_range: Any, lat_range: Any, time_range: Any) -> None:
        for s, _, _ in self.parts:
            s.check_coverage(lon_range, lat_range, time_range)


def _join(parts: Sequence[Conditions]) -> Conditions:
    """Conditions of consecutive row blocks joined along the first axis."""
    names = [f.name for f in dataclass_fields(Conditions)]
    shapes = [np.shape(p.tws_kn) for p in parts]
    return Conditions(
        **{
            n: np.concatenate([np.broadcast_to(getattr(p, n), s) for p, s in zip(parts, shapes, strict=True)])
            for n in names
        }  # fmt: skip
    )


def _obstacles(
    problem: RoutingProblem, avoid: Any, lon: FloatArray, lat: FloatArray, depart: FloatArray, has: Any
) -> tuple[npt.NDArray[np.bool_], npt.NDArray[np.bool_]]:
    """Which legs touch land and which an exclusion zone active at the leg's departure (``depart`` [h], (rows, legs):
    after its wait; as the router's mask)."""
    land = np.zeros(has.shape, dtype=bool)
    zone = np.zeros(has.shape, dtype=bool)
    if avoid is None or not has.any():
        return land, zone
    a, b, c, d = lon[:, :-1][has], lat[:, :-1][has], lon[:, 1:][has], lat[:, 1:][has]
    if avoid.land:
        from pyroute_rel.obstacles.land import arcs_on_land

        land[has] = arcs_on_land(a, b, c, d, margin_km=avoid.margin_km, resolution=avoid.resolution)
    if avoid.zones:
        from pyroute_rel.obstacles.zones import arcs_blocked_by_zones
        from pyroute_rel.times import hours_after

        t0 = depart[has]
        when = hours_after(problem.departure, np.where(np.isfinite(t0), t0, 0.0))
        zone[has] = arcs_blocked_by_zones(a, b, c, d, avoid.zones, when)
    return land, zone


# ------------------------------------------------------------------------------------------------ evaluation


@dataclass(frozen=True, eq=False)
class Evaluation:
    """A track sailed in a scenario's weather (:func:`evaluate_track`).

    Attributes
    ----------
    legs : Per-leg conditions, the columns of :attr:`pyroute_rel.routing.route.Route.legs` (NaN after a leg that cannot
        be sailed; that leg's ``time_h`` is ``inf``).
    track : The points, (N, 2) lon, lat [deg].
    time : UTC time at each point (NaT from the first leg that cannot be sailed).
    elapsed_h : Time at each point [h after the departure] (``inf`` likewise).
    departure : Departure time (UTC).
    feasible : True when the router could have sailed every leg: no ``p_f > apf``, land, zone, or leg that cannot be
        sailed.
    reason : None, or why the first blocked leg is blocked: one of :data:`BLOCK_REASONS`.
    blocked_leg : Index of that leg, or None.
    leg_reasons : Why each leg is blocked (a tuple of :data:`BLOCK_REASONS` names per leg, empty where it is not).
    exposure_by_criterion_h : Hours sailed where each criterion of the failure model fires [h].
    meta : Settings for the summary (apf, failure model, polar, samples per leg, scenario).
    manoeuvres : Side of the wind of each leg and the tack or gybe at its start, with the time it cost
        (:class:`~pyroute_rel.boat.manoeuvre.TrackManoeuvres`; penalties zero unless the boat has them), as a route's.
    distance_to_finish_nm : How far the track's last point is from the scenario's finish (its finish line when it
        has one) [nm]; None when not known (a track sailed without its scenario's course).
    leg_criteria : For each leg with ``p_f > apf``, the failure model's criteria that fire along it as sailed and for
        how long (e.g. ``"WH: hs_m >= 4 m for 0.83 h"``, joined by ``"; "``); ``""`` for the other legs.

    The voyage figures (``voyage_time_h``, ``distance_nm``, ``arrival``, ``max_failure_probability``,
    ``voyage_failure_probability``) are properties, documented below.
    """

    legs: Legs
    track: FloatArray
    time: npt.NDArray[np.datetime64]
    elapsed_h: FloatArray
    departure: np.datetime64
    feasible: bool
    reason: str | None
    blocked_leg: int | None
    leg_reasons: tuple[tuple[str, ...], ...]
    exposure_by_criterion_h: dict[str, float] = field(default_factory=dict)
    meta: dict[str, Any] = field(default_factory=dict)
    manoeuvres: TrackManoeuvres | None = None
    distance_to_finish_nm: float | None = None
    leg_criteria: tuple[str, ...] = ()

    @property
    def arrived(self) -> bool:
        """True when every leg was sailed and the track ends at the finish (within :data:`ARRIVAL_TOLERANCE_NM`) or
        crosses its finish line; a track whose finish is not known ends at its own last point."""
        near = self.distance_to_finish_nm is None or self.distance_to_finish_nm <= ARRIVAL_TOLERANCE_NM
        return math.isfinite(self.voyage_time_h) and near

    def why(self) -> str | None:
        """One line on what stops the track being a route -- the first blocked leg, why, and the conditions met on
        it, or how far short of the finish it ends -- or None when it is feasible and arrives."""
        if self.feasible and self.arrived:
            return None
        if self.feasible:
            end = self.track[-1]
            return (
                f"the track ends {self.distance_to_finish_nm:.1f} nm from the scenario's finish (at lon "
                f"{end[0]:.2f}, lat {end[1]:.2f}; a route ends within {ARRIVAL_TOLERANCE_NM:g} nm of it, or crosses "
                "its finish line)"
            )
        i = int(self.blocked_leg)  # type: ignore[arg-type]  # not feasible: a leg is blocked
        legs = self.legs
        lon, lat = self.track[i]
        n_blocked = sum(1 for r in self.leg_reasons if r)
        more = f" ({n_blocked - 1} more leg{'s' if n_blocked > 2 else ''} blocked after it)" if n_blocked > 1 else ""
        met = ", ".join(
            f"{label} {legs[key][i]:.{digits}f}{unit}"
            for key, label, unit, digits in (
                ("tws_kn", "TWS", " kn", 1),
                ("twa_deg", "TWA", " deg", 0),
                ("hs_m", "Hs", " m", 2),
            )  # fmt: skip
            if math.isfinite(legs[key][i])
        )
        why = ", ".join(_LEG_BLOCKS[r](self, i) for r in self.leg_reasons[i])
        return (
            f"leg {i} (from track point {i} at lon {lon:.2f}, lat {lat:.2f}) is blocked: {why}"
            + (f" (conditions at its middle: {met})" if met else "")
            + more
        )

    @property
    def voyage_time_h(self) -> float:
        """Time to the last point [h] (``inf`` when a leg cannot be sailed)."""
        return float(self.elapsed_h[-1])

    @property
    def distance_nm(self) -> float:
        """Great-circle length of the track [nm]."""
        return float(self.legs.distance_nm.sum())

    @property
    def arrival(self) -> np.datetime64:
        """Arrival time (UTC; NaT when a leg cannot be sailed)."""
        return self.time[-1]

    @property
    def max_failure_probability(self) -> float:
        """Largest leg ``p_f`` of the legs sailed (0 when none)."""
        p = self.legs.p_f[np.isfinite(self.legs.p_f)]
        return float(p.max()) if p.size else 0.0

    @property
    def voyage_failure_probability(self) -> float:
        """Probability of failure over the legs sailed, ``1 - prod(1 - p_fail_leg)`` [-]."""
        return combined_failure_probability(self.legs.p_fail_leg)

    def summary(self) -> dict[str, Any]:
        """The JSON of ``pyroute-rel evaluate --json``: the keys of :meth:`Route.summary
        <pyroute_rel.routing.route.Route.summary>` that apply to a track (no grid, no arcs), plus ``feasible``,
        ``reason``, ``blocked_leg`` and each leg's reasons in the track's points."""
        p_point = np.concatenate([[0.0], self.legs.p_f])
        reasons = [(), *self.leg_reasons]
        return {
            "voyage_time_h": _finite(self.voyage_time_h),
            "distance_nm": self.distance_nm,
            "departure": iso_utc(self.departure),
            "arrival": None if np.isnat(self.arrival) or not self.arrived else iso_utc(self.arrival),
            "arrived": self.arrived,
            "distance_to_finish_nm": self.distance_to_finish_nm,
            "feasible": self.feasible,
            "reason": self.reason,
            "blocked_leg": self.blocked_leg,
            "max_failure_probability": self.max_failure_probability,
            "voyage_failure_probability": self.voyage_failure_probability,
            "exposure_by_criterion_h": dict(self.exposure_by_criterion_h),
            "manoeuvres": {"tacks": 0, "gybes": 0, "penalty_h": 0.0}
            if self.manoeuvres is None
            else self.manoeuvres.summary(),
            **self.meta,
            "track": [
                {
                    "lon": float(lo),
                    "lat": float(la),
                    "time": None if np.isnat(t) else iso_utc(t),
                    "p_f": _finite(p),
                    "blocked": list(r),
                }
                for lo, la, t, p, r in zip(self.track[:, 0], self.track[:, 1], self.time, p_point, reasons, strict=True)
            ],
        }


#: How close to the finish a track must end to arrive [nm] (a route's own track ends on it; a GPS log or a
#: hand-drawn track may stop a little short).
ARRIVAL_TOLERANCE_NM = 1.0

#: What each of :data:`BLOCK_REASONS` says about leg ``i`` of an evaluation.
_LEG_BLOCKS = {
    "no_speed": lambda ev, i: "the polar gives no boat speed there",
    "current": lambda ev, i: "the current is too strong to hold the course",
    "weather": lambda ev, i: "the weather has no data there",
    "land": lambda ev, i: "it crosses land",
    "zone": lambda ev, i: "it enters an exclusion zone",
    "p_f": lambda ev, i: (
        f"p_f {ev.legs.p_f[i]:.3f} > apf {ev.meta.get('apf', float('nan')):g}"
        + (f", meeting {ev.leg_criteria[i]}" if i < len(ev.leg_criteria) and ev.leg_criteria[i] else "")
    ),
}


def _finite(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def evaluate_track(
    scenario: Scenario | str | Path,
    track: Track | npt.ArrayLike,
    *,
    departure: Any = None,
    member: int | None = None,
    apf: float | None = None,
    weather: WeatherSource | None = None,
    samples: int | None = None,
) -> Evaluation:
    """Sail a track in a scenario's weather with its polar, failure model, land and zones (see the module notes).

    Parameters
    ----------
    scenario : The scenario (:func:`~pyroute_rel.scenario.load_scenario`), or its file.
    track : A :class:`Track` (:func:`read_track`) or an (N, 2) array of lon, lat [deg].
    departure : Departure time (UTC; default: the track's first time, else the scenario's departure).
    member : Sail in this ensemble member's weather (:func:`pyroute_rel.analysis.members.member_scenario`: the
        scenario's file read with ``[weather] member = k``).
    apf : Acceptable probability of failure the legs are held to (default the scenario's).
    weather : Sail in this weather source instead of the scenario's.
    samples : Weather samples per leg (default: as the scenario's route samples its arcs).

    Returns
    -------
    Evaluation

    Examples
    --------
    >>> from pyroute_rel import scenario_from_mapping
    >>> sc = scenario_from_mapping({
    ...     "route": {"start": [-12.0, 45.0], "finish": [-20.0, 40.0], "departure": "2018-06-01T00:00:00Z"},
    ...     "grid": {"n_ranks": 20}, "weather": {"kind": "uniform", "tws_kn": 15.0, "twd_deg": 0.0},
    ...     "avoid": {"land": False}, "failure": {"model": "dickson2018", "apf": 0.5}})
    >>> route = sc.route()
    >>> ev = evaluate_track(sc, np.column_stack([route.lon_deg, route.lat_deg]))
    >>> abs(ev.voyage_time_h - route.voyage_time_h) < 1e-9, ev.feasible, ev.reason
    (True, True, None)
    """
    trk = as_track(track)
    if member is not None:
        from pyroute_rel.analysis.members import member_scenario

        scenario = member_scenario(scenario, member)
    elif isinstance(scenario, str | Path):
        from pyroute_rel.scenario import load_scenario

        scenario = load_scenario(scenario)
    _check_scenario(scenario)
    if departure is None and trk.time is not None:
        departure = trk.time[0]
    problem = evaluation_problem(scenario, departure=departure, apf=apf, samples=samples, weather=weather)
    lon0, lat0 = float(trk.lon_deg[0]), float(trk.lat_deg[0])
    # a track that starts where or when the weather has no data is an error, not a voyage of no time (issue 34)
    problem.weather.check_coverage((lon0, lon0), (lat0, lat0), (problem.departure, problem.departure))
    sailed = sail_tracks(problem, [trk], avoid=scenario.avoid, manoeuvres=True)[0]
    ev = describe(problem, sailed, meta={"scenario": scenario.source, "land": scenario.avoid.land})
    end = float(trk.lon_deg[-1]), float(trk.lat_deg[-1])
    mark = scenario.finish_line or (scenario.finish,)
    distance = geodesy.distance_to_segment_nm(*end, *mark)
    if scenario.finish_line is not None:  # a track that crosses the finish line has arrived, wherever it ends
        (c_lon, c_lat), (d_lon, d_lat) = scenario.finish_line
        lon, lat = trk.lon_deg, trk.lat_deg
        crossed = geodesy.crossing_fraction(lon[:-1], lat[:-1], lon[1:], lat[1:], c_lon, c_lat, d_lon, d_lat)
        distance = 0.0 if np.isfinite(crossed).any() else distance
    return replace(ev, distance_to_finish_nm=distance)


def evaluation_route(
    evaluation: Evaluation,
    grid: Grid,
    problem: RoutingProblem,
    *,
    arrived: bool,
    nodes: Sequence[int] = (),
    zones: tuple[Zone, ...] = (),
) -> Route | None:
    """A sailed track as a :class:`~pyroute_rel.routing.route.Route`, so the DP's outputs (map, GPX, CSV, GeoJSON)
    write it: the evaluation's track, times, legs and exposure on ``grid`` and ``problem``; None when a leg cannot be
    sailed (no times after it).

    The route's ``dp`` is empty (no arc was costed by the DP: every node unreached); ``nodes`` are its nodes on the
    grid, if any; ``arrived`` False for a track that stops short of the finish (a planner's that did not reach it, the
    best partial route of a course that does not route).
    """
    from pyroute_rel.routing.solve import DPResult

    if not np.all(np.isfinite(evaluation.elapsed_h)):
        return None
    shape = (grid.n_ranks, grid.n_nodes)
    empty = DPResult(
        arrival_h=np.full(shape, np.inf),
        back=np.full(shape, -1, dtype=np.intp),
        finish_h=float(evaluation.voyage_time_h),
        finish_back=-1,
        arcs_evaluated=0,
        arcs_forbidden=0,
        forbidden_by_reason={},
        dead_rank=None,
    )
    return Route(
        lon_deg=np.asarray(evaluation.track[:, 0], dtype=float),
        lat_deg=np.asarray(evaluation.track[:, 1], dtype=float),
        elapsed_h=np.asarray(evaluation.elapsed_h, dtype=float),
        departure=evaluation.departure,
        legs=evaluation.legs,
        nodes=np.asarray(nodes, dtype=np.intp),
        grid=grid,
        dp=empty,
        problem=problem,
        meta=dict(evaluation.meta),
        zones=zones,
        exposure_by_criterion_h=dict(evaluation.exposure_by_criterion_h),
        arrived=arrived,
    )


def describe(problem: RoutingProblem, sailed: Sailed, *, meta: dict[str, Any] | None = None) -> Evaluation:
    """The :class:`Evaluation` of a sailed track: its legs described as a routed track's
    (:func:`~pyroute_rel.routing.route.track_legs`) up to the first leg that cannot be sailed."""
    lon, lat, e = sailed.lon_deg, sailed.lat_deg, sailed.elapsed_h
    n = lon.size - 1
    finite = np.isfinite(e)
    k = n if finite.all() else int(np.flatnonzero(~finite)[0]) - 1  # legs sailed in full
    cols = {name: np.full(n, np.nan) for name in Legs.__dataclass_fields__}
    cols["distance_nm"] = geodesy.distance_nm(lon[:-1], lat[:-1], lon[1:], lat[1:])
    waits = np.zeros(n) if sailed.wait_h is None else sailed.wait_h
    cols["wait_h"] = waits.copy()
    exposure: dict[str, float] = {}
    criteria_h: dict[str, FloatArray] = {}  # hours each criterion fires on each leg sailed
    if k > 0:
        c = sailed.costs
        marks = None if c.marks_h is None else c.marks_h[:k]
        part = ArcCosts(time_h=c.time_h[:k], p_f=c.p_f[:k], reason=c.reason[:k], marks_h=marks)
        legs, exp = track_legs(problem, lon[: k + 1], lat[: k + 1], e[: k + 1], waits[:k], part)
        for name in cols:
            cols[name][:k] = legs[name]
        exposure = {c: float(v.sum()) for c, v in exp.criterion_h.items()}
        criteria_h = {c: np.asarray(v, dtype=float) for c, v in exp.criterion_h.items()}
    if k < n:  # the leg that cannot be sailed
        cols["time_h"][k] = np.inf
        cols["p_f"][k] = sailed.costs.p_f[k]
    reasons = sailed.leg_reasons()
    blocked = next((i for i, r in enumerate(reasons) if r), None)
    leg_criteria = tuple(
        "; ".join(f"{c} for {h[i]:.2f} h" for c, h in criteria_h.items() if i < k and h[i] > 0.0) if "p_f" in r else ""
        for i, r in enumerate(reasons)
    )
    start = np.datetime64(problem.departure, "s")  # type: ignore[call-overload]  # numpy's stubs have no datetime64(datetime64, unit) overload
    seconds = np.round(np.where(finite, e, 0.0) * 3600.0).astype("timedelta64[s]")
    times = np.where(finite, start + seconds, np.datetime64("NaT", "s"))
    return Evaluation(
        legs=Legs(**cols),
        track=np.column_stack([lon, lat]),
        time=times.astype("datetime64[s]"),
        elapsed_h=e,
        departure=start,
        feasible=blocked is None,
        reason=None if blocked is None else reasons[blocked][0],
        blocked_leg=blocked,
        leg_reasons=tuple(reasons),
        exposure_by_criterion_h=exposure,
        manoeuvres=sailed.manoeuvres,
        leg_criteria=leg_criteria,
        meta={
            "apf": float(problem.apf),
            "failure_model": None if problem.failure is None else problem.failure.name,
            "failure_exposure_h": None if problem.failure is None else problem.failure.exposure_h,
            "polar": problem.polar.name,
            "samples_per_arc": problem.samples,
            **(meta or {}),
        },
    )


def _check_scenario(scenario: Any) -> None:
    from pyroute_rel.scenario import Scenario

    if not isinstance(scenario, Scenario):
        raise ScenarioError(f"expected a Scenario (pyroute_rel.load_scenario) (got {type(scenario).__name__})")
