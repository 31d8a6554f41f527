"""Maps of routes, drawn with matplotlib's object API on an Agg canvas (pyplot is never imported).

What a route's map shows
------------------------
- **The failure model, in three classes against the route's apf**
  (:func:`~pyroute_rel.reliability.risk.route_risk_field`): forbidden (``p_f > apf``: the router forbids arcs there,
  red), criteria fire but allowed (``p_f <= apf``, yellow), allowed (no criterion fires, unshaded), darker for higher
  p_f; the legend gives the p_f values of each class (:func:`risk_levels`). Over wave-height colours the classes are
  hatched instead. Criteria such as the apparent wave direction depend on the heading, and time-varying weather on the
  time, so each point is evaluated as the route would meet it: with the course the route sails where it passes nearest
  (the heading that holds it in a current) and with the weather at the time it passes there. Along the track this is
  exactly what the router judged; away from it, "what if the route had come here, sailing as it does nearby".
- **The weather**: for weather that varies in space (a file), the significant wave height in colour and the wind
  in barbs (kn; the barb points where the wind comes from), at the same times; for uniform weather its patches,
  named with their values.
- The coast, exclusion zones (named in the legend), each leg's grid extent, the great circle of each leg, the start
  line (green) and the finish line (chequered), the start, the finish and the waypoints.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from pyroute_rel import geodesy
from pyroute_rel.obstacles.zones import Zone
from pyroute_rel.reliability.risk import (
    RISK_CLASSES,
    RiskField,
    continuous_lon_deg,
    failure_field,
    format_probability,
    route_risk_field,
)
from pyroute_rel.weather import UniformWeather

if TYPE_CHECKING:
    from matplotlib.artist import Artist
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from pyroute_rel.routing.grid import Grid
    from pyroute_rel.routing.route import Route
    from pyroute_rel.weather import WeatherSource

__all__ = ["plot_route", "plot_routes", "failure_field", "new_figure", "map_mesh", "risk_levels", "MESH_POINTS"]

_COLOURS = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown")
#: Points of the mesh the failure model and the weather are evaluated on, along the longer side of the map.
MESH_POINTS = 200
#: Wind barbs along the longer side of the map.
_BARBS = 18
_START_STYLE: dict[str, Any] = {"color": "tab:green", "lw": 3.0, "solid_capstyle": "butt"}
_FINISH_STYLE: dict[str, Any] = {"color": "k", "lw": 3.2, "solid_capstyle": "butt"}


def new_figure(figsize: tuple[float, float] = (9.0, 6.5), dpi: float = 110) -> Figure:
    """A figure on its own Agg canvas: no pyplot, no GUI backend, nothing global left open."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize, dpi=dpi)
    FigureCanvasAgg(fig)
    return fig


def _unwrap(ref_deg: float) -> Any:
    """Longitudes [deg] -> continuous around ``ref_deg`` (:func:`~pyroute_rel.reliability.risk.continuous_lon_deg`)."""

    def view(lon: Any) -> Any:
        return continuous_lon_deg(lon, ref_deg)

    return view


def _draw_grid_outlines(ax: Axes, grids: Sequence[Grid], view: Any) -> None:
    """The extent and the great circle of each leg's grid (one legend entry each)."""
    for i, grid in enumerate(grids):
        edge_lon = np.concatenate([grid.lon_deg[:, 0], grid.lon_deg[::-1, -1], grid.lon_deg[:1, 0]])
        edge_lat = np.concatenate([grid.lat_deg[:, 0], grid.lat_deg[::-1, -1], grid.lat_deg[:1, 0]])
        many = len(grids) > 1
        ax.plot(
            view(edge_lon),
            edge_lat,
            color="0.6",
            lw=0.8,
            ls="--",
            gid=f"grid extent {i}",
            label="_" if i else ("grid extent (each leg)" if many else "grid extent"),
        )
        gc_lon, gc_lat = geodesy.intermediate_point(*grid.start, *grid.finish, np.linspace(0, 1, 100))
        ax.plot(
            view(gc_lon),
            gc_lat,
            color="0.4",
            lw=0.8,
            ls=":",
            label="_" if i else ("great circle (each leg)" if many else "great circle"),
        )


def _patches(weather: WeatherSource | None) -> tuple[Any, ...]:
    """The weather's patches (boxes of a uniform weather; none for other sources)."""
    return weather.patches if isinstance(weather, UniformWeather) else ()


