"""Convergence plot of a grid-convergence study (matplotlib, imported lazily).

Kept apart from :mod:`pyroute_rel.gci.numbers` so that the mathematics never imports matplotlib.
"""

from __future__ import annotations

import math
import os
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from pyroute_rel.gci.numbers import StudyResult

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

__all__ = ["plot_convergence"]


def plot_convergence(
    study: StudyResult,
    *,
    path: str | os.PathLike[str] | None = None,
    title: str | None = None,
    xlabel: str = "grid spacing h [km]",
    ylabel: str = "voyage time [h]",
) -> Figure:
    """Plot phi against grid spacing with the extrapolated value, the GCI band and the least-squares fit.

    Draws the values phi(h) as markers, the Richardson-extrapolated value of the three finest grids as a
    horizontal line with a marker at h = 0, the band phi1 (1 +- GCI_fine) around the finest value (when the
    triplet defines a GCI), and the least-squares curve from h = 0 to the coarsest grid when the study has
    four or more grids and a fitted form.

    Parameters
    ----------
    study : Result of :func:`pyroute_rel.gci.numbers.convergence_study`.
    path : PNG file to write, atomically (temporary file in the same folder, then ``os.replace``). The
        figure is then drawn on a private Agg canvas that pyplot never sees, so nothing is left open (no
        ``plt.close`` needed) and no GUI backend is touched. With None the figure is made with pyplot
        (for notebooks and ``plt.show()``) and nothing is written.
    title : Figure title; a default names the number of grids and the convergence label.
    xlabel : Label of the spacing axis [unit of h].
    ylabel : Label of the value axis [unit of phi].

    Returns
    -------
    matplotlib.figure.Figure
    """
    finest = study.finest
    ls = study.least_squares
    h = np.asarray(study.h, dtype=float)
    phi = np.asarray(study.phi, dtype=float)

    if path is not None:
        # Agg canvas without pyplot: no global figure registry, no GUI backend, nothing left open
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        fig = Figure(figsize=(7.0, 4.5))
        FigureCanvasAgg(fig)
        ax = fig.add_subplot()
    else:
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(7.0, 4.5))

    x_max = float(h[-1]) * 1.05
    if ls is not None and ls.fit not in ("data-range",):
        xs = np.linspace(0.0, float(h[-1]), 200)
        label = f"least squares ({ls.fit}" + (f", p = {ls.p:.2f})" if ls.p is not None else ")")
        ax.plot(xs, ls.predict(xs), "-", color="tab:green", lw=1.2, label=label)
    if finest.phi_ext is not None:
        ax.axhline(finest.phi_ext, color="tab:red", ls="--", lw=1.0)
        label = "phi_ext (3 finest grids" + (f", p = {finest.p:.2f})" if finest.p is not None else ")")
        ax.plot([0.0], [finest.phi_ext], "*", color="tab:red", ms=11, label=label, clip_on=False)
    if finest.gci_fine is not None and math.isfinite(finest.gci_fine):
        half = finest.gci_fine * abs(finest.phi[0])
        ax.axhspan(
            finest.phi[0] - half,
            finest.phi[0] + half,
            color="tab:blue",
            alpha=0.15,
            label=f"GCI_fine = {100.0 * finest.gci_fine:.3g} %",
        )
        ax.errorbar([finest.h[0]], [finest.phi[0]], yerr=[[half], [half]], fmt="none", ecolor="tab:blue", capsize=4)
    ax.plot(h, phi, "o", color="tab:blue", ms=6, label="grids")
    ax.set_xlim(0.0, x_max)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title if title is not None else f"Grid convergence: {h.size} grids, {finest.convergence}")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize="small")

    if path is not None:
        target = Path(path)
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent or ".")
        try:
            with os.fdopen(fd, "wb") as fh:
                fig.savefig(fh, format="png", dpi=120, bbox_inches="tight")
            os.chmod(tmp, 0o644)  # mkstemp creates 0600; a plot is an ordinary output file
            os.replace(tmp, target)
        except BaseException:
            if os.path.exists(tmp):
                os.unlink(tmp)
            raise
    return fig
