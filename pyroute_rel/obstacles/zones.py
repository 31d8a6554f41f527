"""User exclusion zones: GeoJSON no-go areas (fishing grounds, shipping lanes, exercise areas), seasonal or not.

A zone is a lon/lat Polygon or MultiPolygon (holes allowed) with an optional ``valid_from``/``valid_to`` window;
an arc touching a zone that is active when the arc is sailed is forbidden. The arc test is the one land uses
(:func:`pyroute_rel.obstacles.areas.arcs_blocked`: great circles densified, cached index per geometry).

References
----------
Butler, H. et al. (2016). The GeoJSON Format. RFC 7946, doi:10.17487/RFC7946.
"""

from __future__ import annotations

import datetime as dt
import json
import os
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import shapely

from pyroute_rel.errors import ScenarioError, brief, check_path
from pyroute_rel.files import brief_path, read_regular_bytes
from pyroute_rel.obstacles.areas import area_index, as_arcs, blocked_flat, checked_samples

__all__ = [
    "Zone",
    "load_zones",
    "zones_active",
    "arcs_blocked_by_zones",
    "zones_outside",
    "ZONE_MAX_BYTES",
]

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]
PathLike = str | os.PathLike[str]

_GEOJSON_POLYGONAL = ("Polygon", "MultiPolygon")

#: Largest zone file read [bytes]: 100 MB holds about 3 million positions of GeoJSON, far more than any
#: exclusion zone needs; a wrong path (a device, a huge download) is refused before it is read.
ZONE_MAX_BYTES = 100_000_000


@dataclass(frozen=True)
class Zone:
    """A user exclusion zone.

    Attributes
    ----------
    name : Label for messages and plots.
    geometry : shapely Polygon or MultiPolygon in lon/lat [deg] (holes are free water).
    valid_from : First instant the zone applies (UTC, ``numpy.datetime64``), or None = always.
    valid_to : Last instant the zone applies (UTC), or None = for ever.
    """

    name: str
    geometry: shapely.Geometry
    valid_from: np.datetime64 | None = None
    valid_to: np.datetime64 | None = None

    def active(self, time: npt.ArrayLike, time_end: npt.ArrayLike | None = None) -> BoolArray:
        """Whether the zone applies at ``time`` (or at any instant of [time, time_end]); NaT -> True."""
        t0 = np.asarray(time, dtype="datetime64[ns]")
        t1 = t0 if time_end is None else np.asarray(time_end, dtype="datetime64[ns]")
        t0, t1 = np.broadcast_arrays(t0, t1)
        ok = np.ones(t0.shape, dtype=bool)
        if self.valid_from is not None:
            ok &= ~(t1 < self.valid_from)
        if self.valid_to is not None:
            ok &= ~(t0 > self.valid_to)
        return ok | np.isnat(t0) | np.isnat(t1)


def zones_active(zones: Iterable[Zone], t0: Any, t1: Any = None) -> tuple[Zone, ...]:
    """The zones whose validity window overlaps [t0, t1] (``t1=None``: the instant t0).

    >>> z = Zone("z", shapely.box(0, 0, 1, 1), np.datetime64("2018-06-01"), np.datetime64("2018-06-30"))
    >>> [len(zones_active([z], np.datetime64(d))) for d in ("2018-05-31", "2018-06-15", "2018-07-01")]
    [0, 1, 0]
    """
    return tuple(z for z in zones if bool(z.active(np.datetime64(t0), None if t1 is None else np.datetime64(t1))))