def _draw_patches(ax: Axes, weather: WeatherSource | None, view: Any) -> None:
    from matplotlib.patches import Rectangle

    for i, patch in enumerate(_patches(weather)):
        label = patch.name or f"patch {i + 1}"
        if len(label) > 40:
            label = label[:37] + "..."
        desc = ", ".join(f"{k}={v:g}" for k, v in patch.values.items())
        ax.add_patch(
            Rectangle(
                (float(view(patch.lon[0])), patch.lat[0]),
                patch.lon[1] - patch.lon[0],
                patch.lat[1] - patch.lat[0],
                fill=False,
                ec="k",
                lw=1.0,
                label="weather patches (named)" if i == 0 else "_",
            )
        )
        # label each box at a different corner so nested boxes stay readable
        corner = (float(view(patch.lon[0])), patch.lat[1] if i % 2 == 0 else patch.lat[0])
        ax.annotate(
            f"{label}: {desc}",
            corner,
            xytext=(1, 2 if i % 2 == 0 else -2),
            textcoords="offset points",
            va="bottom" if i % 2 == 0 else "top",
            fontsize=6.5,
        )


def _draw_coast(ax: Axes, limits: tuple[float, float, float, float]) -> None:
    try:
        from pyroute_rel.obstacles.land import land_geometry
    except ImportError:
        return
    import shapely

    x0, x1, y0, y1 = limits
    west, east, south, north = x0 - 2, x1 + 2, max(y0 - 2, -90.0), min(y1 + 2, 90.0)
    pieces = []
    for shift in (-360.0, 0.0, 360.0):  # the view may run past +-180: read each side of the seam, shifted
        w, e = max(west + shift, -180.0), min(east + shift, 180.0)
        if e - w < 1e-6:
            continue
        try:
            land = land_geometry((w, south, e, north))
        except Exception:  # the map is still useful without a coastline
            return
        pieces.append(shapely.transform(land, lambda xy, d=shift: xy - (d, 0.0)) if shift else land)
    for land in pieces:
        _fill_polygons(ax, land, facecolor="0.85", edgecolor="0.5", linewidth=0.4, zorder=0.5)


def _fill_polygons(ax: Axes, geometry: Any, **style: Any) -> None:
    """Fill a (Multi)Polygon, holes included, as one matplotlib artist (a coastline has thousands of parts:
    an artist each made a map take seconds to draw and the legend seconds more to place)."""
    import shapely
    from matplotlib.collections import PathCollection
    from matplotlib.path import Path as MplPath

    paths = []
    # exterior counter-clockwise, holes clockwise: holes stay empty under the nonzero fill rule
    for poly in shapely.get_parts(shapely.orient_polygons(geometry)):
        if poly.is_empty or not isinstance(poly, shapely.Polygon):
            continue
        rings = [poly.exterior, *poly.interiors]
        paths.append(MplPath.make_compound_path(*[MplPath(shapely.get_coordinates(r), closed=True) for r in rings]))
    if paths:
        ax.add_collection(PathCollection(paths, **style), autolim=False)


def _p_text(lo: float, hi: float) -> str:
    return f"p_f {format_probability(lo)}" if lo == hi else f"p_f {format_probability(lo)}-{format_probability(hi)}"


def risk_levels(field: RiskField, *, max_shades: int = 4) -> list[tuple[int, int, int, np.ndarray, str]]:
    """The areas a map shades: for each risk class drawn (forbidden, criteria fire but allowed, unknown), the
    distinct p_f values met in it (or ``max_shades`` ranges when there are more), darker for higher p_f.

    Returns
    -------
    ``(class, shade, n_shades, mask, label)`` per area, ``mask`` a boolean array in the field's shape.
    """
    out: list[tuple[int, int, int, np.ndarray, str]] = []
    apf = format_probability(field.apf)
    for cls in (2, 1):
        inside = field.risk_class == cls
        if not inside.any():
            continue
        values = np.unique(field.p_f[inside])
        if values.size <= max_shades:
            bins = [(float(v), float(v)) for v in values]
        else:
            edges = np.linspace(values[0], values[-1], max_shades + 1)
            bins = [(float(edges[i]), float(edges[i + 1])) for i in range(max_shades)]
        for k, (lo, hi) in enumerate(bins):
            if lo == hi:  # one value
                mask = inside & (field.p_f == lo)
            else:
                mask = inside & (field.p_f >= lo) & (field.p_f <= hi if k == len(bins) - 1 else field.p_f < hi)
            if not mask.any():
                continue
            met = field.p_f[mask]
            text = _p_text(float(met.min()), float(met.max()))
            label = f"forbidden: {text} > apf {apf}" if cls == 2 else f"criteria fire, allowed: {text} <= apf {apf}"
            out.append((cls, k, len(bins), mask, label))
    unknown = field.risk_class == -1
    if unknown.any():
        out.append((-1, 0, 1, unknown, RISK_CLASSES[-1]))
    return out


