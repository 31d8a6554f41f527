"""The departure-planning figure of a sweep (:mod:`pyroute_rel.batch.sweep`): voyage time and voyage failure probability
against departure, with the departures that have no route marked.

Drawn on matplotlib's object API (a :class:`~matplotlib.figure.Figure` on an Agg canvas, never pyplot).
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from pyroute_rel.files import atomic_write

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

__all__ = ["sweep_figure", "write_sweep_figure", "series", "MAX_LINES", "VARIED"]

#: Most series drawn as separate lines; with more, every run is a dot and the median of each departure a line.
MAX_LINES = 8
#: The settings a series is told apart by (all but the departure), as the table's columns.
VARIED = ("member", "apf", "failure_model", "polar", "grid", "options")


def series(rows: Sequence[Mapping[str, Any]]) -> dict[str, list[Mapping[str, Any]]]:
    """The routed rows grouped by their settings other than the departure, each group ordered by departure; the
    label names only the settings that vary across the rows (``""`` when none does)."""
    varied = [c for c in VARIED if len({json.dumps(r.get(c)) for r in rows}) > 1]
    groups: dict[str, list[Mapping[str, Any]]] = {}
    for r in rows:
        label = ", ".join(f"{c} {_value(r.get(c))}" for c in varied)
        groups.setdefault(label, []).append(r)
    return {k: sorted(v, key=lambda r: str(r["departure"])) for k, v in groups.items()}


def _value(v: Any) -> str:
    if isinstance(v, str) and v.startswith("{"):
        d = json.loads(v)
        return " ".join(f"{k}={x}" for k, x in d.items()) or "file's"
    return "file's" if v is None else str(v)


def _times(rows: Sequence[Mapping[str, Any]]) -> np.ndarray:
    return np.array([str(r["departure"]).rstrip("Z") for r in rows], dtype="datetime64[s]")


def _spread(ax_t: Any, ax_p: Any, rows: Sequence[Mapping[str, Any]], color: str, label: str) -> None:
    """Each run as a dot and each departure's median as a line, on both panels."""
    x = _times(rows)
    days = np.unique(x)
    for ax, col in ((ax_t, "voyage_time_h"), (ax_p, "voyage_failure_probability")):
        values = np.array([r[col] for r in rows], dtype=float)
        ax.plot(x, values, ".", color=color, ms=3, alpha=0.5)
        med = [float(np.median(values[x == d])) for d in days]
        ax.plot(days, med, "o-", color=color, ms=4, label=f"{label + ': ' if label else ''}median per departure")


def sweep_figure(rows: Sequence[Mapping[str, Any]], *, title: str | None = None) -> Figure:
    """Voyage time [h] (top) and voyage failure probability (bottom) against departure.

    Each series of routed runs (:func:`series`) is a line when there are at most :data:`MAX_LINES`; with more,
    each run is a dot and a line joins each departure's median over the members (over all runs when the other
    settings still make more than :data:`MAX_LINES` series). Departures where some run found no route (status
    ``no_route`` or ``error``) are red crosses along the bottom of the top panel, labelled with their count.

    Parameters
    ----------
    rows : The sweep's rows (``run_sweep(...).to_pylist()``); rows without a departure are left out.
    title : The figure's title (default: the number of runs).
    """
    from matplotlib.dates import date2num
    from matplotlib.figure import Figure

    rows = [r for r in rows if r.get("departure")]
    ok = [r for r in rows if r["status"] == "ok"]
    bad = [r for r in rows if r["status"] != "ok"]
    fig = Figure(figsize=(9.0, 6.0))
    ax_t, ax_p = fig.subplots(2, 1, sharex=True)
    groups = series(ok)
    pooled = series([{**r, "member": None} for r in ok])  # members pooled: their spread as dots
    if len(groups) <= MAX_LINES:
        for label, g in groups.items():
            x = _times(g)
            ax_t.plot(x, [r["voyage_time_h"] for r in g], "o-", ms=4, label=label or None)
            ax_p.plot(x, [r["voyage_failure_probability"] for r in g], "o-", ms=4, label=label or None)
    else:
        if len(pooled) > MAX_LINES:
            pooled = {"": ok}
        for i, (label, g) in enumerate(pooled.items()):
            _spread(ax_t, ax_p, g, f"C{i}", label)
    if bad:
        when, count = np.unique(_times(bad), return_counts=True)
        ax_t.plot(when, np.zeros(when.size), "x", color="tab:red", ms=9, mew=2, transform=ax_t.get_xaxis_transform())
        ax_t.lines[-1].set_label(f"no route ({len(bad)} run{'s' if len(bad) != 1 else ''})")
        ax_t.lines[-1].set_clip_on(False)
        for t, n in zip(when, count, strict=True):
            ax_t.annotate(str(n), (date2num(t), 0.0), xycoords=ax_t.get_xaxis_transform(), xytext=(0, 8),
                          textcoords="offset points", ha="center", color="tab:red", fontsize=8)  # fmt: skip
    ax_t.set_ylabel("voyage time [h]")
    ax_p.set_ylabel("voyage failure probability [-]")
    ax_p.set_xlabel("departure (UTC)")
    ax_p.set_ylim(-0.03, 1.03)
    for ax in (ax_t, ax_p):
        ax.grid(True, alpha=0.3)
    if any(line.get_label() and not line.get_label().startswith("_") for line in ax_t.lines):
        ax_t.legend(fontsize=8, loc="best")
    fig.autofmt_xdate()
    fig.subplots_adjust(left=0.09, right=0.98, top=0.93, bottom=0.14, hspace=0.08)
    fig.suptitle(title or f"sweep of {len(rows)} runs: {len(ok)} routed, {len(bad)} without a route")
    return fig


def write_sweep_figure(rows: Sequence[Mapping[str, Any]], path: str | os.PathLike[str], **kwargs: Any) -> Path:
    """Draw :func:`sweep_figure` and write it as a PNG, atomically; returns the path."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    fig = sweep_figure(rows, **kwargs)
    FigureCanvasAgg(fig)
    atomic_write(path, lambda p: fig.savefig(p, format="png", dpi=110))
    return Path(path)