def arcs_blocked_by_zones(
    lon0: npt.ArrayLike,
    lat0: npt.ArrayLike,
    lon1: npt.ArrayLike,
    lat1: npt.ArrayLike,
    zones: Sequence[Zone],
    time: npt.ArrayLike | None = None,
    *,
    time_end: npt.ArrayLike | None = None,
    samples_km: float = 2.0,
) -> BoolArray:
    """Which arcs touch an exclusion zone that is active when the arc is sailed.

    Parameters
    ----------
    lon0, lat0, lon1, lat1 : End points of the arcs [deg]; broadcast together.
    zones : Exclusion zones (:func:`load_zones`).
    time : Departure time of each arc (``datetime64``, broadcast with the arcs), or None: every zone
        counts as active.
    time_end : Optional arrival time of each arc; a zone then blocks an arc whose window overlaps
        [time, time_end] rather than only containing ``time``.
    samples_km : Largest spacing of the points along each arc [km].

    Examples
    --------
    >>> z = Zone("z", shapely.box(-30, 35, -28, 37), np.datetime64("2018-06-01"), np.datetime64("2018-06-30"))
    >>> t = np.array(["2018-06-10", "2018-07-10"], dtype="datetime64[s]")
    >>> arcs_blocked_by_zones(-31.0, 36.0, -27.0, 36.0, [z], t).tolist()
    [True, False]
    """
    arrays = [np.asarray(a, dtype=float) for a in (lon0, lat0, lon1, lat1)]
    t0 = None if time is None else np.asarray(time, dtype="datetime64[ns]")
    t1 = None if time_end is None else np.asarray(time_end, dtype="datetime64[ns]")
    extra = [np.empty(t.shape) for t in (t0, t1) if t is not None]
    shape = np.broadcast_shapes(*(a.shape for a in arrays), *(e.shape for e in extra))
    arrays = [np.broadcast_to(a, shape) for a in arrays]
    _, a, b, c, d = as_arcs(*arrays)
    step = checked_samples(samples_km)
    blocked = np.zeros(a.shape, dtype=bool)
    for zone in zones:  # loop over zones (a handful), vectorised over arcs
        live: BoolArray = np.ones(a.shape, dtype=bool)
        if t0 is not None:
            live = np.broadcast_to(zone.active(t0, t1), shape).ravel()
        todo = np.flatnonzero(live & ~blocked)
        if todo.size:
            hit = blocked_flat(a[todo], b[todo], c[todo], d[todo], area_index(zone.geometry), step)
            blocked[todo[hit]] = True
    return blocked.reshape(shape)


def load_zones(paths: PathLike | Iterable[PathLike], *, base_dir: PathLike | None = None) -> tuple[Zone, ...]:
    """Read exclusion zones from GeoJSON files (RFC 7946, lon/lat [deg]).

    Each file holds a FeatureCollection, a Feature, or a bare Polygon / MultiPolygon geometry; every
    polygonal Feature becomes one :class:`Zone` (holes allowed). Optional Feature properties: ``name``
    (default: file stem, with the feature number when there are several), ``valid_from`` and
    ``valid_to`` (ISO 8601; naive times are UTC, offsets are converted to UTC; a date alone is its
    midnight). Invalid polygons (edges that cross, a figure of eight) are refused with the place where they
    cross. A polygon that crosses the antimeridian must be split into parts on either side of it.

    Parameters
    ----------
    paths : One path or several.
    base_dir : Folder that relative paths are resolved against (e.g. the scenario file's folder).

    Returns
    -------
    tuple of :class:`Zone`, in file and feature order.

    Raises
    ------
    ScenarioError
        Naming the file (and feature) and what was wrong: missing, not JSON, not a polygon, coordinates
        out of range, invalid (self-crossing) polygon, bad time, not a regular file or larger than
        :data:`ZONE_MAX_BYTES`.
    """
    if isinstance(paths, (str, os.PathLike)):
        paths = [paths]
    if not isinstance(paths, Iterable) or isinstance(paths, bytes | Mapping):
        raise ScenarioError(f"zone files must be a path or a list of paths (got {brief(paths)})")
    if base_dir is not None:
        check_path(base_dir, "base_dir", ScenarioError)
    paths = list(paths)
    for p in paths:  # every one before any file is read
        if not isinstance(p, (str, os.PathLike)):
            raise ScenarioError(f"a zone file must be a path (str or pathlib.Path) (got {brief(p)})")
    zones: list[Zone] = []
    for p in paths:
        path = Path(p)
        if base_dir is not None and not path.is_absolute():
            path = Path(base_dir) / path
        zones.extend(_read_zone_file(path))
    return tuple(zones)


