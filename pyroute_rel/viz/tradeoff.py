"""The figures of a trade-off (:mod:`pyroute_rel.routing.tradeoff`): the front with the single-apf routes on it, a map
of the front's routes, and a map of the route at the user's apf coloured by the failure criterion that bends each leg.

Drawn on matplotlib's object API (a :class:`~matplotlib.figure.Figure` on an Agg canvas, never pyplot).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from pyroute_rel.reliability.risk import continuous_lon_deg
from pyroute_rel.weather.uniform import UniformWeather

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from pyroute_rel.routing.route import Route
    from pyroute_rel.routing.tradeoff import Front, Sensitivity

__all__ = ["front_figure", "routes_figure", "sensitivity_figure"]

#: What the second objective of each kind of front is called on an axis.
OBJECTIVE = {
    "bottleneck": ("max_failure_probability", "largest leg p_f [-]"),
    "voyage": ("voyage_failure_probability", "voyage failure probability [-]"),
}
_CRITERION_COLOURS = ("tab:red", "tab:purple", "tab:orange", "tab:brown", "tab:pink", "tab:olive")


def _figure(width: float, height: float) -> Figure:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), dpi=110)
    FigureCanvasAgg(fig)
    return fig


def front_figure(
    front: Front, marked: Sequence[tuple[str, float, float, float]] = (), *, title: str | None = None
) -> Figure:
    """The front: voyage time [h] against its second objective, as a staircase (the region it dominates is above
    and right of it), with other routes marked (e.g. the routes at single apf values: ``(label, time [h], value,
    hazard)``). The voyage front has a second panel, the hazard on a log scale: its probabilities crowd near 1.
    """
    key, label = OBJECTIVE[front.kind]
    t = np.array([p.voyage_time_h for p in front.points])
    y = np.array([getattr(p, key) for p in front.points])
    voyage = front.kind == "voyage"
    fig = _figure(8.0, 7.5 if voyage else 5.0)
    axes = [fig.add_subplot(2, 1, 1) if voyage else fig.add_subplot()]
    if voyage:
        axes.append(fig.add_subplot(2, 1, 2, sharex=axes[0]))
    panels: list[tuple[np.ndarray, str, tuple[float, float] | None]] = [(y, label, (-0.03, 1.03))]
    if voyage:
        panels.append(
            (np.array([p.hazard for p in front.points]), "hazard -ln(1 - p) [-] (log; inf and 0 off scale)", None)
        )
    for j, (ax, (values, name, limits)) in enumerate(zip(axes, panels, strict=True)):
        ax.step(t, values, where="post", color="tab:blue", lw=1.2, label=f"{front.kind} front ({t.size} routes)")
        ax.plot(t, values, "o", color="tab:blue", ms=4)
        for i, mark in enumerate(marked):
            colour = _CRITERION_COLOURS[i % len(_CRITERION_COLOURS)]
            ax.plot([mark[1]], [mark[2 + j]], "x", ms=9, mew=2, color=colour, label=mark[0])
        ax.set_ylabel(name)
        if limits is None:
            ax.set_yscale("log")
        else:
            ax.set_ylim(*limits)
        ax.grid(True, lw=0.3)
        ax.legend(fontsize=7, loc="best")
    axes[-1].set_xlabel("voyage time [h]")
    axes[0].set_title(title or f"time against reliability: {front.kind} front")
    fig.tight_layout()
    return fig


def _map_axes(fig: Figure, routes: Sequence[Any], example: Route) -> tuple[Axes, Any]:
    """Axes framing the tracks (each with ``lon_deg``, ``lat_deg``), the weather's patches and the course's marks (of
    the route ``example``), longitudes continuous from the start."""
    weather = example.weather
    ax = fig.add_subplot()
    ref = float(routes[0].lon_deg[0])

    def view(lon: Any) -> Any:
        return continuous_lon_deg(lon, ref)

    for patch in weather.patches if isinstance(weather, UniformWeather) else ():
        (w, e), (s, n) = patch.lon, patch.lat
        ax.fill(view(np.array([w, e, e, w])), [s, s, n, n], facecolor="0.5", alpha=0.15, edgecolor="0.3", zorder=0)
        what = ", ".join(f"{k} {v:g}" for k, v in patch.values.items())
        name = getattr(patch, "name", "")
        ax.text(float(view(w)) + 0.2, n - 0.2, f"{name}: {what}" if name else what, fontsize=6, va="top")
    ax.plot(view(routes[0].lon_deg[0]), routes[0].lat_deg[0], "k^", ms=7, label="start")
    ax.plot(view(routes[0].lon_deg[-1]), routes[0].lat_deg[-1], "ks", ms=7, label="finish")
    marks = [(leg.lon_deg[-1], leg.lat_deg[-1]) for leg in example.course_legs[:-1]]
    if marks:
        lon, lat = np.array(marks).T
        ax.plot(view(lon), lat, "kD", ms=6, label="waypoint" if len(marks) == 1 else "waypoints")
    ax.set_xlabel("longitude [deg]")
    ax.set_ylabel("latitude [deg]")
    mid = float(np.mean(np.concatenate([r.lat_deg for r in routes])))
    ax.set_aspect(1.0 / np.cos(np.radians(mid)))
    ax.grid(True, lw=0.3)
    return ax, view


def routes_figure(front: Front, *, title: str | None = None, max_labelled: int = 8) -> Figure:
    """Map of the front's routes, coloured from the fastest (dark) to the safest (light); the weather's patches in
    grey. At most ``max_labelled`` routes are named in the legend (fastest, safest and evenly between)."""
    from matplotlib import colormaps

    key, _ = OBJECTIVE[front.kind]
    routes = front.points  # their tracks: no route is built
    fig = _figure(9.0, 6.5)
    ax, view = _map_axes(fig, routes, routes[0].route)  # one route built: its weather and marks
    cmap = colormaps["viridis"]
    n = len(routes)
    named = set(np.linspace(0, n - 1, min(n, max_labelled)).round().astype(int).tolist())
    for i, p in enumerate(front.points):
        colour = cmap(i / max(n - 1, 1))
        label = None
        if i in named:
            label = f"{p.voyage_time_h:.1f} h, p {getattr(p, key):.3g}"
            label += f", hazard {p.hazard:.3g}" if front.kind == "voyage" else ""
        ax.plot(view(p.lon_deg), p.lat_deg, color=colour, lw=1.2, label=label)
    ax.legend(fontsize=7, loc="best", title=f"{front.kind} front: time, {key.replace('_', ' ')}", title_fontsize=7)
    ax.set_title(title or f"the {n} routes of the {front.kind} front")
    fig.tight_layout()
    return fig


def sensitivity_figure(route: Route, rows: Sequence[Sensitivity], which: Any, *, title: str | None = None) -> Figure:
    """Map of the route at the user's apf, each leg coloured by the criterion that bends it (``which``: index into
    ``rows`` per leg, -1 for none: grey); the stretches exposed to a criterion (it fires there) drawn wide and pale in
    its colour."""
    fig = _figure(9.0, 6.5)
    ax, view = _map_axes(fig, [route], route)
    lon, lat = view(route.lon_deg), route.lat_deg
    for i, row in enumerate(rows):
        colour = _CRITERION_COLOURS[i % len(_CRITERION_COLOURS)]
        for k in np.flatnonzero(row.exposed_legs):
            ax.plot(lon[k : k + 2], lat[k : k + 2], color=colour, lw=7, alpha=0.3, solid_capstyle="butt")
        ax.plot([], [], color=colour, lw=7, alpha=0.3, label=f"exposed to {row.node}: {row.exposure_h:.1f} h")
    for leg in range(route.legs.n_legs):
        i = int(which[leg])
        colour = "0.4" if i < 0 else _CRITERION_COLOURS[i % len(_CRITERION_COLOURS)]
        ax.plot(lon[leg : leg + 2], lat[leg : leg + 2], color=colour, lw=1.8)
    ax.plot([], [], color="0.4", lw=1.8, label="not bent by a criterion")
    for i, row in enumerate(rows):
        ax.plot(
            [],
            [],
            color=_CRITERION_COLOURS[i % len(_CRITERION_COLOURS)],
            lw=1.8,
            label=f"bent by {row.criterion}: costs {row.hours_cost:.1f} h",
        )
    ax.legend(fontsize=7, loc="best")
    ax.set_title(title or f"what bounds the route at apf {route.problem.apf:g} ({route.voyage_time_h:.1f} h)")
    fig.tight_layout()
    return fig
