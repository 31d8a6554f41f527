"""Refining a routed track: narrow corridor grids around it, each solved again exactly.

The DP is exact on its grid, but the grid only offers node positions ``spacing_km`` apart on each rank line, so a
track that should run straight at a slant zig-zags between nodes. Refinement frees the track's points to slide along
their rank lines: around the track it lays a *corridor grid* on the same rank lines, :data:`CORRIDOR_NODES` nodes
across ``track +- half_width_km`` on every rank, joined like the grid's (within its ``max_deviation_deg``), and
solves it with the same problem (weather, polar, failure model and apf, obstacles, waiting, finish line). The
corridor's middle nodes are the previous track, so the exact DP on it can only keep or lower the voyage time
(tested). The first corridor spans :data:`FIRST_HALF_WIDTH` grid spacings each side at half the grid's spacing;
after a level whose track stays inside its corridor the next is :data:`SHRINK` times narrower (and finer), else it
keeps the width, recentred on the new track.

On the paper's control course (default grid, 160 ranks) five levels take the voyage from 701.65 h to 699.40 h at
apf 1, 708.27 h to 706.90 h at apf 0.95 and 729.06 h to 727.09 h at apf 0.5, from 0.2-0.4 % above the converged
values of the README's study (699.05, 706.83, 727.19 h) to within 0.05 % of them. (Those were measured while arcs
were judged at their weather samples and could cut corners; judged on every piece they cross,
:mod:`pyroute_rel.reliability.crossings`, apf 0.95 goes from 708.57 h to 707.29 h and apf 0.5 from 729.60 h to 727.65
h.)

This is discrete differential dynamic programming (Heidari et al. 1971): a continuous optimisation of the track's
points along the ranks, done by exact DPs on small graphs, which keeps every constraint of the cost (forbidden
arcs, land, zones, time windows) without derivatives. It finds a local optimum near the DP track; the rank
spacing stays as it was.

References
----------
Heidari, M., Chow, V. T., Kokotovic, P. V. and Meredith, D. D. (1971). Discrete differential dynamic programming
approach to water resources systems optimization. Water Resources Research 7(2), 273-282,
doi:10.1029/WR007i002p00273.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from pyroute_rel.errors import GridError, check_callable
from pyroute_rel.geodesy import EARTH_RADIUS_KM
from pyroute_rel.routing.grid import Grid, rank_points
from pyroute_rel.routing.solve import DPResult, RoutingProblem, forward_dp

__all__ = ["RefineLevel", "corridor_grid", "track_offsets_km", "refine"]

FloatArray = npt.NDArray[np.float64]

#: Nodes across a corridor (odd, so the previous track is the middle node).
CORRIDOR_NODES = 33
#: The first corridor's half-width, in node spacings of the grid routed on (its spacing is then half the grid's).
FIRST_HALF_WIDTH = 8.0
#: A corridor the track stays inside is followed by one this many times narrower (else one as wide, recentred).
SHRINK = 4.0
#: Corridors are not made finer than this node spacing [km]: a metre is far below any weather or polar detail.
MIN_SPACING_KM = 1e-3


@dataclass(frozen=True)
class RefineLevel:
    """One refinement level: the corridor's half-width and node spacing [km], the voyage time [h] on it and the
    arcs costed."""

    half_width_km: float
    spacing_km: float
    voyage_time_h: float
    arcs_evaluated: int


def _check_n_nodes(n_nodes: int) -> None:
    if isinstance(n_nodes, bool) or not isinstance(n_nodes, int) or n_nodes < 3 or n_nodes % 2 == 0:
        raise GridError(f"n_nodes must be an odd whole number >= 3 (got {n_nodes!r})")


def corridor_grid(grid: Grid, centre_km: npt.ArrayLike, *, half_width_km: float, n_nodes: int = CORRIDOR_NODES) -> Grid:
    """A grid on ``grid``'s rank lines with ``n_nodes`` nodes across ``centre_km[k] +- half_width_km`` on rank k.

    Every node joins every node of the next rank whose lateral offset differs by at most
    ``tan(max_deviation_deg) * rank_spacing_km`` (every node, when ``grid`` has no ``max_deviation_deg``); the start
    and the finish join the nodes ``grid``'s rule allows (a start line's points join every node).

    Parameters
    ----------
    grid : The grid whose course, ranks, start points and finish line the corridor keeps.
    centre_km : Lateral offset of the corridor's middle on each rank [km] (positive to starboard), (n_ranks,).
    half_width_km : Distance from the middle to the outermost nodes [km] (> 0).
    n_nodes : Nodes across the corridor (odd, >= 3).

    Examples
    --------
    >>> from pyroute_rel.routing.grid import make_grid
    >>> g = make_grid((-12.0, 45.0), (-60.0, 17.5), n_ranks=9, n_nodes=5)
    >>> cols = np.array([2, 3, 3, 2, 1, 2, 2, 2, 2])[:, None]  # a track through the grid's nodes
    >>> c = corridor_grid(g, g.offset_km[cols[:, 0]], half_width_km=g.spacing_km, n_nodes=9)
    >>> ranks = np.arange(9)[:, None]  # the middle node is the track, the last one a node spacing to starboard
    >>> same = np.allclose(c.lon_deg[:, [4, 8]], g.lon_deg[ranks, np.hstack([cols, cols + 1])])
    >>> c.spacing_km / g.spacing_km, same
    (0.25, True)
    """
    centre = np.asarray(centre_km, dtype=np.float64)
    if centre.shape != (grid.n_ranks,) or not np.all(np.isfinite(centre)):
        raise GridError(
            f"centre_km must be {grid.n_ranks} finite offsets [km], one per rank (got shape {centre.shape})"
        )
    _check_n_nodes(n_nodes)
    if not (np.isfinite(half_width_km) and half_width_km > 0.0):
        raise GridError(f"half_width_km must be a positive number of km (got {half_width_km!r})")
    reach = float(np.max(np.abs(centre))) + half_width_km
    if reach > 0.25 * np.pi * EARTH_RADIUS_KM:
        raise GridError(
            f"the corridor reaches {reach:.0f} km from the great circle: at most 5000 km (ranks would "
            "converge), as for any grid"
        )
    offset = np.linspace(-half_width_km, half_width_km, n_nodes)
    node = centre[:, None] + offset[None, :]  # offset of every node from the great circle [km]
    lon, lat = rank_points(grid.start, grid.finish, node)
    every = np.ones(n_nodes, dtype=bool)
    start_valid, finish_valid, rank_valid = every, every.copy(), None
    if grid.max_deviation_deg is not None:  # the grid's arcs stay within max_deviation_deg: so do the corridor's
        reach = np.tan(np.radians(grid.max_deviation_deg)) * grid.rank_spacing_km
        slack = 1e-6 * max(grid.spacing_km, 1e-3)  # the previous track's arcs sit exactly at the limit
        rank_valid = np.abs(node[1:, :, None] - node[:-1, None, :]) <= reach + slack  # (rank, dst, src)
        if grid.start_lon is None:
            start_valid = np.abs(node[0]) <= max(reach, grid.spacing_km / 2.0) + slack
        finish_valid = np.abs(node[-1]) <= max(reach, grid.spacing_km / 2.0) + slack
    return Grid(
        start=grid.start,
        finish=grid.finish,
        lon_deg=lon,
        lat_deg=lat,
        offset_km=offset,
        route_length_km=grid.route_length_km,
        rank_spacing_km=grid.rank_spacing_km,
        spacing_km=float(offset[1] - offset[0]),
        max_deviation_deg=grid.max_deviation_deg,
        band=n_nodes - 1,
        src_index=np.broadcast_to(np.arange(n_nodes, dtype=np.intp), (n_nodes, n_nodes)).copy(),
        arc_valid=np.ones((n_nodes, n_nodes), dtype=bool),
        start_valid=start_valid,
        finish_valid=finish_valid,
        start_lon=grid.start_lon,
        start_lat=grid.start_lat,
        finish_line=grid.finish_line,
        centre_km=centre,
        rank_valid=rank_valid,
    )


def track_offsets_km(grid: Grid, result: DPResult) -> FloatArray:
    """Lateral offset [km] of the DP track on every rank, (n_ranks,); ranks past a finish-line crossing repeat the
    last point's offset (a corridor there is never reached by a better track anyway)."""
    if not isinstance(result, DPResult) or result.arrival_h.shape != (grid.n_ranks, grid.n_nodes):
        raise GridError(f"result must be the DPResult of this grid ({grid.n_ranks} ranks x {grid.n_nodes} nodes)")
    nodes = result.path()
    offsets = grid.node_offsets_km()
    if nodes.size == 0:
        raise GridError("the track crosses the finish line before the first rank: nothing to refine")
    out = np.empty(grid.n_ranks)
    out[: nodes.size] = offsets[np.arange(nodes.size), nodes]
    out[nodes.size :] = out[nodes.size - 1]
    return out