def _read_zone_file(path: Path) -> list[Zone]:
    data = read_regular_bytes(
        path, limit_bytes=ZONE_MAX_BYTES, error=ScenarioError, label=brief_path(path), what="zone file"
    )
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise ScenarioError(f"{brief_path(path)}: cannot read zone file (not UTF-8 text: offset {exc.start})") from None
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ScenarioError(
            f"{brief_path(path)}: not valid JSON ({exc.msg} at line {exc.lineno} column {exc.colno})"
        ) from None
    except RecursionError:
        raise ScenarioError(f"{brief_path(path)}: JSON arrays or objects nested too deeply to read") from None
    except ValueError as exc:  # (a number of more than 4300 digits)
        raise ScenarioError(f"{brief_path(path)}: not valid JSON ({' '.join(str(exc).split())[:120]})") from None
    if not isinstance(doc, dict) or not isinstance(doc.get("type"), str):
        raise ScenarioError(
            f"{brief_path(path)}: expected a GeoJSON object with a 'type' member (got {type(doc).__name__})"
        )
    crs = doc.get("crs")
    if crs is not None:
        props = crs.get("properties") if isinstance(crs, dict) else None
        name = str(props.get("name", "")) if isinstance(props, dict) else ""
        if not (name.endswith("CRS84") or name.endswith("4326")):
            raise ScenarioError(
                f"{brief_path(path)}: coordinates must be WGS84 lon/lat (CRS84) (got crs {brief(name or crs)})"
            )
    kind = doc["type"]
    if kind == "FeatureCollection":
        features = doc.get("features")
        if not isinstance(features, list):
            raise ScenarioError(f"{path}: FeatureCollection needs a 'features' array")
        if not features:
            raise ScenarioError(f"{path}: FeatureCollection has no features (expected at least one polygon)")
    elif kind == "Feature":
        features = [doc]
    elif kind in _GEOJSON_POLYGONAL:
        features = [{"type": "Feature", "geometry": doc, "properties": {}}]
    else:
        raise ScenarioError(
            f"{path}: expected GeoJSON type FeatureCollection, Feature, Polygon or MultiPolygon (got {kind!r})"
        )
    zones = []
    for i, feat in enumerate(features):
        where = f"{path}: feature {i}" if len(features) > 1 else f"{path}"
        if not isinstance(feat, dict) or feat.get("type") != "Feature":
            raise ScenarioError(f"{where}: expected a GeoJSON Feature object")
        props = feat.get("properties") or {}
        if not isinstance(props, dict):
            raise ScenarioError(f"{where}: 'properties' must be an object or null")
        geom = _parse_geometry(feat.get("geometry"), where)
        default = path.stem if len(features) == 1 else f"{path.stem}[{i}]"
        name = props.get("name", default)
        if not isinstance(name, str) or not name:
            raise ScenarioError(f"{where}: property 'name' must be a non-empty string (got {name!r})")
        t0 = _parse_time(props.get("valid_from"), where, "valid_from")
        t1 = _parse_time(props.get("valid_to"), where, "valid_to")
        if t0 is not None and t1 is not None and t1 < t0:
            raise ScenarioError(f"{where}: valid_to ({t1}) is before valid_from ({t0})")
        zones.append(Zone(name, geom, t0, t1))
    return zones


def _parse_time(value: Any, where: str, key: str) -> np.datetime64 | None:
    if value is None:
        return None
    if not isinstance(value, str):
        raise ScenarioError(f"{where}: property {key!r} must be an ISO 8601 UTC time string (got {value!r})")
    try:
        t = dt.datetime.fromisoformat(value.strip())
    except ValueError:
        raise ScenarioError(
            f"{where}: property {key!r} must be an ISO 8601 time like 2018-06-01T00:00:00Z (got {value!r})"
        ) from None
    if t.tzinfo is not None:
        try:
            t = t.astimezone(dt.UTC).replace(tzinfo=None)
        except OverflowError:  # e.g. 0001-01-01T00:00:00+05:00 is before year 1 in UTC
            raise ScenarioError(f"{where}: property {key!r} is out of range in UTC (got {brief(value)})") from None
    return np.datetime64(t, "s")


