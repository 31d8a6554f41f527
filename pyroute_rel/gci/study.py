"""Routed grid-convergence studies: route one scenario on a family of grids, then estimate the error.

A study is a list of :class:`GridLevel` (a *refinement path*) routed one after the other; the voyage
times and a representative spacing ``h`` of each level feed :func:`pyroute_rel.gci.numbers.convergence_study`.

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

import math
import numbers
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from pyroute_rel.errors import ConvergenceError
from pyroute_rel.gci.numbers import StudyResult, convergence_study
from pyroute_rel.routing.grid import make_grid
from pyroute_rel.routing.solve import forward_dp

if TYPE_CHECKING:
    from pyroute_rel.scenario import Scenario

__all__ = [
    "GridLevel",
    "RoutedStudy",
    "square_levels",
    "angular_levels",
    "check_study_scenario",
    "run_study",
    "REFINEMENTS",
]

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
            "verdict": self.study.verdict()[0],
            "verdict_reason": self.study.verdict()[1],
        }

    def csv(self) -> str:
        """The table of grids as CSV."""
        cols = [
            "n_ranks",
            "n_nodes",
            "h_km",
            "spacing_km",
            "rank_spacing_km",
            "max_deviation_deg",
            "arcs",
            "voyage_time_h",
            "runtime_s",
        ]
        lines = [",".join(cols)]
        for r in self.rows:
            lines.append(
                ",".join(
                    "" if r.get(c) is None else f"{r[c]:.10g}" if isinstance(r[c], float) else str(r[c]) for c in cols
                )
            )
        return "\n".join(lines) + "\n"


def _whole_numbers(values: Sequence[int], option: str) -> list[int]:
    """Refuse anything but whole numbers >= 1 (naming the CLI option they came from)."""
    out = list(values)
    if not out:
        raise ConvergenceError(f"{option} needs one whole number >= 1 per grid (got none)")
    for v in out:
        if isinstance(v, bool) or not isinstance(v, int | np.integer) or v < 1:
            raise ConvergenceError(f"{option} must be whole numbers >= 1, one per grid (got {v!r} in {out})")
    return [int(v) for v in out]


def _positive(value: float, option: str, unit: str = "") -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not (math.isfinite(value) and value > 0):
        raise ConvergenceError(f"{option} must be a finite number > 0{unit} (got {value!r})")
    return float(value)


def square_levels(n_nodes: Sequence[int], n_ranks: Sequence[int] | None = None) -> list[GridLevel]:
    """The paper's square all-to-all grids (``n_ranks = n_nodes`` unless given).

    Raises
    ------
    ConvergenceError
        A count that is not a whole number >= 1 (named by its CLI option, ``--n-nodes`` or ``--n-ranks``), or
        ``n_ranks`` of another length than ``n_nodes``.
    """
    nodes = _whole_numbers(n_nodes, "--n-nodes")
    ranks = list(nodes) if n_ranks is None else _whole_numbers(n_ranks, "--n-ranks")
    if len(ranks) != len(nodes):
        raise ConvergenceError(f"--n-ranks needs one value per grid ({len(nodes)}), got {len(ranks)}")
    return [GridLevel(n_ranks=r, n_nodes=n) for r, n in zip(ranks, nodes, strict=True)]


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

    The defaults differ from a single route's (``aspect = 6``, ``half_width_km = 1000``, ``max_deviation_deg =
    45``, see :func:`pyroute_rel.routing.grid.make_grid`) on purpose, because they describe a path of grids rather than
    one grid. ``aspect0`` is the coarsest grid's aspect: from 2, the levels 41, 81, 161 ranks have aspects 2, 4, 8, so
    the finest grid resolves angles better than the default route; from 6 they would be 6, 12, 24 (with the route's
    three settings the finest grid has 10.8 M arcs against 2.5 M with these defaults, on the 5382 km example course).
    The band is wider (60 deg) so that the coarse, low-aspect grids can still turn: at aspect 2 a 45 deg band holds two
    arcs on each side (26.6 and 45 deg), a 60 deg band three (up to 56.3 deg). The half-width is fixed along the path,
    so it keeps a margin (1200 km) over the route's 1000 km. Results documented with these defaults stay as they are.

    Raises
    ------
    ConvergenceError
        ``n_ranks`` not whole numbers >= 1, ``aspect0``, ``half_width_km`` or ``route_length_km`` not finite
        and > 0, or ``max_deviation_deg`` outside (0, 90) (named by their CLI options).
    """
    ranks = _whole_numbers(n_ranks, "--n-ranks")
    aspect0 = _positive(aspect0, "--aspect0 (rank spacing / lateral spacing of the coarsest grid)")
    half_width_km = _positive(half_width_km, "--half-width-km", " [km]")
    route_length_km = _positive(route_length_km, "route length", " [km]")
    if isinstance(max_deviation_deg, bool) or not (
        isinstance(max_deviation_deg, numbers.Real) and 0.0 < max_deviation_deg < 90.0
    ):
        raise ConvergenceError(f"--max-deviation must be in (0, 90) [deg] (got {max_deviation_deg!r})")
    levels = []
    for nr in ranks:
        rank_spacing = route_length_km / (nr + 1)
        aspect = aspect0 * nr / ranks[0]
        spacing = rank_spacing / aspect
        n_nodes = 2 * int(np.ceil(half_width_km / spacing)) + 1
        levels.append(
            GridLevel(n_ranks=nr, n_nodes=n_nodes, spacing_km=spacing, max_deviation_deg=float(max_deviation_deg))
        )
    return levels


