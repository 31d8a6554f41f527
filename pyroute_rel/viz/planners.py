"""Map of every planner's track on each course of a comparison (:func:`pyroute_rel.planners.compare.compare_planners`).

One panel per course: land (grown by the scenario's margin) in grey, exclusion zones hatched, the control weather's
patches outlined, and each planner's track labelled with the evaluator's voyage time (or "did not arrive").
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from matplotlib.figure import Figure

from pyroute_rel.geodesy import gc_densify
from pyroute_rel.weather.uniform import UniformWeather

if TYPE_CHECKING:
    from pyroute_rel.planners.compare import Comparison

__all__ = ["planners_map", "COLOURS"]

#: Colour of each planner's track (by the label's first word).
COLOURS = {"dp": "black", "mcts": "tab:red", "qlearning": "tab:blue", "dqn": "tab:green"}


def _dense(lon: Any, lat: Any) -> tuple[Any, Any]:
    lon, lat = np.asarray(lon, dtype=float), np.asarray(lat, dtype=float)
    if lon.size < 2:
        return lon, lat
    x, y, _ = gc_densify(lon[:-1], lat[:-1], lon[1:], lat[1:], max_step_km=25.0)
    return x, y


def _fill(ax: Any, geometry: Any, **style: Any) -> None:
    for poly in getattr(geometry, "geoms", [geometry]):
        if poly.is_empty or not hasattr(poly, "exterior"):
            continue
        x, y = poly.exterior.xy
        ax.fill(x, y, **style)


def _panel(ax: Any, comp: Comparison) -> None:
    sc = comp.scenario
    runs = comp.runs
    lon = np.concatenate([r.track.lon_deg for r in runs])
    lat = np.concatenate([r.track.lat_deg for r in runs])
    pad = 1.0
    box = (lon.min() - pad, lat.min() - pad, lon.max() + pad, lat.max() + pad)
    if sc.avoid.land:
        from pyroute_rel.obstacles.land import land_geometry

        land = land_geometry(
            (max(box[0], -180.0), max(box[1], -89.0), min(box[2], 180.0), min(box[3], 89.0)),
            margin_km=sc.avoid.margin_km,
            resolution=sc.avoid.resolution,
        )
        _fill(ax, land, color="0.8", lw=0, label="_land")
    for zone in sc.avoid.zones:
        _fill(ax, zone.geometry, facecolor="none", edgecolor="tab:purple", hatch="//", lw=0.8)
    for patch in sc.weather.patches if isinstance(sc.weather, UniformWeather) else ():
        (x0, x1), (y0, y1) = patch.lon, patch.lat
        ax.plot([x0, x1, x1, x0, x0], [y0, y0, y1, y1, y0], color="tab:orange", lw=0.8, ls="--")
    for r in runs:
        x, y = _dense(r.track.lon_deg, r.track.lat_deg)
        v = r.voyage_time_h
        what = f"{v:.1f} h" if np.isfinite(v) else "did not arrive"
        if np.isfinite(v) and not r.feasible:
            what += ", infeasible"
        colour = COLOURS.get(r.label.split()[0], None)
        style = "--" if "published" in r.label else ":" if "cells" in r.label else "-"
        ax.plot(x, y, style, color=colour, lw=1.6 if r.label == "dp" else 1.1, label=f"{r.label}: {what}")
    ax.plot(*sc.start, "o", color="black", ms=4)
    ax.plot(*sc.finish, "s", color="black", ms=4)
    ax.set_xlim(box[0], box[2])
    ax.set_ylim(box[1], box[3])
    ax.set_aspect(1.0 / np.cos(np.radians(0.5 * (box[1] + box[3]))))
    ax.set_xlabel("longitude [deg]")
    ax.set_ylabel("latitude [deg]")
    ax.set_title(comp.name, fontsize=9)
    ax.legend(fontsize=6, loc="best")


def planners_map(comparisons: Sequence[Comparison], *, columns: int = 2) -> Figure:
    """A map per course of every planner's track (see the module notes); save with ``fig.savefig(path)``."""
    n = len(comparisons)
    cols = min(columns, n)
    rows = -(-n // cols)
    fig = Figure(figsize=(6.0 * cols, 4.6 * rows), layout="constrained")
    for i, comp in enumerate(comparisons):
        _panel(fig.add_subplot(rows, cols, i + 1), comp)
    fig.suptitle("Planners on the DP's problem: tracks and the evaluator's voyage times", fontsize=10)
    return fig
