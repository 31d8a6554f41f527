"""A route's files: GeoJSON, GPX, CSV, the JSON summary, the forbidden arcs and the map, written together (all or
none).

Formats are functions of a :class:`~pyroute_rel.routing.route.Route`; :func:`write_outputs` renders them into a folder
through :func:`pyroute_rel.files.write_together`.
"""

from __future__ import annotations

import csv
import datetime as _dt
import io
import json
import math
import os
import xml.etree.ElementTree as ET
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Any

import gpxpy
import gpxpy.gpx
import numpy as np
import numpy.typing as npt

from pyroute_rel import geodesy
from pyroute_rel.boat.manoeuvre import KIND_NAMES, SIDE_NAMES, TrackManoeuvres
from pyroute_rel.errors import OutputError, brief, check_flag, check_instance
from pyroute_rel.files import check_out_dir, write_together
from pyroute_rel.routing.route import LEG_FIELDS, Route
from pyroute_rel.times import iso_utc
from pyroute_rel.units import KN_PER_MS

__all__ = [
    "OUTPUT_FILES",
    "TURN_THRESHOLD_DEG",
    "to_geojson",
    "forbidden_geojson",
    "to_gpx",
    "to_csv",
    "turning_points",
    "write_outputs",
    "write_no_route",
    "track_writers",
    "write_replacing",
    "finite_or_null",
    "MANOEUVRE_FIELDS",
    "manoeuvre_cells",
]

FloatArray = npt.NDArray[np.float64]

#: Files written by :func:`write_outputs`.
OUTPUT_FILES = ("route.geojson", "route.gpx", "route.csv", "summary.json", "forbidden.geojson", "route.png")

#: Smallest course change [deg] that makes a track point a turning point of the GPX ``<rte>`` (:func:`turning_points`).
TURN_THRESHOLD_DEG = 1.0

_OPENCPN_NS = "http://www.opencpn.org"  # OpenCPN's GPX extensions (read by OpenCPN's route loader)
_GPXTPX_NS = "http://www.garmin.com/xmlschemas/TrackPointExtension/v2"  # Garmin's track point extension v2


def to_geojson(route: Route) -> dict[str, Any]:
    """A route as a GeoJSON FeatureCollection: the track as a LineString plus one Point per track point."""
    times = route.time
    parts = _split_at_antimeridian(route.lon_deg, route.lat_deg)
    geometry = (
        {"type": "LineString", "coordinates": parts[0]}
        if len(parts) == 1
        else {"type": "MultiLineString", "coordinates": parts}
    )
    line = {
        "type": "Feature",
        "geometry": geometry,
        "properties": {
            "name": "route",
            "voyage_time_h": route.voyage_time_h,
            "distance_nm": route.distance_nm,
            "departure": iso_utc(times[0]),
            "arrival": iso_utc(times[-1]) if route.arrived else None,
            "arrived": route.arrived,
            **({} if route.arrived else {"track_end": iso_utc(times[-1])}),
            "max_failure_probability": route.max_failure_probability,
            "voyage_failure_probability": route.voyage_failure_probability,
            "exposure_by_criterion_h": dict(route.exposure_by_criterion_h),
        },
    }
    points = []
    for i in range(len(route.lon_deg)):
        props: dict[str, Any] = {"index": i, "time": iso_utc(times[i]), "elapsed_h": float(route.elapsed_h[i])}
        if i < len(route.lon_deg) - 1:
            props.update({f"leg_{k}": _num(v[i]) for k, v in route.legs.items()})
        points.append(
            {
                "type": "Feature",
                "geometry": {"type": "Point", "coordinates": [float(route.lon_deg[i]), float(route.lat_deg[i])]},
                "properties": props,
            }
        )
    return {"type": "FeatureCollection", "features": [line, *points]}