def check_study_scenario(scenario: Scenario) -> None:
    """Refuse, before any routing, a scenario a study cannot route as ``pyroute-rel route`` would.

    A course with waypoints (one grid per leg) is refused; a start, finish (or the start/finish line's
    reference points) on land or inside an exclusion zone is refused with the message of
    :meth:`~pyroute_rel.scenario.Scenario.route`.
    """
    from pyroute_rel.errors import ScenarioError
    from pyroute_rel.obstacles.mask import check_points

    if scenario.waypoints:
        raise ScenarioError(
            f"gci study does not support [route].waypoints yet ({len(scenario.waypoints)} given): study each leg "
            "as its own scenario"
        )
    check_points(scenario.marks(), scenario.avoid)  # no waypoints here: start and finish


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
    compiled once and shared by all levels. The grids run from the scenario's start (or ``[route].start_line``) to
    its finish (or ``[route].finish_line``), as in :meth:`~pyroute_rel.scenario.Scenario.route`; every grid is
    built and the start, finish and weather coverage are checked before the first is routed.

    Raises
    ------
    ScenarioError
        The scenario has waypoints, or its start or finish is on land or inside an exclusion zone.
    GridError, WeatherCoverageError
        A grid cannot be built, or the weather does not cover its ends or the departure.
    ConvergenceError
        Fewer than three levels, an unknown refinement, a bad safety factor, or no feasible route on a grid.
    """
    if len(levels) < 3:
        raise ConvergenceError(f"a study needs at least three grids (got {len(levels)})")
    if refinement not in REFINEMENTS:
        raise ConvergenceError(f"refinement must be one of {list(REFINEMENTS)} (got {refinement!r})")
    if isinstance(safety_factor, bool) or not (
        isinstance(safety_factor, numbers.Real) and math.isfinite(safety_factor) and safety_factor > 0
    ):
        raise ConvergenceError(f"safety_factor must be a finite number > 0 (got {safety_factor!r})")

    check_study_scenario(scenario)
    failure = scenario.load_failure()
    grids = [
        make_grid(
            scenario.start,
            scenario.finish,
            n_ranks=lv.n_ranks,
            n_nodes=lv.n_nodes,
            spacing_km=lv.spacing_km,
            max_deviation_deg=lv.max_deviation_deg,
            start_line=scenario.start_line,
            finish_line=scenario.finish_line,
        )
        for lv in levels
    ]
    for grid in grids:  # as Scenario.route: the weather must cover the end points and the departure
        s_lon, s_lat = grid.start_points
        lons, lats = [*s_lon, grid.finish[0]], [*s_lat, grid.finish[1]]
        scenario.weather.check_coverage(
            (min(lons), max(lons)), (min(lats), max(lats)), (scenario.departure, scenario.departure)
        )
    todo = grids[::-1]  # routed grids are dropped one by one, with what forward_dp cached on them
    del grids
    rows = []
    for i, lv in enumerate(levels):
        grid = todo.pop()
        problem = scenario.problem(failure=failure, grid=grid)  # samples per arc from the scenario's spacing
        t0 = time.perf_counter()
        res = forward_dp(grid, problem)
        dt = time.perf_counter() - t0
        if not np.isfinite(res.finish_h):
            from pyroute_rel.routing.solve import explain_infeasible

            raise ConvergenceError(f"grid {lv.n_ranks}x{lv.n_nodes}: {explain_infeasible(grid, problem, res)}")
        h = grid.spacing_km if refinement == "square" else grid.rank_spacing_km
        row = {
            "n_ranks": grid.n_ranks,
            "n_nodes": grid.n_nodes,
            "h_km": float(h),
            "spacing_km": grid.spacing_km,
            "rank_spacing_km": grid.rank_spacing_km,
            "max_deviation_deg": grid.max_deviation_deg,
            "arcs": res.arcs_evaluated,
            "samples_per_arc": problem.samples,
            "voyage_time_h": float(res.finish_h),
            "runtime_s": dt,
        }
        rows.append(row)
        if progress is not None:
            progress(i, len(levels), row)
    study = convergence_study(
        [float(r["h_km"] or 0.0) for r in rows],
        [float(r["voyage_time_h"] or 0.0) for r in rows],
        safety_factor=safety_factor,
    )
    return RoutedStudy(refinement=refinement, rows=tuple(rows), study=study)