def refine(
    grid: Grid,
    problem: RoutingProblem,
    result: DPResult,
    *,
    levels: int,
    problem_for: Callable[[Grid], RoutingProblem] | None = None,
    n_nodes: int = CORRIDOR_NODES,
) -> tuple[Grid, RoutingProblem, DPResult, list[RefineLevel]]:
    """Refine a DP track ``levels`` times (see the module notes).

    Parameters
    ----------
    grid, problem, result : The grid routed on, its problem and DP result (a feasible track).
    levels : Number of corridor solves (>= 1).
    problem_for : The routing problem for a corridor grid. Default: ``problem`` itself, which suits problems
        without obstacles; with an obstacle mask (it belongs to one grid) pass a builder that makes the corridor's
        own (:func:`pyroute_rel.obstacles.mask.obstacle_mask` with ``parent=grid`` reuses the grid's land). Keep
        ``samples`` equal to ``problem``'s, so an arc costs the same in both.
    n_nodes : Nodes across each corridor (odd, >= 3).

    Returns
    -------
    The best corridor grid, its problem and DP result (the input grid, ``problem`` and ``result`` when no level
    improved), and one :class:`RefineLevel` per level solved (fewer than ``levels`` once the corridors would be
    finer than :data:`MIN_SPACING_KM`). A level that would lengthen the voyage (possible
    only with costs that are not FIFO, see :mod:`pyroute_rel.routing.solve`) ends the refinement.
    """
    if isinstance(levels, bool) or not isinstance(levels, int) or levels < 1:
        raise GridError(f"refine levels must be a whole number >= 1 (got {levels!r})")
    _check_n_nodes(n_nodes)
    if problem_for is not None:
        check_callable(problem_for, "refine: problem_for", GridError)
    for name, value, kind in (("grid", grid, Grid), ("problem", problem, RoutingProblem), ("result", result, DPResult)):
        if not isinstance(value, kind):
            raise GridError(f"refine: {name} must be a {kind.__name__} (got {type(value).__name__})")
    if not np.isfinite(result.finish_h):
        raise GridError("result has no route to refine (the finish is unreachable on the grid)")
    half = FIRST_HALF_WIDTH * grid.spacing_km
    history: list[RefineLevel] = []
    best = (grid, problem, result)
    for _ in range(levels):
        if 2.0 * half / (n_nodes - 1) < MIN_SPACING_KM:  # nothing left to gain: stop
            break
        corridor = corridor_grid(best[0], track_offsets_km(best[0], best[2]), half_width_km=half, n_nodes=n_nodes)
        sub = problem if problem_for is None else problem_for(corridor)
        res = forward_dp(corridor, sub)
        history.append(
            RefineLevel(
                half_width_km=half,
                spacing_km=corridor.spacing_km,
                voyage_time_h=float(res.finish_h),
                arcs_evaluated=int(res.arcs_evaluated),
            )
        )
        if not res.finish_h <= best[2].finish_h:
            # the previous track is a path of the corridor, so under FIFO costs the DP finds it or better; costs
            # that are not FIFO (an arc that opens later, without waiting) can make the earliest arrival worse
            break
        nodes = res.path()
        if not np.any((nodes == 0) | (nodes == n_nodes - 1)):  # inside the corridor: narrow it
            half /= SHRINK
        best = (corridor, sub, res)
    return best[0], best[1], best[2], history