def forbidden_geojson(route: Route) -> dict[str, Any]:
    """The arcs the route's DP found forbidden (:meth:`~pyroute_rel.routing.route.Route.forbidden_arcs`) as a GeoJSON
    FeatureCollection: one LineString per arc from its source to its destination (a MultiLineString split at the
    antimeridian, like the track), in the table's order.

    Each feature's properties are the table's row: ``leg``, ``rank``, ``src``, ``dst`` (int), ``departure_h`` [h
    after the route's departure], ``departure`` (ISO 8601 UTC), ``p_f`` (null where the weather is missing),
    ``reason`` (e.g. ``"failure"``, ``"failure+obstacle"``) and ``criteria`` (the criteria that fired, joined by
    ``"; "``; ``""`` for other reasons).
    """
    arcs = route.forbidden_arcs()
    features = []
    for i in range(len(arcs)):
        parts = _split_at_antimeridian(
            np.array([arcs.from_lon_deg[i], arcs.to_lon_deg[i]]), np.array([arcs.from_lat_deg[i], arcs.to_lat_deg[i]])
        )
        geometry = (
            {"type": "LineString", "coordinates": parts[0]}
            if len(parts) == 1
            else {"type": "MultiLineString", "coordinates": parts}
        )
        props = {
            "leg": int(arcs.leg[i]),
            "rank": int(arcs.rank[i]),
            "src": int(arcs.src[i]),
            "dst": int(arcs.dst[i]),
            "departure_h": float(arcs.departure_h[i]),
            "departure": iso_utc(arcs.departure[i]),
            "p_f": _num(arcs.p_f[i]),
            "reason": str(arcs.reason[i]),
            "criteria": str(arcs.criteria[i]),
        }
        features.append({"type": "Feature", "geometry": geometry, "properties": props})
    return {"type": "FeatureCollection", "features": features}


def _feature_lines(collection: dict[str, Any]) -> str:
    """A FeatureCollection as JSON text with one feature per line (compact: there may be many)."""
    head = json.dumps({k: v for k, v in collection.items() if k != "features"})[:-1]
    body = ",\n".join(json.dumps(f, separators=(",", ":")) for f in collection["features"])
    return f'{head}, "features": [\n{body}\n]}}\n'


def turning_points(route: Route, *, threshold_deg: float = TURN_THRESHOLD_DEG) -> npt.NDArray[np.intp]:
    """Indices of a route's turning points: the start, every track point where the course changes by more than
    ``threshold_deg``, every point where the route waits, and the finish.

    The course change at point ``i`` is measured from the last turning point ``k`` kept before it: the angle between
    the great-circle course arriving at ``i`` straight from ``k`` and the track's course leaving ``i``. Against the
    previous point alone, a track that bends by less than the threshold at every point would never turn; measured
    from ``k``, the bends add up until they pass it, so the straight legs between turning points stay close to the
    track. On a straight great circle no point turns.

    Parameters
    ----------
    route : The route.
    threshold_deg : Smallest course change kept [deg] (default :data:`TURN_THRESHOLD_DEG`, 1 deg).

    Returns
    -------
    Track point indices, increasing, first 0 and last ``len(route.lon_deg) - 1``.
    """
    lon, lat = route.lon_deg, route.lat_deg
    waits = route.legs.get("wait_h")
    keep = [0]
    for i in range(1, len(lon) - 1):
        k = keep[-1]
        if waits is not None and waits[i] > 0.0:
            keep.append(i)
            continue
        if (lon[i] == lon[k] and lat[i] == lat[k]) or (lon[i] == lon[i + 1] and lat[i] == lat[i + 1]):
            continue  # a repeated point has no course
        arriving = (geodesy.initial_bearing_deg(lon[i], lat[i], lon[k], lat[k]) + 180.0) % 360.0
        leaving = geodesy.initial_bearing_deg(lon[i], lat[i], lon[i + 1], lat[i + 1])
        if geodesy.angle_diff_deg(arriving, leaving) > threshold_deg:
            keep.append(i)
    keep.append(len(lon) - 1)
    return np.asarray(keep, dtype=np.intp)


