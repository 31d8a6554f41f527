"""The Route result: track, per-leg conditions and failure probabilities, and its exports.

Voyage failure probability
--------------------------
Each leg's ``p_f`` is the failure model's probability for the worst conditions met along that leg. The
voyage failure probability is ``1 - prod(1 - p_f_leg)``: it assumes that failures on different legs are
independent events, which overstates the risk when the same weather system is met over many consecutive
legs (the legs are then strongly correlated) and depends on the grid's leg length. Treat it as an
indicator for comparing routes on the same grid, not as a calibrated probability; the maximum leg
``p_f`` (which the ``apf`` constraint bounds) does not depend on the grid.
"""

from __future__ import annotations

import csv
import functools
import io
import json
import os
import tempfile
from collections.abc import Callable
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from . import geodesy
from .cost import _to_datetime, arc_quantities

if TYPE_CHECKING:
    from .grid import Grid
    from .solve import DPResult, RoutingProblem
    from .weather import Conditions

__all__ = ["Route", "build_route", "join_routes", "atomic_write", "check_out_dir", "write_outputs", "write_together",
           "OUTPUT_FILES"]

FloatArray = npt.NDArray[np.float64]

#: Files written by :func:`write_outputs`.
OUTPUT_FILES = ("route.geojson", "route.gpx", "route.csv", "summary.json", "route.png")

LEG_FIELDS = (
    "wait_h", "distance_nm", "time_h", "sog_kn", "course_deg", "tws_kn", "twd_deg", "twa_deg",
    "hs_m", "wave_dir_deg", "awd_deg", "p_f",
)