#: Lightest and darkest fill of each class (class 0, allowed, is left unshaded); hatches when the weather is drawn in
#: colour underneath.
_RISK_FILL = {2: ("#f6a5a5", "#b3001b"), 1: ("#fff1a8", "#f2bf00"), -1: ("0.75", "0.75")}
_RISK_HATCH = {2: "x", 1: "/", -1: "."}
_RISK_HATCH_COLOUR = {2: "#b3001b", 1: "#d98200", -1: "0.45"}


def _draw_risk(ax: Axes, field: RiskField, *, hatched: bool) -> list[Artist]:
    """Shade the risk classes of ``field`` (:func:`risk_levels`); returns their legend handles."""
    from matplotlib.colors import to_rgb
    from matplotlib.patches import Patch

    handles: list[Artist] = []
    for cls, k, n, mask, label in risk_levels(field):
        light, dark = (np.array(to_rgb(c)) for c in _RISK_FILL[cls])
        colour = tuple(light + (dark - light) * (k / (n - 1) if n > 1 else 1.0))
        if hatched:  # over the wave heights' colours: strong hatch colours, denser for higher p_f
            strong = _RISK_HATCH_COLOUR[cls]
            hatch = _RISK_HATCH[cls] * (2 + k)
            style: dict[str, Any] = {"colors": ["none"], "hatches": [hatch], "hatchcolor": strong}
            handle = Patch(facecolor="none", edgecolor=strong, hatch=hatch, label=label)
        else:
            style = {"colors": [colour], "alpha": 0.55}
            handle = Patch(facecolor=colour, alpha=0.55, label=label)
        cs = ax.contourf(field.lon_deg, field.lat_deg, mask.astype(float), levels=[0.5, 1.5], zorder=1, **style)
        cs.set_gid(f"risk {cls} {k}")
        if hatched:
            cs.set_hatch_linewidth(0.7)
            handle.set_hatch_linewidth(0.7)
        handles.append(handle)
    return handles