def to_gpx(route: Route, *, threshold_deg: float = TURN_THRESHOLD_DEG) -> str:
    """A GPX 1.1 document (written with :mod:`gpxpy`): the route's track and a route of its turning points.

    - ``<trk>``: every track point with its UTC ``<time>`` (arrival) and, for every point but the finish, the speed
      over ground of the leg sailed from it [m/s] as ``<gpxtpx:speed>`` in a Garmin TrackPointExtension v2
      (GPX 1.1 has no speed in ``<trkpt>``; OpenCPN ignores it, Garmin BaseCamp, GPXSee and gpxpy read it). Where the
      route waits, the point is written twice, as a GPS log records a stay: at its arrival, then at its departure
      (with the speed); :func:`~pyroute_rel.analysis.evaluate.read_track` reads the pair back as the wait.
    - ``<rte>``: the :func:`turning_points` (``threshold_deg``, default 1 deg) with their arrival ``<time>``, as
      OpenCPN reads a voyage plan: each point after the start carries the mean speed over ground of the route leg
      that ends at it [kn] (along the track, waits excluded), and each point before the finish its departure time
      (after any wait), in ``<opencpn:rte_properties planned_speed="..." etd="..."/>``; the route itself carries
      ``<opencpn:planned_departure>`` and the voyage's mean speed as ``<opencpn:planned_speed>`` [kn].

    Opens in OpenCPN and most chart plotters.
    """
    gpx = gpxpy.gpx.GPX()
    gpx.creator = "pyroute_rel"
    gpx.nsmap.update({"opencpn": _OPENCPN_NS, "gpxtpx": _GPXTPX_NS})
    times = [_utc(t) for t in route.time]
    sog_ms = np.asarray(route.legs["sog_kn"], dtype=float) / KN_PER_MS
    waits = np.asarray(route.legs["wait_h"], dtype=float)
    segment = gpxpy.gpx.GPXTrackSegment()
    for i, (lo, la) in enumerate(zip(route.lon_deg, route.lat_deg, strict=True)):
        point = gpxpy.gpx.GPXTrackPoint(round(float(la), 6), round(float(lo), 6), time=times[i])
        if i < len(waits) and waits[i] > 0.0:  # the stay: arrival here, departure next
            segment.points.append(point)
            leave = route.departure + np.round((route.elapsed_h[i] + waits[i]) * 3600.0).astype("timedelta64[s]")
            point = gpxpy.gpx.GPXTrackPoint(round(float(la), 6), round(float(lo), 6), time=_utc(leave))
        if i < len(sog_ms) and np.isfinite(sog_ms[i]):
            ext = ET.Element(f"{{{_GPXTPX_NS}}}TrackPointExtension")
            ET.SubElement(ext, f"{{{_GPXTPX_NS}}}speed").text = f"{sog_ms[i]:.4f}"
            point.extensions.append(ext)
        segment.points.append(point)
    track = gpxpy.gpx.GPXTrack(name="pyroute_rel route")
    track.segments.append(segment)
    gpx.tracks.append(track)
    gpx.routes.append(_gpx_route(route, turning_points(route, threshold_deg=threshold_deg), times))
    return str(gpx.to_xml(version="1.1"))


