"""Maps of routes (matplotlib, imported lazily; the Agg backend when saving to a file).

The failure shading shows where the failure model's criteria fire for a craft sailing the local great-circle
course towards the finish (criteria such as the apparent wave direction depend on the heading, so the
shading is indicative: the router evaluates every arc with its own heading).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from . import geodesy
from .obstacles.zones import Zone
from .risk import continuous_lon_deg, failure_field
from .weather import UniformWeather

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from .failure import FailureModel
    from .grid import Grid
    from .route import Route
    from .weather import WeatherSource

__all__ = ["plot_route", "plot_routes", "failure_field"]

_COLOURS = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown")


def _pyplot() -> Any:
    import matplotlib

    if not os.environ.get("MPLBACKEND"):
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _unwrap(ref_deg: float) -> Any:
    """Longitudes [deg] -> continuous around ``ref_deg`` (:func:`~pyroute_rel.risk.continuous_lon_deg`)."""

    def view(lon: Any) -> Any:
        return continuous_lon_deg(lon, ref_deg)

    return view


def _draw_grid_outline(ax: Axes, grid: Grid) -> None:
    view = _unwrap(grid.start[0])
    edge_lon = np.concatenate([grid.lon_deg[:, 0], grid.lon_deg[::-1, -1], grid.lon_deg[:1, 0]])
    edge_lat = np.concatenate([grid.lat_deg[:, 0], grid.lat_deg[::-1, -1], grid.lat_deg[:1, 0]])
    ax.plot(view(edge_lon), edge_lat, color="0.6", lw=0.8, ls="--", label="grid extent")
    gc_lon, gc_lat = geodesy.intermediate_point(*grid.start, *grid.finish, np.linspace(0, 1, 100))
    ax.plot(view(gc_lon), gc_lat, color="0.4", lw=0.8, ls=":", label="great circle")


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


def _draw_coast(ax: Axes, grid: Grid) -> None:
    try:
        from .obstacles.land import land_geometry
    except ImportError:
        return
    import shapely

    lon = _unwrap(grid.start[0])(grid.lon_deg)
    west, east = float(lon.min()) - 2, float(lon.max()) + 2
    south, north = max(float(grid.lat_deg.min()) - 2, -90.0), min(float(grid.lat_deg.max()) + 2, 90.0)
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
        _fill_polygons(ax, land, facecolor="0.85", edgecolor="0.5", linewidth=0.4, zorder=0)


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


def _draw_failure(ax: Axes, fig: Figure, grid: Grid, weather: WeatherSource, failure: FailureModel) -> None:
    """Shade where the failure model's criteria fire (count of fired criteria, course heading)."""
    glon, glat, _, fired = failure_field(grid, weather, failure)
    levels = np.arange(0.5, max(int(np.nanmax(fired)), 1) + 1.5)
    if np.nanmax(fired) > 0:
        cs = ax.contourf(glon, glat, fired, levels=levels, cmap="Reds", alpha=0.45)
        cb = fig.colorbar(cs, ax=ax, shrink=0.7, ticks=np.arange(1, levels.size))
        cb.set_label(f"criteria of '{failure.name}' fired (course heading)")