def _parse_ring(raw: Any, where: str) -> FloatArray:
    try:
        xy = np.asarray(raw, dtype=float)
    except (TypeError, ValueError):
        raise ScenarioError(f"{where}: a ring must be an array of [lon, lat] number pairs") from None
    if xy.ndim != 2 or xy.shape[1] < 2:
        raise ScenarioError(f"{where}: a ring must be an array of [lon, lat] number pairs (got shape {xy.shape})")
    xy = xy[:, :2]
    if not np.isfinite(xy).all():
        raise ScenarioError(f"{where}: coordinates must be finite numbers")
    bad = (np.abs(xy[:, 0]) > 180.0) | (np.abs(xy[:, 1]) > 90.0)
    if bad.any():
        lon, lat = xy[np.argmax(bad)]
        raise ScenarioError(
            f"{where}: coordinates must be lon in [-180, 180], lat in [-90, 90] [deg] (got [{lon:g}, {lat:g}])"
        )
    if len(xy) < 3 or (len(xy) == 3 and np.array_equal(xy[0], xy[-1])):
        raise ScenarioError(f"{where}: a ring needs at least 3 distinct positions (got {len(xy)})")
    jump = np.abs(np.diff(np.vstack([xy, xy[:1]])[:, 0])) > 180.0
    if jump.any():  # lon/lat rings are planar (RFC 7946): such an edge runs the long way round, not across the seam
        i = int(np.argmax(jump))
        a, b = xy[i], xy[(i + 1) % len(xy)]
        raise ScenarioError(
            f"{where}: the edge from [{a[0]:g}, {a[1]:g}] to [{b[0]:g}, {b[1]:g}] spans {abs(b[0] - a[0]):g} deg of "
            "longitude; a zone across the antimeridian must be split into polygons on either side of it "
            "(a MultiPolygon, RFC 7946 section 3.1.9)"
        )
    return xy


def _parse_geometry(raw: Any, where: str) -> shapely.Geometry:
    if not isinstance(raw, dict):
        raise ScenarioError(f"{where}: expected a Polygon or MultiPolygon geometry (got {raw!r})")
    kind = raw.get("type")
    if kind not in _GEOJSON_POLYGONAL:
        raise ScenarioError(f"{where}: expected geometry type Polygon or MultiPolygon (got {kind!r})")
    coords = raw.get("coordinates")
    polys_raw = [coords] if kind == "Polygon" else coords
    if not isinstance(polys_raw, list) or not polys_raw:
        raise ScenarioError(f"{where}: {kind} needs a non-empty 'coordinates' array")
    polys = []
    for rings in polys_raw:
        if not isinstance(rings, list) or not rings:
            raise ScenarioError(f"{where}: a polygon must be a non-empty array of rings")
        shell, *holes = (_parse_ring(r, where) for r in rings)
        polys.append(shapely.Polygon(shell, holes))
    geom = polys[0] if kind == "Polygon" else shapely.MultiPolygon(polys)
    if not geom.is_valid:
        raise ScenarioError(f"{where}: {_invalid_polygon(geom)}")
    if geom.is_empty or geom.area <= 0.0:
        raise ScenarioError(f"{where}: polygon has zero area")
    return geom


def _invalid_polygon(geom: shapely.Geometry) -> str:
    """Why a polygon is invalid, with where (shapely's ``is_valid_reason``, e.g. 'Self-intersection[1 1]')."""
    reason = str(shapely.is_valid_reason(geom))
    what, _, at = reason.partition("[")
    xy = at.rstrip("]").split()
    where = f" at lon {float(xy[0]):g}, lat {float(xy[1]):g}" if len(xy) >= 2 else ""
    if what.strip().lower().startswith(("self-intersection", "ring self-intersection")):
        return (
            f"the polygon's edges cross{where} ({reason}): a zone must be a simple ring, not a figure of eight; "
            "reorder its positions, or give the two parts as a MultiPolygon"
        )
    return f"invalid polygon{where} ({reason}): rings must not cross or touch, holes must lie inside the shell"


def zones_outside(zones: Iterable[Zone], lon_deg: npt.ArrayLike, lat_deg: npt.ArrayLike) -> list[Zone]:
    """The zones that lie wholly outside the routing area: the convex hull of the given points (a grid's nodes,
    its start and finish) [deg]. Such a zone cannot change the route, which usually means a mistake: coordinates
    written [lat, lon] instead of GeoJSON's [lon, lat], or the wrong file.

    The hull is taken in lon/lat; a grid across the antimeridian spans nearly all longitudes, so a zone is then
    reported only when it is clear of the grid's latitudes (no false warnings, fewer true ones).

    >>> z = Zone("far", shapely.box(100.0, 10.0, 101.0, 11.0))
    >>> [zone.name for zone in zones_outside([z], [-12.0, -60.0, -30.0], [45.0, 17.5, 40.0])]
    ['far']
    """
    lon = np.asarray(lon_deg, dtype=float).ravel()
    lat = np.asarray(lat_deg, dtype=float).ravel()
    ok = np.isfinite(lon) & np.isfinite(lat)
    hull = shapely.multipoints(np.column_stack([lon[ok], lat[ok]])).convex_hull
    return [zone for zone in zones if not hull.intersects(zone.geometry)]