def _gpx_route(route: Route, turns: npt.NDArray[np.intp], times: list[_dt.datetime]) -> gpxpy.gpx.GPXRoute:
    """The ``<rte>`` of :func:`to_gpx`: turning points with OpenCPN's planned speed [kn] and departure time."""
    dist = np.asarray(route.legs["distance_nm"], dtype=float)
    sail_h = np.asarray(route.legs["time_h"], dtype=float)
    waits = np.asarray(route.legs.get("wait_h", np.zeros_like(dist)), dtype=float)
    rte = gpxpy.gpx.GPXRoute(name="pyroute_rel route")
    rte.extensions.append(_text_element(f"{{{_OPENCPN_NS}}}planned_departure", iso_utc(route.time[0])))
    rte.extensions.append(_text_element(f"{{{_OPENCPN_NS}}}planned_speed", f"{dist.sum() / sail_h.sum():.4f}"))
    last = len(route.lon_deg) - 1
    for j, i in enumerate(turns):
        name = "start" if i == 0 else ("finish" if route.arrived else "end") if i == last else f"T{i}"
        point = gpxpy.gpx.GPXRoutePoint(
            round(float(route.lat_deg[i]), 6), round(float(route.lon_deg[i]), 6), time=times[i], name=name
        )
        props: dict[str, str] = {}
        if j > 0:
            k = turns[j - 1]
            props["planned_speed"] = f"{dist[k:i].sum() / sail_h[k:i].sum():.4f}"
        if i < last:
            leave = route.departure + np.round((route.elapsed_h[i] + waits[i]) * 3600.0).astype("timedelta64[s]")
            props["etd"] = iso_utc(leave)
        point.extensions.append(ET.Element(f"{{{_OPENCPN_NS}}}rte_properties", props))
        rte.points.append(point)
    return rte


def _text_element(tag: str, text: str) -> ET.Element:
    element = ET.Element(tag)
    element.text = text
    return element


def _utc(t: np.datetime64) -> _dt.datetime:
    """A UTC instant as an aware :class:`datetime.datetime` to the second (gpxpy writes it with a ``Z``)."""
    return _dt.datetime.fromisoformat(iso_utc(t).removesuffix("Z")).replace(tzinfo=_dt.UTC)


def to_csv(route: Route) -> str:
    """A route as CSV, one row per track point; leg columns describe the leg that starts at the point."""
    times = route.time
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(
        [
            "index",
            "lon_deg",
            "lat_deg",
            "time_utc",
            "elapsed_h",
            *(f"leg_{k}" for k in LEG_FIELDS),
            *(f"leg_{k}" for k in MANOEUVRE_FIELDS),
        ]
    )
    for i in range(len(route.lon_deg)):
        legs = [_fmt(route.legs[k][i]) if i < len(route.lon_deg) - 1 else "" for k in LEG_FIELDS]
        legs += manoeuvre_cells(route.manoeuvres, i)
        w.writerow(
            [
                i,
                f"{route.lon_deg[i]:.6f}",
                f"{route.lat_deg[i]:.6f}",
                iso_utc(times[i]),
                f"{route.elapsed_h[i]:.6f}",
                *legs,
            ]
        )
    return buf.getvalue()


#: The CSV's manoeuvre columns (:mod:`pyroute_rel.boat.manoeuvre`): the leg's side of the wind (``port``,
#: ``starboard``), the manoeuvre at its start (``tack``, ``gybe`` or empty) and the time it cost [h].
MANOEUVRE_FIELDS = ("side", "manoeuvre", "manoeuvre_h")


def manoeuvre_cells(m: TrackManoeuvres | None, i: int) -> list[str]:
    """The CSV's manoeuvre columns (:data:`MANOEUVRE_FIELDS`) of the leg leaving track point ``i`` (empty after the
    last point, or without manoeuvres)."""
    if m is None or i >= m.side.size:
        return ["", "", ""]
    return [SIDE_NAMES[int(m.side[i])], KIND_NAMES[int(m.kind[i])], _fmt(m.penalty_h[i])]