def _draw_zones(ax: Axes, zones: Sequence[Any], view: Any) -> None:
    import shapely

    for zone in zones:
        shape = shapely.transform(
            zone.geometry if isinstance(zone, Zone) else zone,
            lambda xy: np.column_stack([view(xy[:, 0]), xy[:, 1]]),
        )
        _fill_polygons(ax, shape, facecolor="tab:purple", alpha=0.25, linewidth=0.8, edgecolor="tab:purple")


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
                label=f"{label} on the grid, before refinement: {before.voyage_time_h:.1f} h",
            )
        ax.plot(
            view(route.lon_deg),
            route.lat_deg,
            color=_COLOURS[i % len(_COLOURS)],
            lw=1.6,
            label=f"{label}{' (refined)' if before is not None else ''}: {route.voyage_time_h:.1f} h",
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


def _draw_marks(ax: Axes, routes: Sequence[Route], grid: Grid, view: Any) -> None:
    """Start and finish lines and points."""
    if grid.start_lon is not None and grid.start_lat is not None:
        ax.plot(view(grid.start_lon), grid.start_lat, "k-", lw=2.5, label="start line")
    if grid.finish_line is not None:
        (c_lon, c_lat), (d_lon, d_lat) = grid.finish_line
        f_lon, f_lat = geodesy.intermediate_point(c_lon, c_lat, d_lon, d_lat, np.linspace(0.0, 1.0, 50))
        ax.plot(view(f_lon), f_lat, "k-", lw=2.5, label="finish line")
    ax.plot(view(routes[0].lon_deg[0]), routes[0].lat_deg[0], "k^", ms=7, label="start")
    ax.plot(view(routes[0].lon_deg[-1]), routes[0].lat_deg[-1], "ks", ms=7, label="finish")


def _frame(ax: Axes, routes: Sequence[Route], grid: Grid, weather: WeatherSource | None, view: Any) -> None:
    """Axes labels, and limits framing the routes, patches and lines (the grid outline may extend beyond: it is
    clipped)."""
    ax.set_xlabel("longitude [deg]")
    from matplotlib.ticker import FuncFormatter

    ax.xaxis.set_major_formatter(FuncFormatter(lambda x, _: f"{(x + 180.0) % 360.0 - 180.0:g}"))  # -175, not 185
    ax.set_ylabel("latitude [deg]")
    xs = [view(r.lon_deg) for r in routes]
    ys = [np.asarray(r.lat_deg) for r in routes]
    for patch in _patches(weather):
        xs.append(view(np.asarray(patch.lon)))
        ys.append(np.asarray(patch.lat))
    if grid.finish_line is not None:
        xs.append(view(np.array([p[0] for p in grid.finish_line])))
        ys.append(np.array([p[1] for p in grid.finish_line]))
    if grid.start_lon is not None and grid.start_lat is not None:
        xs.append(view(grid.start_lon))
        ys.append(grid.start_lat)
    x_all, y_all = np.concatenate(xs), np.concatenate(ys)
    pad_x = max(3.0, 0.15 * float(np.ptp(x_all)))
    pad_y = max(3.0, 0.15 * float(np.ptp(y_all)))
    ax.set_xlim(float(x_all.min()) - pad_x, float(x_all.max()) + pad_x)
    ax.set_ylim(float(y_all.min()) - pad_y, float(y_all.max()) + pad_y)
    mid_lat = 0.5 * (grid.lat_deg.min() + grid.lat_deg.max())
    ax.set_aspect(1.0 / np.cos(np.radians(mid_lat)))


def plot_routes(
    routes: Sequence[Route],
    *,
    labels: Sequence[str] | None = None,
    weather: WeatherSource | None = None,
    failure: FailureModel | None = None,
    zones: Sequence[Any] = (),
    title: str | None = None,
    path: str | os.PathLike[str] | None = None,
    coast: bool = True,
) -> Figure:
    """Draw one or more routes over the grid extent, the weather patches and the failure-criteria shading.

    Parameters
    ----------
    routes : The routes; the first one's grid gives the extent, start and finish.
    labels : Legend label of each route (default ``route 1``, ``route 2``, ...).
    weather, failure : With both, the failure criteria fired are shaded (:func:`~pyroute_rel.risk.failure_field`);
        a uniform weather's patches are drawn.
    zones : Exclusion zones (:class:`~pyroute_rel.obstacles.zones.Zone` or shapely geometries [deg]).
    title : Figure title (default: the grid's size).
    path : With a path the PNG is written atomically and the figure closed.
    coast : Draw the coastline (GSHHG; skipped when unavailable).
    """
    plt = _pyplot()
    grid = routes[0].grid
    view = _unwrap(grid.start[0])  # continuous longitudes across the antimeridian
    fig, ax = plt.subplots(figsize=(9, 6.5), dpi=110)
    if failure is not None and weather is not None:
        _draw_failure(ax, fig, grid, weather, failure)
    if coast:
        _draw_coast(ax, grid)
    _draw_zones(ax, zones, view)
    _draw_grid_outline(ax, grid)
    if weather is not None:
        _draw_patches(ax, weather, view)
    labels = list(labels) if labels is not None else [f"route {i + 1}" for i in range(len(routes))]
    _draw_tracks(ax, routes, labels, view)
    _draw_manoeuvres(ax, routes, view)
    _draw_marks(ax, routes, grid, view)
    _frame(ax, routes, grid, weather, view)
    ax.grid(True, lw=0.3)
    ax.legend(fontsize=7, loc="best")
    ax.set_title(title or f"{grid.n_ranks} ranks x {grid.n_nodes} nodes")
    fig.tight_layout()
    if path is not None:
        from .files import atomic_write

        out_path = Path(path)
        atomic_write(out_path, lambda tmp: fig.savefig(tmp, format="png"))
        plt.close(fig)
    return fig


def plot_route(route: Route, *, path: str | os.PathLike[str] | None = None, title: str | None = None) -> Figure:
    """Map of one route with its weather's patches, the failure shading and the zones it avoided."""
    t = title or (
        f"{route.voyage_time_h:.1f} h, apf {route.meta.get('apf', 1.0):g}, max p_f {route.max_failure_probability:.2f}"
    )
    return plot_routes(
        [route],
        labels=["route"],
        weather=route.weather,
        failure=route.failure,
        title=t,
        path=path,
        zones=route.zones,
    )
