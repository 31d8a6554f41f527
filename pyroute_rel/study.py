"""Routed grid-convergence studies: route one scenario on a family of grids, then estimate the error.

A study is a list of :class:`GridLevel` (a *refinement path*) routed one after the other; the voyage
times and a representative spacing ``h`` of each level feed :func:`pyroute_rel.gci.convergence_study`.

Refinement paths (:data:`REFINEMENTS`)
--------------------------------------
``"square"``
    The paper's grids: ``n_ranks = n_nodes = n``, all-to-all arcs, lateral spacing = rank spacing =
    route length / (n + 1); ``h`` is that spacing [km]. An arc can only point at ``atan(k)`` from the
    route, the same angles at every level, so routes that turn do not converge (see README,
    "Convergent discretisation").
``"angular"``
    Rank spacing and lateral spacing both shrink, the lateral spacing faster (``aspect = rank spacing /
    lateral spacing`` doubles whenever ``n_ranks`` doubles), arcs banded to ``max_deviation_deg``, and a
    fixed domain half-width; the smallest angle between arcs improves at every level. ``h`` is the rank
    spacing [km].
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from .errors import ConvergenceError
from .gci import StudyResult, convergence_study
from .grid import make_grid
from .solve import forward_dp

if TYPE_CHECKING:
    from .scenario import Scenario

__all__ = ["GridLevel", "RoutedStudy", "square_levels", "angular_levels", "run_study", "REFINEMENTS"]

REFINEMENTS = ("square", "angular")


@dataclass(frozen=True)
class GridLevel:
    """One grid of a study: ranks, nodes, lateral spacing [km] (None: square), band [deg] (None: all-to-all)."""

    n_ranks: int
    n_nodes: int
    spacing_km: float | None = None
    max_deviation_deg: float | None = None


@dataclass(frozen=True)
class RoutedStudy:
    """Result of :func:`run_study`: the grids, their voyage times and the convergence estimates."""

    refinement: str
    rows: tuple[dict[str, Any], ...]
    study: StudyResult

    def to_dict(self) -> dict[str, Any]:
        """The JSON contract of ``pyroute-rel gci study --json``."""
        fin = self.study.finest
        ls = self.study.least_squares
        return {
            "refinement": self.refinement,
            "grids": list(self.rows),
            "p": fin.to_dict()["p"],
            "phi_ext": fin.to_dict()["phi_ext"],
            "gci_fine": fin.to_dict()["gci_fine"],
            "gci_coarse": fin.to_dict()["gci_coarse"],
            "e_a": fin.to_dict()["e_a"],
            "asymptotic_ratio": fin.to_dict()["asymptotic_ratio"],
            "convergence": fin.convergence,
            "method": fin.method,
            "note": fin.note,
            "triplets": [t.to_dict() for t in self.study.triplets],
            "least_squares": None if ls is None else ls.to_dict(),
        }

    def csv(self) -> str:
        """The table of grids as CSV."""
        cols = ["n_ranks", "n_nodes", "h_km", "spacing_km", "rank_spacing_km", "max_deviation_deg", "arcs",
                "voyage_time_h", "runtime_s"]
        lines = [",".join(cols)]
        for r in self.rows:
            lines.append(",".join("" if r.get(c) is None else f"{r[c]:.10g}" if isinstance(r[c], float)
                                  else str(r[c]) for c in cols))
        return "\n".join(lines) + "\n"


def square_levels(n_nodes: Sequence[int], n_ranks: Sequence[int] | None = None) -> list[GridLevel]:
    """The paper's square all-to-all grids (``n_ranks = n_nodes`` unless given)."""
    ranks = list(n_nodes) if n_ranks is None else list(n_ranks)
    if len(ranks) != len(n_nodes):
        raise ConvergenceError(f"--n-ranks needs one value per grid ({len(n_nodes)}), got {len(ranks)}")
    return [GridLevel(n_ranks=int(r), n_nodes=int(n)) for r, n in zip(ranks, n_nodes, strict=True)]


def angular_levels(
    route_length_km: float,
    n_ranks: Sequence[int],
    *,
    aspect0: float = 2.0,
    half_width_km: float = 1200.0,
    max_deviation_deg: float = 60.0,
) -> list[GridLevel]:
    """A refinement path that converges: rank spacing halves, lateral spacing quarters, band fixed in angle.

    Level ``i`` has ``n_ranks[i]`` ranks (rank spacing ``L / (n_ranks + 1)``) and aspect ratio
    ``aspect0 * n_ranks[i] / n_ranks[0]``, so the lateral spacing falls as the square of the rank spacing
    and the angular resolution ``atan(1 / aspect)`` improves with every level. The half-width is fixed.
    """
    levels = []
    for nr in n_ranks:
        rank_spacing = route_length_km / (nr + 1)
        aspect = aspect0 * nr / n_ranks[0]
        spacing = rank_spacing / aspect
        n_nodes = 2 * int(np.ceil(half_width_km / spacing)) + 1
        levels.append(GridLevel(n_ranks=int(nr), n_nodes=n_nodes, spacing_km=spacing,
                                max_deviation_deg=max_deviation_deg))
    return levels


def run_study(
    scenario: Scenario,
    levels: Sequence[GridLevel],
    *,
    refinement: str = "square",
    safety_factor: float = 1.25,
    progress: Callable[[int, int, dict[str, Any]], None] | None = None,
) -> RoutedStudy:
    """Route ``scenario`` on every level and estimate the discretisation error of the voyage time.

    ``h`` is the lateral spacing for square grids and the rank spacing otherwise [km]. The failure model is
    compiled once and shared by all levels.
    """
    if len(levels) < 3:
        raise ConvergenceError(f"a study needs at least three grids (got {len(levels)})")
    from dataclasses import replace

    from .grid import auto_samples

    failure = scenario.load_failure()
    rows = []
    for i, lv in enumerate(levels):
        grid = make_grid(scenario.start, scenario.finish, n_ranks=lv.n_ranks, n_nodes=lv.n_nodes,
                         spacing_km=lv.spacing_km, max_deviation_deg=lv.max_deviation_deg)
        problem = scenario.problem(failure=failure, grid=grid)
        if scenario.samples_per_arc is None:
            problem = replace(problem, samples=auto_samples(grid))
        t0 = time.perf_counter()
        res = forward_dp(grid, problem)
        dt = time.perf_counter() - t0
        if not np.isfinite(res.finish_h):
            from .solve import explain_infeasible

            raise ConvergenceError(f"grid {lv.n_ranks}x{lv.n_nodes}: {explain_infeasible(grid, problem, res)}")
        h = grid.spacing_km if refinement == "square" else grid.rank_spacing_km
        row = {
            "n_ranks": grid.n_ranks, "n_nodes": grid.n_nodes, "h_km": float(h), "spacing_km": grid.spacing_km,
            "rank_spacing_km": grid.rank_spacing_km, "max_deviation_deg": grid.max_deviation_deg,
            "arcs": res.arcs_evaluated, "samples_per_arc": problem.samples, "voyage_time_h": float(res.finish_h),
            "runtime_s": dt,
        }
        rows.append(row)
        if progress is not None:
            progress(i, len(levels), row)
    study = convergence_study([float(r["h_km"] or 0.0) for r in rows], [float(r["voyage_time_h"] or 0.0) for r in rows],
                              safety_factor=safety_factor)
    return RoutedStudy(refinement=refinement, rows=tuple(rows), study=study)