def _split_at_antimeridian(lon: FloatArray, lat: FloatArray) -> list[list[list[float]]]:
    """A track's [lon, lat] coordinates, in parts split where a leg crosses the antimeridian (RFC 7946 section
    3.1.9), each part ending or starting on +-180 at the leg's great-circle crossing latitude.

    >>> _split_at_antimeridian(np.array([178.0, -178.0]), np.array([0.0, 0.0]))
    [[[178.0, 0.0], [180.0, 0.0]], [[-180.0, 0.0], [-178.0, 0.0]]]
    """
    parts: list[list[list[float]]] = [[[float(lon[0]), float(lat[0])]]]
    for i in range(1, len(lon)):
        a, b = float(lon[i - 1]), float(lon[i])
        if abs(b - a) > 180.0:  # the short way round crosses +-180
            frac = float(
                geodesy.crossing_fraction(a, float(lat[i - 1]), b, float(lat[i]), 180.0, -89.999, 180.0, 89.999)
            )
            frac = frac if np.isfinite(frac) else 0.5
            _, x_lat = geodesy.intermediate_point(a, float(lat[i - 1]), b, float(lat[i]), frac)
            side = 180.0 if a > 0 else -180.0
            parts[-1].append([side, float(x_lat)])
            parts.append([[-side, float(x_lat)]])
        parts[-1].append([b, float(lat[i])])
    return parts


def _num(x: Any) -> float | None:
    v = float(x)
    return v if np.isfinite(v) else None


def _fmt(x: Any) -> str:
    v = float(x)
    return f"{v:.6g}" if np.isfinite(v) else ""


def write_outputs(
    route: Route, out_dir: str | os.PathLike[str], *, plot: bool = True, extra: Mapping[str, Any] | None = None
) -> list[Path]:
    """Write ``route.geojson``, ``route.gpx``, ``route.csv``, ``summary.json``, ``forbidden.geojson``
    (:func:`forbidden_geojson`) and ``route.png`` to a folder, all or none (:func:`write_together`).

    Parameters
    ----------
    route : The route (:meth:`Scenario.route <pyroute_rel.scenario.Scenario.route>`).
    out_dir : The folder (created if needed).
    plot : Whether to draw ``route.png``.
    extra : More entries for ``summary.json``: str keys, JSON values (None, bool, int, finite float, str, lists
        and dicts of them). NaN and infinities are not JSON, so they are refused (give None for a missing value);
        non-finite numbers of the route's own summary are written as ``null``.

    Raises
    ------
    OutputError
        ``route`` is not a Route, ``out_dir`` not a folder name or not writable, ``plot`` not a bool, ``extra`` not
        a mapping of JSON values, or writing failed (then nothing was written).
    """
    check_instance(route, Route, "route", OutputError)
    check_out_dir(out_dir, option="out_dir")
    plot = check_flag(plot, "plot", OutputError)
    summary = finite_or_null(route.summary())
    if extra is not None:
        check_instance(extra, Mapping, "extra", OutputError, expected="a dict of JSON values")
        for key, value in extra.items():
            if not isinstance(key, str):
                raise OutputError(f"extra: keys must be str (got {brief(key)}, a {type(key).__name__})")
            summary[key] = _json_value(value, f"extra[{brief(key)}]")
    text = json.dumps(summary, indent=1, allow_nan=False)
    writers = track_writers(route, plot=plot)
    writers["summary.json"] = lambda p: p.write_text(text, encoding="utf-8")
    writers["forbidden.geojson"] = lambda p: p.write_text(_feature_lines(forbidden_geojson(route)), encoding="utf-8")
    return write_replacing(out_dir, writers, OUTPUT_FILES)


def track_writers(route: Route, *, title: str | None = None, plot: bool = True) -> dict[str, Callable[[Path], object]]:
    """The writers of a track's files for :func:`~pyroute_rel.files.write_together`: ``route.geojson``,
    ``route.gpx``, ``route.csv`` and, with ``plot``, ``route.png`` (:func:`~pyroute_rel.viz.maps.plot_route`, with
    ``title`` or its own)."""
    writers: dict[str, Callable[[Path], object]] = {
        "route.geojson": lambda p: Path(p).write_text(json.dumps(to_geojson(route), indent=1), encoding="utf-8"),
        "route.gpx": lambda p: Path(p).write_text(to_gpx(route), encoding="utf-8"),
        "route.csv": lambda p: Path(p).write_text(to_csv(route), encoding="utf-8"),
    }
    if plot:
        from pyroute_rel.viz.maps import plot_route

        writers["route.png"] = lambda p: plot_route(route, path=p, title=title)
    return writers


