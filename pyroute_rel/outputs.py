"""A route's files: GeoJSON, GPX, CSV, the JSON summary and the map, written together (all or none).

Formats are functions of a :class:`~pyroute_rel.route.Route`; :func:`write_outputs` renders them into a folder
through :func:`pyroute_rel.files.write_together`.
"""

from __future__ import annotations

import csv
import io
import json
import os
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from . import geodesy
from .files import write_together
from .route import LEG_FIELDS
from .times import iso_utc

if TYPE_CHECKING:
    from .route import Route

__all__ = ["OUTPUT_FILES", "to_geojson", "to_gpx", "to_csv", "write_outputs"]

FloatArray = npt.NDArray[np.float64]

#: Files written by :func:`write_outputs`.
OUTPUT_FILES = ("route.geojson", "route.gpx", "route.csv", "summary.json", "route.png")


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
            "arrival": iso_utc(times[-1]),
            "max_failure_probability": route.max_failure_probability,
            "voyage_failure_probability": route.voyage_failure_probability,
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


def to_gpx(route: Route) -> str:
    """A GPX 1.1 document with the route as a track (opens in OpenCPN and most chart plotters)."""
    times = route.time
    out = io.StringIO()
    out.write('<?xml version="1.0" encoding="UTF-8"?>\n')
    out.write('<gpx version="1.1" creator="pyroute_rel" xmlns="http://www.topografix.com/GPX/1/1">\n')
    out.write("  <trk>\n    <name>pyroute_rel route</name>\n    <trkseg>\n")
    for lo, la, t in zip(route.lon_deg, route.lat_deg, times, strict=True):
        out.write(f'      <trkpt lat="{la:.6f}" lon="{lo:.6f}"><time>{iso_utc(t)}</time></trkpt>\n')
    out.write("    </trkseg>\n  </trk>\n</gpx>\n")
    return out.getvalue()


def to_csv(route: Route) -> str:
    """A route as CSV, one row per track point; leg columns describe the leg that starts at the point."""
    times = route.time
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["index", "lon_deg", "lat_deg", "time_utc", "elapsed_h", *(f"leg_{k}" for k in LEG_FIELDS)])
    for i in range(len(route.lon_deg)):
        legs = [_fmt(route.legs[k][i]) if i < len(route.lon_deg) - 1 else "" for k in LEG_FIELDS]
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
    route: Route, out_dir: str | os.PathLike[str], *, plot: bool = True, extra: dict[str, Any] | None = None
) -> list[Path]:
    """Write ``route.geojson``, ``route.gpx``, ``route.csv``, ``summary.json`` and ``route.png`` to a folder, all or
    none (:func:`write_together`)."""
    summary = route.summary()
    if extra:
        summary.update(extra)
    writers: dict[str, Callable[[Path], object]] = {
        "route.geojson": lambda p: p.write_text(json.dumps(to_geojson(route), indent=1), encoding="utf-8"),
        "route.gpx": lambda p: p.write_text(to_gpx(route), encoding="utf-8"),
        "route.csv": lambda p: p.write_text(to_csv(route), encoding="utf-8"),
        "summary.json": lambda p: p.write_text(json.dumps(summary, indent=1), encoding="utf-8"),
    }
    if plot:
        from .plot import plot_route

        writers["route.png"] = lambda p: plot_route(route, path=p)
    written = write_together(out_dir, writers)
    for name in set(OUTPUT_FILES) - set(writers):  # e.g. a route.png from an earlier run with a plot: stale now
        (Path(out_dir) / name).unlink(missing_ok=True)
    return written