@dataclass(frozen=True, eq=False)
class Route:
    """A routed voyage.

    Attributes
    ----------
    lon_deg, lat_deg : Track points [deg]: start, one node per rank, finish.
    elapsed_h : Time at each track point since departure [h].
    departure : Departure time (UTC).
    legs : Per-leg arrays (one fewer than points): ``distance_nm`` [nm], ``time_h`` [h], ``sog_kn`` mean speed
        over ground [kn], ``course_deg`` [deg], and at the leg's midpoint and mid-time ``tws_kn``, ``twd_deg``,
        ``twa_deg``, ``hs_m``, ``wave_dir_deg``, ``awd_deg`` (where the data have a hole at the midpoint that the
        leg's cost samples straddle, at the sample nearest it); ``p_f`` the leg's largest failure probability.
    nodes : Node index on each rank.
    grid : The grid routed on.
    dp : The raw DP result.
    meta : Scenario details for reports (polar, failure model, apf, ...).
    """

    lon_deg: FloatArray
    lat_deg: FloatArray
    elapsed_h: FloatArray
    departure: np.datetime64
    legs: dict[str, FloatArray]
    nodes: npt.NDArray[np.intp]
    grid: Grid
    dp: DPResult
    meta: dict[str, Any] = field(default_factory=dict)

    @property
    def voyage_time_h(self) -> float:
        """Voyage time [h]."""
        return float(self.elapsed_h[-1])

    @property
    def distance_nm(self) -> float:
        """Sailed great-circle distance along the track [nm]."""
        return float(self.legs["distance_nm"].sum())

    @property
    def time(self) -> npt.NDArray[np.datetime64]:
        """UTC time at each track point."""
        start = np.asarray(self.departure).astype("datetime64[s]")
        return start + np.round(self.elapsed_h * 3600.0).astype("timedelta64[s]")

    @property
    def arrival(self) -> np.datetime64:
        """Arrival time (UTC)."""
        return self.time[-1]

    @property
    def max_failure_probability(self) -> float:
        """Largest leg failure probability."""
        return float(np.max(self.legs["p_f"]))

    @property
    def voyage_failure_probability(self) -> float:
        """``1 - prod(1 - p_f)`` over legs (legs assumed independent; see the module notes)."""
        return float(1.0 - np.prod(1.0 - self.legs["p_f"]))

    @property
    def touches_edge(self) -> bool:
        """True when the track uses an outermost node of a rank (the grid may be too narrow)."""
        n = self.grid.n_nodes
        return n > 2 and bool(np.any((self.nodes == 0) | (self.nodes == n - 1)))

    def _legs_grids(self) -> dict[str, Any]:
        """For a course through waypoints: the ranks of all legs and each leg's grid (the other keys are the first
        leg's)."""
        grids = self.meta.get("grids_object")
        if not grids:
            return {}
        return {"n_ranks": sum(g.n_ranks for g in grids), "legs": [g.describe() for g in grids]}

    def summary(self) -> dict[str, Any]:
        """The JSON contract of ``pyroute-rel route --json`` (see the README)."""
        times = self.time
        p_point = np.concatenate([[0.0], self.legs["p_f"]])
        return {
            "voyage_time_h": self.voyage_time_h,
            "distance_nm": self.distance_nm,
            "departure": _iso(times[0]),
            "arrival": _iso(times[-1]),
            "grid": {
                "n_ranks": self.grid.n_ranks,
                "n_nodes": self.grid.n_nodes,
                "spacing_km": self.grid.spacing_km,
                "rank_spacing_km": self.grid.rank_spacing_km,
                "max_deviation_deg": self.grid.max_deviation_deg,
                "aspect": self.grid.aspect,
                "half_width_km": self.grid.half_width_km,
                "band": self.grid.band,
                "touches_edge": self.touches_edge,
                **self._legs_grids(),
            },
            "arcs": {
                "evaluated": self.dp.arcs_evaluated,
                "pruned": self.dp.arcs_pruned,
                "forbidden": self.dp.arcs_forbidden,
                "forbidden_by_reason": self.dp.forbidden_by_reason,
                "forbidden_by_criterion": self.dp.forbidden_by_criterion,
            },
            "max_failure_probability": self.max_failure_probability,
            "voyage_failure_probability": self.voyage_failure_probability,
            **{k: v for k, v in self.meta.items() if not k.endswith("_object")},
            "track": [
                {"lon": float(lo), "lat": float(la), "time": _iso(t), "p_f": float(p)}
                for lo, la, t, p in zip(self.lon_deg, self.lat_deg, times, p_point, strict=True)
            ],
        }

    # ---- exports -------------------------------------------------------------------------------------------
    def to_geojson(self) -> dict[str, Any]:
        """GeoJSON FeatureCollection: the track as a LineString plus one Point per track point."""
        times = self.time
        parts = _split_at_antimeridian(self.lon_deg, self.lat_deg)
        geometry = ({"type": "LineString", "coordinates": parts[0]} if len(parts) == 1
                    else {"type": "MultiLineString", "coordinates": parts})
        line = {
            "type": "Feature",
            "geometry": geometry,
            "properties": {
                "name": "route",
                "voyage_time_h": self.voyage_time_h,
                "distance_nm": self.distance_nm,
                "departure": _iso(times[0]),
                "arrival": _iso(times[-1]),
                "max_failure_probability": self.max_failure_probability,
                "voyage_failure_probability": self.voyage_failure_probability,
            },
        }
        points = []
        for i in range(len(self.lon_deg)):
            props: dict[str, Any] = {"index": i, "time": _iso(times[i]), "elapsed_h": float(self.elapsed_h[i])}
            if i < len(self.lon_deg) - 1:
                props.update({f"leg_{k}": _num(v[i]) for k, v in self.legs.items()})
            points.append({
                "type": "Feature",
                "geometry": {"type": "Point", "coordinates": [float(self.lon_deg[i]), float(self.lat_deg[i])]},
                "properties": props,
            })
        return {"type": "FeatureCollection", "features": [line, *points]}

    def to_gpx(self) -> str:
        """GPX 1.1 document with the route as a track (opens in OpenCPN and most chart plotters)."""
        times = self.time
        out = io.StringIO()
        out.write('<?xml version="1.0" encoding="UTF-8"?>\n')
        out.write('<gpx version="1.1" creator="pyroute_rel" xmlns="http://www.topografix.com/GPX/1/1">\n')
        out.write("  <trk>\n    <name>pyroute_rel route</name>\n    <trkseg>\n")
        for lo, la, t in zip(self.lon_deg, self.lat_deg, times, strict=True):
            out.write(f'      <trkpt lat="{la:.6f}" lon="{lo:.6f}"><time>{_iso(t)}</time></trkpt>\n')
        out.write("    </trkseg>\n  </trk>\n</gpx>\n")
        return out.getvalue()

    def to_csv(self) -> str:
        """CSV, one row per track point; leg columns describe the leg that starts at the point."""
        times = self.time
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(["index", "lon_deg", "lat_deg", "time_utc", "elapsed_h", *(f"leg_{k}" for k in LEG_FIELDS)])
        for i in range(len(self.lon_deg)):
            legs = [_fmt(self.legs[k][i]) if i < len(self.lon_deg) - 1 else "" for k in LEG_FIELDS]
            w.writerow([i, f"{self.lon_deg[i]:.6f}", f"{self.lat_deg[i]:.6f}", _iso(times[i]),
                        f"{self.elapsed_h[i]:.6f}", *legs])
        return buf.getvalue()