def write_replacing(
    out_dir: str | os.PathLike[str],
    writers: Mapping[str, Callable[[Path], object]],
    known: Iterable[str],
    *,
    option: str = "output folder",
) -> list[Path]:
    """Write ``writers`` to the folder, all or none (:func:`~pyroute_rel.files.write_together`), then remove the files
    of ``known`` it did not write: what an earlier run left there (a route.png, forbidden arcs) is stale now."""
    written = write_together(out_dir, dict(writers), option=option)
    for name in set(known) - set(writers):
        (Path(out_dir) / name).unlink(missing_ok=True)
    return written


def write_no_route(scenario: Any, relaxation: Any, summary: Mapping[str, Any], out_dir: str | os.PathLike[str]) -> None:
    """``route --out`` when no route exists: ``summary.json`` (``summary``: the error and the relaxation) and, when
    the DP reached some node, the best partial route (:class:`~pyroute_rel.routing.relax.PartialRoute`) sailed by the
    evaluator as ``route.geojson``, ``route.gpx``, ``route.csv`` and ``route.png`` (its last point named ``end``; the
    map marks the finish and where the track stops). Other files of an earlier run are removed."""
    text = json.dumps(finite_or_null(dict(summary)), indent=1, allow_nan=False)
    writers: dict[str, Callable[[Path], object]] = {"summary.json": lambda p: p.write_text(text, encoding="utf-8")}
    partial = None if relaxation is None else relaxation.partial
    if partial is not None and partial.lon_deg.size > 1:
        from pyroute_rel.analysis.evaluate import evaluate_track, evaluation_route
        from pyroute_rel.routing.relax import apf_text

        grid = scenario.leg_grids()[relaxation.leg]
        points = np.column_stack([partial.lon_deg, partial.lat_deg])
        ev = evaluate_track(scenario, points, departure=partial.departure)
        route = evaluation_route(
            ev, grid, scenario.problem(grid=grid), arrived=False, zones=tuple(scenario.avoid.zones)
        )
        if route is not None:
            title = (
                f"no route: the closest one gets is {partial.distance_to_finish_nm:.0f} nm from the "
                f"{'finish' if relaxation.leg == relaxation.n_legs - 1 else 'next mark'}"
                + (f"; it routes with apf {apf_text(relaxation.apf)}" if relaxation.apf is not None else "")
            )
            writers.update(track_writers(route, title=title))
    write_replacing(out_dir, writers, OUTPUT_FILES)


def _json_value(value: Any, where: str) -> Any:
    """A user's value for ``summary.json`` as plain JSON (numpy scalars and arrays to Python), or OutputError."""
    if value is None or isinstance(value, (bool, str)):
        return value
    if isinstance(value, np.ndarray):
        value = value.tolist()
    elif isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        if not math.isfinite(value):
            raise OutputError(f"{where} is {value}, which is not valid JSON (give None for a missing value)")
        return value
    if isinstance(value, (list, tuple)):
        return [_json_value(v, f"{where}[{i}]") for i, v in enumerate(value)]
    if isinstance(value, Mapping):
        out = {}
        for k, v in value.items():
            if not isinstance(k, str):
                raise OutputError(f"{where}: keys must be str (got {brief(k)}, a {type(k).__name__})")
            out[k] = _json_value(v, f"{where}[{brief(k)}]")
        return out
    if isinstance(value, (bool, str)):  # numpy bools and strings, made Python ones by .item() above
        return value
    raise OutputError(f"{where} cannot be written to JSON (got {brief(value)}, a {type(value).__name__})")


def finite_or_null(value: Any) -> Any:
    """A summary with every non-finite float as None (JSON null): NaN and infinity are not JSON."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: finite_or_null(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [finite_or_null(v) for v in value]
    return value
