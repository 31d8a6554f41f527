"""Figures of an ensemble (:class:`~pyroute_rel.analysis.ensemble.EnsembleResult`): the members' routes, the arrival
distribution of each candidate route, and the regret matrix.

Each function returns a :class:`matplotlib.figure.Figure` (object API, no pyplot) and saves it when given a path.
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from pyroute_rel.analysis.ensemble import EnsembleResult
    from pyroute_rel.analysis.monte_carlo import MonteCarloResult

__all__ = ["spaghetti_map", "arrival_cdf", "regret_heatmap", "monte_carlo_histogram"]

_CHOSEN = "tab:red"
_MEAN = "tab:blue"


def _figure(width: float, height: float) -> Figure:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _save(fig: Figure, path: str | os.PathLike[str] | None) -> Figure:
    if path is not None:
        fig.savefig(path, dpi=130)
    return fig


def _style(result: EnsembleResult, i: int) -> dict[str, Any]:
    if i == result.chosen:
        return {"color": _CHOSEN, "lw": 2.4, "zorder": 4, "label": f"chosen: {result.names[i]} ({result.risk})"}
    if result.names[i] == "mean":
        return {"color": _MEAN, "lw": 1.8, "ls": "--", "zorder": 3, "label": "ensemble-mean field"}
    return {"color": "0.55", "lw": 0.8, "alpha": 0.8, "zorder": 2}


def spaghetti_map(
    result: EnsembleResult, *, path: str | os.PathLike[str] | None = None, title: str | None = None
) -> Figure:
    """The candidate routes on a lon/lat map: members' routes thin grey, the mean-field route dashed blue, the chosen
    route bold red."""
    fig = _figure(8.0, 6.0)
    ax = fig.add_subplot()
    labelled = False
    for i, track in enumerate(result.tracks):
        style = _style(result, i)
        if "label" not in style and not labelled:
            style["label"], labelled = "member routes", True
        ax.plot(track[:, 0], track[:, 1], **style)
    start, finish = result.tracks[0][0], result.tracks[0][-1]
    ax.plot(*start, "k^", ms=8, zorder=5, label="start")
    ax.plot(*finish, "ks", ms=7, zorder=5, label="finish")
    lat = np.concatenate([t[:, 1] for t in result.tracks])
    ax.set_aspect(1.0 / np.cos(np.radians(float(np.mean(lat)))))
    ax.set_xlabel("longitude [deg]")
    ax.set_ylabel("latitude [deg]")
    ax.grid(True, lw=0.3)
    ax.legend(loc="best", fontsize=8)
    ax.set_title(title or f"{len(result.members)} members: {len(result.tracks)} candidate routes")
    return _save(fig, path)


def arrival_cdf(result: EnsembleResult, *, path: str | os.PathLike[str] | None = None) -> Figure:
    """Empirical CDF of each candidate's voyage time over the members (a curve that stops short of 1: the route
    cannot be completed in some members); infeasible members (``p_f > apf``, land, zone) are marked with a cross."""
    fig = _figure(8.0, 5.0)
    ax = fig.add_subplot()
    n = result.time_h.shape[1]
    labelled = False
    for i in range(len(result.names)):
        t = result.time_h[i]
        order = np.argsort(t)
        ts = t[order]
        finite = np.isfinite(ts)
        y = np.arange(1, n + 1) / n
        style = _style(result, i)
        if "label" not in style and not labelled:
            style["label"], labelled = "member routes", True
        ax.step(ts[finite], y[finite], where="post", **style)
        bad = finite & ~result.feasible[i][order]
        if bad.any():
            ax.plot(ts[bad], y[bad], "x", color=style["color"], ms=5, zorder=style["zorder"])
    ax.plot([], [], "x", color="0.3", label="infeasible in that member (p_f > apf, land, zone)")
    ax.set_xlabel("voyage time [h]")
    ax.set_ylabel("fraction of members arrived")
    ax.set_ylim(0.0, 1.02)
    ax.grid(True, lw=0.3)
    ax.legend(loc="lower right", fontsize=8)
    ax.set_title("Arrival distribution of each candidate route over the members")
    return _save(fig, path)


def regret_heatmap(result: EnsembleResult, *, path: str | os.PathLike[str] | None = None) -> Figure:
    """The regret matrix [h]: candidate ``i`` (rows) sailed in member ``j`` (columns) minus member ``j``'s own
    optimum; grey where the candidate is infeasible in that member or the member has no route."""
    from matplotlib import colormaps

    regret = result.regret_h
    fig = _figure(max(6.0, 0.28 * regret.shape[1] + 3.0), max(4.5, 0.26 * regret.shape[0] + 2.0))
    ax = fig.add_subplot()
    cmap = colormaps["viridis"].with_extremes(bad="0.8")
    im = ax.imshow(np.ma.masked_invalid(regret), cmap=cmap, aspect="auto", interpolation="nearest")
    fig.colorbar(im, ax=ax, label="regret [h]")
    ax.set_xticks(range(len(result.members)), [str(m) for m in result.members], fontsize=7)
    ax.set_yticks(range(len(result.names)), list(result.names), fontsize=7)
    ax.get_yticklabels()[result.chosen].set_color(_CHOSEN)
    ax.set_xlabel("member whose weather comes true")
    ax.set_ylabel("candidate route")
    ax.set_title("Regret: hours lost against each member's own optimum (grey: infeasible)")
    return _save(fig, path)


def monte_carlo_histogram(result: MonteCarloResult, *, path: str | os.PathLike[str] | None = None) -> Figure:
    """Histogram of the Monte-Carlo voyage times [h] with the deterministic time and the runs that meet
    ``p_f > apf``."""
    fig = _figure(8.0, 4.5)
    ax = fig.add_subplot()
    t = result.voyage_time_h
    finite = np.isfinite(t)
    bins = max(10, min(60, int(np.sqrt(finite.sum()))))
    arrived = f"{int(finite.sum())} runs" if finite.all() else f"{int(finite.sum())} of {t.size} runs arrived"
    ax.hist(t[finite], bins=bins, color="0.6", label=arrived)
    over = finite & result.p_fail
    if over.any():
        ax.hist(t[over], bins=bins, range=(float(t[finite].min()), float(t[finite].max())), color=_CHOSEN,
                alpha=0.7, label="runs meeting p_f > apf")  # fmt: skip
    ax.axvline(result.deterministic_h, color="k", lw=1.5, ls="--", label="deterministic")
    ax.set_xlabel("voyage time [h]")
    ax.set_ylabel("runs")
    ax.legend(fontsize=8)
    lo, hi = result.p_fail_interval
    ax.set_title(f"Monte Carlo: P(p_f > apf) = {result.p_fail_fraction:.3f} (95 % CI {lo:.3f} to {hi:.3f})")
    return _save(fig, path)