def _sample(problem: RoutingProblem, lon: FloatArray, lat: FloatArray, t_h: FloatArray) -> Conditions:
    """The problem's weather at points and times [h after departure] (at the departure when it is steady)."""
    if getattr(problem.weather, "steady", False):
        return problem.weather.sample(lon, lat, problem.departure)
    return problem.weather.sample(lon, lat, _to_datetime(problem.departure, np.asarray(t_h, dtype=float)))


def _put(values: FloatArray, i: npt.NDArray[np.intp], new: FloatArray) -> FloatArray:
    out = np.array(values, dtype=float)  # a copy
    out[i] = new
    return out


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
            frac = float(geodesy.crossing_fraction(a, float(lat[i - 1]), b, float(lat[i]), 180.0, -89.999, 180.0,
                                                   89.999))
            frac = frac if np.isfinite(frac) else 0.5
            _, x_lat = geodesy.intermediate_point(a, float(lat[i - 1]), b, float(lat[i]), frac)
            side = 180.0 if a > 0 else -180.0
            parts[-1].append([side, float(x_lat)])
            parts.append([[-side, float(x_lat)]])
        parts[-1].append([b, float(lat[i])])
    return parts


def build_route(grid: Grid, problem: RoutingProblem, result: DPResult) -> Route:
    """Turn a DP result into a Route, recomputing every leg from its end points."""
    from .solve import leg_costs

    nodes = result.path()
    waits = result.waits()
    lon, lat = result.points(grid)
    elapsed, costs = leg_costs(problem, lon, lat, waits)
    dist = geodesy.distance_nm(lon[:-1], lat[:-1], lon[1:], lat[1:])
    mlon, mlat = geodesy.intermediate_point(lon[:-1], lat[:-1], lon[1:], lat[1:], 0.5)
    course = geodesy.initial_bearing_deg(mlon, mlat, lon[1:], lat[1:])
    mid_h = elapsed[:-1] + waits + 0.5 * costs.time_h
    cond = _sample(problem, mlon, mlat, mid_h)
    hole = ~(np.isfinite(cond.tws_kn) & np.isfinite(cond.twd_deg)) & np.isfinite(costs.time_h)
    if hole.any() and problem.samples > 1:
        # a sailable leg whose midpoint falls in a hole of the data (a NaN cell its samples straddle): report the
        # conditions at its cost sample nearest the midpoint instead, which the cost found valid
        frac = (problem.samples // 2 - 0.5) / problem.samples
        i = np.flatnonzero(hole)
        slon, slat = geodesy.intermediate_point(lon[i], lat[i], lon[i + 1], lat[i + 1], frac)
        at = _sample(problem, slon, slat, (elapsed[:-1] + waits)[i] + frac * costs.time_h[i])
        cond = replace(cond, **{f.name: _put(getattr(cond, f.name), i, getattr(at, f.name)) for f in fields(cond)})
        course = course.copy()
        course[i] = geodesy.initial_bearing_deg(slon, slat, lon[i + 1], lat[i + 1])
    q = arc_quantities(cond, course)
    legs = {
        "distance_nm": dist,
        "time_h": costs.time_h,
        "sog_kn": dist / costs.time_h,  # while sailing (waits excluded)
        "course_deg": course,
        "tws_kn": np.asarray(cond.tws_kn, dtype=float),
        "twd_deg": np.asarray(cond.twd_deg, dtype=float),
        "twa_deg": q["twa_deg"],
        "hs_m": np.asarray(cond.hs_m, dtype=float),
        "wave_dir_deg": np.asarray(cond.wave_dir_deg, dtype=float),
        "awd_deg": q["awd_deg"],
        "p_f": np.asarray(costs.p_f, dtype=float),
        "wait_h": waits,
    }
    meta: dict[str, Any] = {
        "apf": float(problem.apf),
        "failure_model": None if problem.failure is None else problem.failure.name,
        "polar": problem.polar.name,
        "samples_per_arc": problem.samples,
        "weather_object": problem.weather,
        "failure_object": problem.failure,
    }
    return Route(
        lon_deg=lon, lat_deg=lat, elapsed_h=elapsed, departure=np.datetime64(problem.departure).astype("datetime64[s]"),  # type: ignore[arg-type]
        legs=legs, nodes=nodes, grid=grid, dp=result, meta=meta,
    )


def join_routes(routes: list[Route]) -> Route:
    """One Route from legs sailed one after the other (each starting where and when the previous ended)."""
    from dataclasses import replace as _replace

    first = routes[0]
    lon = _chain([r.lon_deg for r in routes])
    lat = _chain([r.lat_deg for r in routes])
    offsets = [0.0]
    for r in routes[:-1]:
        offsets.append(offsets[-1] + r.voyage_time_h)
    elapsed = np.concatenate([first.elapsed_h, *(o + r.elapsed_h[1:] for o, r in zip(offsets[1:], routes[1:],
                                                                                      strict=True))])
    legs = {k: np.concatenate([r.legs[k] for r in routes]) for k in first.legs}
    dp = _replace(first.dp, arcs_evaluated=sum(r.dp.arcs_evaluated for r in routes),
                  arcs_pruned=sum(r.dp.arcs_pruned for r in routes),
                  arcs_forbidden=sum(r.dp.arcs_forbidden for r in routes),
                  forbidden_by_reason={k: sum(r.dp.forbidden_by_reason[k] for r in routes)
                                       for k in first.dp.forbidden_by_reason},
                  forbidden_by_criterion={k: sum(r.dp.forbidden_by_criterion.get(k, 0) for r in routes)
                                          for r0 in routes for k in r0.dp.forbidden_by_criterion})
    meta = dict(first.meta)
    meta.update(_joined_refinement(routes))
    meta["legs_of_course"] = len(routes)
    meta["grids_object"] = [r.grid for r in routes]
    return Route(lon_deg=lon, lat_deg=lat, elapsed_h=elapsed, departure=first.departure, legs=legs,
                 nodes=np.concatenate([r.nodes for r in routes]), grid=first.grid, dp=dp, meta=meta)


def _chain(tracks: list[FloatArray]) -> FloatArray:
    """Legs' point arrays joined into one track: each leg after the first starts where the previous one ended."""
    return np.concatenate([tracks[0], *(t[1:] for t in tracks[1:])])


def _joined_refinement(routes: list[Route]) -> dict[str, Any]:
    """``meta["refine"]`` and the grid track of a course whose legs were refined (:mod:`pyroute_rel.refine`): level
    i's voyage time sums every leg's time after its level i (a leg that stopped earlier counts its best), its arcs
    the arcs the legs costed at that level, its half-width and spacing are the widest legs'."""
    infos = [r.meta.get("refine") for r in routes]
    if not any(infos):
        return {}
    n = max(len(i["levels"]) for i in infos if i)
    levels = []
    for k in range(n):
        at = [i["levels"][min(k, len(i["levels"]) - 1)] if i and i["levels"] else None for i in infos]
        levels.append({
            "half_width_km": max(lv["half_width_km"] for lv in at if lv),
            "spacing_km": max(lv["spacing_km"] for lv in at if lv),
            "voyage_time_h": sum(lv["voyage_time_h"] if lv else r.voyage_time_h for lv, r in zip(at, routes,
                                                                                                  strict=True)),
            "arcs_evaluated": sum(i["levels"][k]["arcs_evaluated"] for i in infos if i and k < len(i["levels"])),
        })
    tracks = [r.meta.get("grid_track_object") or (r.lon_deg, r.lat_deg, r.voyage_time_h) for r in routes]
    lon = _chain([t[0] for t in tracks])
    lat = _chain([t[1] for t in tracks])
    grid_h = sum(i["grid_voyage_time_h"] if i else r.voyage_time_h for i, r in zip(infos, routes, strict=True))
    return {"refine": {"levels": levels, "grid_voyage_time_h": grid_h}, "grid_track_object": (lon, lat, grid_h)}


def _iso(t: np.datetime64) -> str:
    return str(np.datetime_as_string(np.asarray(t).astype("datetime64[s]"), unit="s")) + "Z"


def _num(x: Any) -> float | None:
    v = float(x)
    return v if np.isfinite(v) else None


def _fmt(x: Any) -> str:
    v = float(x)
    return f"{v:.6g}" if np.isfinite(v) else ""


@functools.lru_cache(maxsize=1)
def _file_mode() -> int:
    """The mode a new file gets from ``open`` under this process's umask (0o644 for the usual 022)."""
    mask = os.umask(0)
    os.umask(mask)
    return 0o666 & ~mask


def check_out_dir(path: str | os.PathLike[str], *, option: str = "--out") -> Path:
    """Refuse, before any work, an output folder that cannot be written: a file, a folder under a file, or a place
    without write permission (:class:`~pyroute_rel.errors.OutputError`, naming ``option``). Creates nothing."""
    from .errors import OutputError, show

    out = Path(path)
    if str(path).strip() == "":
        raise OutputError(f"{option} needs a folder name (got an empty string)")
    if out.exists() and not out.is_dir():
        raise OutputError(f"{option} {show(out)} is a file, not a folder")
    here = out
    while not here.exists() and here != here.parent:
        here = here.parent
    if not here.is_dir():
        raise OutputError(f"{option} {show(out)}: {show(here)} is a file, not a folder")
    if not os.access(here, os.W_OK | os.X_OK):
        raise OutputError(f"{option} {show(out)}: no permission to write in {show(here)}")
    return out


def atomic_write(path: str | os.PathLike[str], writer: Callable[[Path], object]) -> None:
    """Write a file atomically: ``writer`` writes a temporary file in the same folder, then it is renamed.

    A failure inside ``writer`` leaves neither a partial file nor the temporary file behind. The file gets the
    usual mode of a new file (0o644 under umask 022), not the temporary file's private 0o600.
    """
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    try:
        writer(Path(tmp))
        os.chmod(tmp, _file_mode())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _write_text(path: Path, text: str) -> None:
    atomic_write(path, lambda p: p.write_text(text, encoding="utf-8"))


def write_together(out_dir: str | os.PathLike[str], writers: dict[str, Callable[[Path], object]], *,
                   option: str = "output folder") -> list[Path]:
    """Write a set of files into a folder, all or none: ``writers[name](path)`` renders each into a temporary folder
    inside ``out_dir``, and the files are moved into place only when every one succeeded (with the usual mode of a
    new file). A failure leaves no partial or stale file, nor the folder when this call created it; an error writing
    is an :class:`~pyroute_rel.errors.OutputError` naming ``option``. Returns the paths written."""
    from .errors import OutputError, show

    out = check_out_dir(out_dir, option=option)
    for name in writers:
        if not name or Path(name).name != name or name in (".", ".."):
            raise OutputError(f"{option}: file names must be plain names inside the folder (got {name!r})")
    created = not out.exists()
    try:
        out.mkdir(parents=True, exist_ok=True)
        staging = Path(tempfile.mkdtemp(prefix=".pyroute-rel-", dir=out))
    except OSError as exc:
        raise OutputError(f"{option} {show(out)}: {exc.strerror or exc}") from None
    try:
        for name, writer in writers.items():
            writer(staging / name)
            os.chmod(staging / name, _file_mode())
        written = []
        for name in writers:
            os.replace(staging / name, out / name)
            written.append(out / name)
        return written
    except OSError as exc:
        raise OutputError(f"{option} {show(out)}: cannot write ({exc.strerror or exc})") from None
    finally:
        for p in staging.glob("*"):
            p.unlink(missing_ok=True)
        staging.rmdir()
        if created and not any(out.iterdir()):
            out.rmdir()


def write_outputs(route: Route, out_dir: str | os.PathLike[str], *, plot: bool = True,
                  extra: dict[str, Any] | None = None) -> list[Path]:
    """Write ``route.geojson``, ``route.gpx``, ``route.csv``, ``summary.json`` and ``route.png`` to a folder, all or
    none (:func:`write_together`)."""
    summary = route.summary()
    if extra:
        summary.update(extra)
    writers: dict[str, Callable[[Path], object]] = {
        "route.geojson": lambda p: p.write_text(json.dumps(route.to_geojson(), indent=1), encoding="utf-8"),
        "route.gpx": lambda p: p.write_text(route.to_gpx(), encoding="utf-8"),
        "route.csv": lambda p: p.write_text(route.to_csv(), encoding="utf-8"),
        "summary.json": lambda p: p.write_text(json.dumps(summary, indent=1), encoding="utf-8"),
    }
    if plot:
        from .plot import plot_route

        writers["route.png"] = lambda p: plot_route(route, path=p)
    written = write_together(out_dir, writers)
    for name in set(OUTPUT_FILES) - set(writers):  # e.g. a route.png from an earlier run with a plot: stale now
        (Path(out_dir) / name).unlink(missing_ok=True)
    return written