def _draw_weather(ax: Axes, fig: Figure, field: RiskField) -> None:
    """Significant wave height in colour and wind barbs [kn], from the field's conditions."""
    cond = field.conditions
    hs = np.ma.masked_invalid(np.asarray(cond.hs_m, dtype=float))
    if hs.count():
        mesh = ax.pcolormesh(
            field.lon_deg, field.lat_deg, hs, cmap="Blues", vmin=0.0, shading="nearest", alpha=0.75, zorder=0
        )
        mesh.set_gid("hs")
        cb = fig.colorbar(mesh, ax=ax, shrink=0.7, pad=0.02)
        cb.set_label("significant wave height [m] when the route passes nearest")
    ny, nx = field.lon_deg.shape
    step = max(1, round(max(nx, ny) / _BARBS))
    sel = (slice(step // 2, None, step), slice(step // 2, None, step))
    tws = np.asarray(cond.tws_kn, dtype=float)[sel]
    to = np.radians(np.asarray(cond.twd_deg, dtype=float)[sel])
    ok = np.isfinite(tws) & np.isfinite(to)
    # the wind's velocity (blowing to): matplotlib draws the barb's shaft towards where it comes from
    u, v = -tws * np.sin(to), -tws * np.cos(to)
    if not ok.any():
        return
    barbs = ax.barbs(
        field.lon_deg[sel][ok],
        field.lat_deg[sel][ok],
        u[ok],
        v[ok],
        length=5,
        linewidth=0.5,
        color="0.35",
        zorder=2,
    )
    barbs.set_gid("wind")


def _draw_zones(ax: Axes, zones: Sequence[Any], view: Any) -> list[Artist]:
    """Fill the zones; returns a legend handle naming each."""
    import shapely
    from matplotlib.patches import Patch

    handles: list[Artist] = []
    for i, zone in enumerate(zones):
        shape = shapely.transform(
            zone.geometry if isinstance(zone, Zone) else zone,
            lambda xy: np.column_stack([view(xy[:, 0]), xy[:, 1]]),
        )
        _fill_polygons(ax, shape, facecolor="tab:purple", alpha=0.25, linewidth=0.8, edgecolor="tab:purple", zorder=1)
        name = zone.name if isinstance(zone, Zone) and zone.name else f"zone {i + 1}"
        handles.append(
            Patch(facecolor="tab:purple", alpha=0.25, edgecolor="tab:purple", label=f"exclusion zone: {name}")
        )
    return handles


def _draw_tracks(ax: Axes, routes: Sequence[Route], labels: Sequence[str], view: Any) -> None:
    """Each route's track, and for a refined route the grid's own track before refinement (thin, dotted)."""
    for i, (route, label) in enumerate(zip(routes, labels, strict=True)):
        before = route.grid_track
        if before is not None:  # a refined route: the grid's own track, thin, for comparison
            ax.plot(
                view(before.lon_deg),
                before.lat_deg,
                color=_COLOURS[i % len(_COLOURS)],
                lw=0.8,
                ls=":",
                zorder=3,
                label=f"{label} on the grid, before refinement: {before.voyage_time_h:.1f} h",
            )
        ax.plot(
            view(route.lon_deg),
            route.lat_deg,
            color=_COLOURS[i % len(_COLOURS)],
            lw=1.6,
            zorder=3,
            label=f"{label}{' (refined)' if before is not None else ''}: {route.voyage_time_h:.1f} h"
            + ("" if route.arrived else " sailed, does not arrive"),
        )


# --- manoeuvres (issue 21): one marker per tack or gybe, at the start of the leg it puts the craft on --------------
def _draw_manoeuvres(ax: Axes, routes: Sequence[Route], view: Any) -> None:
    """Tacks (open diamonds) and gybes (open circles) along each route's track, counted in the legend."""
    for i, route in enumerate(routes):
        m = route.manoeuvres
        if m is None:
            continue
        for kind, name, marker in ((1, "tacks", "D"), (2, "gybes", "o")):
            at = np.flatnonzero(m.kind == kind)
            if at.size:
                ax.plot(
                    view(route.lon_deg[at]),
                    route.lat_deg[at],
                    ls="none",
                    marker=marker,
                    mfc="none",
                    ms=5,
                    color=_COLOURS[i % len(_COLOURS)],
                    label=f"{name} ({at.size})",
                )


# --- end of manoeuvres -----------------------------------------------------------------------------------------


def _draw_marks(ax: Axes, routes: Sequence[Route], grids: Sequence[Grid], view: Any) -> None:
    """Start and finish lines (distinct styles), the start, the finish and the waypoints."""
    first, last = grids[0], grids[-1]
    if first.start_lon is not None and first.start_lat is not None:
        ax.plot(view(first.start_lon), first.start_lat, zorder=4, gid="start line", label="start line", **_START_STYLE)
    if last.finish_line is not None:
        (c_lon, c_lat), (d_lon, d_lat) = last.finish_line
        f_lon, f_lat = geodesy.intermediate_point(c_lon, c_lat, d_lon, d_lat, np.linspace(0.0, 1.0, 50))
        # a chequered line: black under white dashes
        ax.plot(view(f_lon), f_lat, zorder=4, gid="finish line", label="finish line", **_FINISH_STYLE)
        ax.plot(view(f_lon), f_lat, color="w", lw=1.6, ls=(0, (2, 2)), zorder=4, label="_")
    track = routes[0]
    ax.plot(view(track.lon_deg[0]), track.lat_deg[0], "^", color="tab:green", mec="k", ms=8, zorder=5, label="start")
    if track.arrived:
        ax.plot(view(track.lon_deg[-1]), track.lat_deg[-1], "s", color="k", ms=7, zorder=5, label="finish")
    else:  # the real finish, and where the track stops short of it
        ax.plot(view(last.finish[0]), last.finish[1], "s", color="k", ms=7, zorder=5, gid="finish", label="finish")
        short = last.distance_to_finish_nm(float(track.lon_deg[-1]), float(track.lat_deg[-1]))
        ax.plot(view(track.lon_deg[-1]), track.lat_deg[-1], "X", color="tab:red", mec="k", ms=9, zorder=6,
                gid="track end", label=f"track ends {short:.0f} nm short of the finish")  # fmt: skip
    marks = np.array([g.finish for g in grids[:-1]], dtype=float).reshape(-1, 2)
    if marks.size:
        ax.plot(
            view(marks[:, 0]), marks[:, 1], "D", color="w", mec="k", ms=6, zorder=5, gid="waypoints", label="waypoints"
        )


def _limits(
    routes: Sequence[Route], grids: Sequence[Grid], weather: WeatherSource | None, view: Any
) -> tuple[float, float, float, float]:
    """Map limits ``(west, east, south, north)`` [deg] framing the routes, patches, lines and waypoints."""
    xs = [view(r.lon_deg) for r in routes]
    ys = [np.asarray(r.lat_deg) for r in routes]
    for patch in _patches(weather):
        xs.append(view(np.asarray(patch.lon)))
        ys.append(np.asarray(patch.lat))
    for grid in grids:
        if grid.finish_line is not None:
            xs.append(view(np.array([p[0] for p in grid.finish_line])))
            ys.append(np.array([p[1] for p in grid.finish_line]))
        if grid.start_lon is not None and grid.start_lat is not None:
            xs.append(view(grid.start_lon))
            ys.append(grid.start_lat)
        xs.append(view(np.array([grid.finish[0]])))
        ys.append(np.array([grid.finish[1]]))
    x_all, y_all = np.concatenate(xs), np.concatenate(ys)
    pad_x = max(3.0, 0.15 * float(np.ptp(x_all)))
    pad_y = max(3.0, 0.15 * float(np.ptp(y_all)))
    south, north = max(float(y_all.min()) - pad_y, -89.0), min(float(y_all.max()) + pad_y, 89.0)
    return float(x_all.min()) - pad_x, float(x_all.max()) + pad_x, south, north


def _frame(ax: Axes, limits: tuple[float, float, float, float]) -> None:
    """Axes labels, limits and aspect (the grid outline may extend beyond: it is clipped)."""
    from matplotlib.ticker import FuncFormatter

    ax.set_xlabel("longitude [deg]")
    ax.xaxis.set_major_formatter(FuncFormatter(lambda x, _: f"{(x + 180.0) % 360.0 - 180.0:g}"))  # -175, not 185
    ax.set_ylabel("latitude [deg]")
    x0, x1, y0, y1 = limits
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_aspect(1.0 / np.cos(np.radians(0.5 * (y0 + y1))))


def map_mesh(limits: tuple[float, float, float, float], n: int = MESH_POINTS) -> tuple[np.ndarray, np.ndarray]:
    """A lon/lat mesh [deg] over ``(west, east, south, north)``, ``n`` points along the longer side (on the map,
    with the aspect of the mid latitude)."""
    x0, x1, y0, y1 = limits
    width = (x1 - x0) * np.cos(np.radians(0.5 * (y0 + y1)))
    nx, ny = (
        (n, max(2, round(n * (y1 - y0) / width))) if width >= y1 - y0 else (max(2, round(n * width / (y1 - y0))), n)
    )
    return np.meshgrid(np.linspace(x0, x1, nx), np.linspace(y0, y1, ny))


def plot_routes(
    routes: Sequence[Route],
    *,
    labels: Sequence[str] | None = None,
    weather: WeatherSource | None = None,
    zones: Sequence[Any] = (),
    shade: int | None = 0,
    title: str | None = None,
    path: str | os.PathLike[str] | None = None,
    coast: bool = True,
) -> Figure:
    """Draw routes over the failure model's classes, the weather, the grid extents, lines, zones and the coast.

    Parameters
    ----------
    routes : The routes; the first one's grids give the extents, lines and waypoints.
    labels : Legend label of each route (default ``route 1``, ``route 2``, ...).
    weather : The weather whose patches are drawn (a uniform weather's; default: the shaded route's). When the shaded
        route's own weather varies in space (a file), its wave height and wind are drawn, at the times that route
        passes.
    zones : Exclusion zones (:class:`~pyroute_rel.obstacles.zones.Zone` or shapely geometries [deg]).
    shade : Index of the route whose failure model, apf, headings and times the shading and the weather follow
        (:func:`~pyroute_rel.reliability.risk.route_risk_field`; see the module notes); None draws neither.
    title : Figure title (default: the grid's size).
    path : With a path the PNG is written atomically.
    coast : Draw the coastline (GSHHG; skipped when unavailable).

    Returns
    -------
    matplotlib.figure.Figure
        On its own Agg canvas (:func:`new_figure`): ``fig.savefig`` works, and nothing needs closing.
    """
    from matplotlib.lines import Line2D

    grids = routes[0].grids
    view = _unwrap(grids[0].start[0])  # continuous longitudes across the antimeridian
    shaded = routes[shade] if shade is not None else None
    weather = weather if weather is not None or shaded is None else shaded.weather
    limits = _limits(routes, grids, weather, view)
    fig = new_figure()
    ax = fig.add_subplot()
    handles: list[Artist] = []
    if shaded is not None:
        field = route_risk_field(shaded, *map_mesh(limits))
        varying = not isinstance(shaded.weather, UniformWeather)
        if varying:
            _draw_weather(ax, fig, field)
        if shaded.failure is not None:
            handles += _draw_risk(ax, field, hatched=varying)
    if coast:
        _draw_coast(ax, limits)
    handles += _draw_zones(ax, zones, view)
    _draw_grid_outlines(ax, grids, view)
    if weather is not None:
        _draw_patches(ax, weather, view)
    labels = list(labels) if labels is not None else [f"route {i + 1}" for i in range(len(routes))]
    _draw_tracks(ax, routes, labels, view)
    _draw_manoeuvres(ax, routes, view)
    _draw_marks(ax, routes, grids, view)
    _frame(ax, limits)
    ax.grid(True, lw=0.3)
    lines, names = ax.get_legend_handles_labels()
    keys: list[Artist | tuple[Artist, ...]] = [*lines]
    finish = [ln for ln in ax.get_lines() if ln.get_gid() == "finish line"]
    if finish:  # the legend's finish line chequered like the map's: black under white dashes
        dashes = Line2D([], [], color="w", lw=1.6, ls=(0, (2, 2)))
        keys = [(h, dashes) if n == "finish line" else h for h, n in zip(lines, names, strict=True)]
    # (each handle made with a label: str, where matplotlib's stubs give get_label() as an object)
    ax.legend([*keys, *handles], [*names, *(str(h.get_label()) for h in handles)], fontsize=6.5, loc="best")
    ax.set_title(title or f"{grids[0].n_ranks} ranks x {grids[0].n_nodes} nodes", fontsize=10)
    if shaded is not None:
        fig.text(0.01, 0.01, _caption(shaded, labels[shade or 0]), fontsize=6.5, color="0.3", va="bottom")
    fig.subplots_adjust(left=0.07, right=0.97, bottom=0.1, top=0.95)  # fixed margins: no layout pass (a draw)
    if path is not None:
        from pyroute_rel.files import atomic_write

        atomic_write(Path(path), lambda tmp: fig.savefig(tmp, format="png"))
    return fig


def _caption(route: Route, label: str) -> str:
    """What the shading and the weather drawn are: for which route, heading and time."""
    lines = []
    if route.failure is not None:
        lines.append(
            f"Shading: failure model '{route.failure.name}' against apf {format_probability(route.problem.apf)} of "
            f"{label!r}, for the course it sails where it passes nearest each point, in the weather when it passes."
        )
    if not isinstance(route.weather, UniformWeather):
        lines.append(
            "Wind barbs [kn] point where the wind comes from (half barb 5 kn, barb 10 kn, pennant 50 kn); wave height "
            "and wind at the time the route passes nearest."
        )
    return "\n".join(lines)


def plot_route(route: Route, *, path: str | os.PathLike[str] | None = None, title: str | None = None) -> Figure:
    """Map of one route: the failure model's classes for its headings and times, its weather, the zones it avoided,
    each leg's grid (see the module notes)."""
    t = title or (
        f"{route.voyage_time_h:.1f} h; each leg held to p_f <= apf {format_probability(route.problem.apf)} "
        f"(largest leg p_f {format_probability(route.max_failure_probability)})\n"
        f"voyage p_f {format_probability(route.voyage_failure_probability)}: the chance of at least one failure "
        "over the voyage (reported, not bounded)"
    )
    return plot_routes([route], labels=["route"], title=t, path=path, zones=route.zones)
