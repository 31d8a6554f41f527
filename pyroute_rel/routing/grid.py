"""The great-circle rank digraph (Philpott & Mason 2001; Dickson et al. 2018, section 2.2).

``n_ranks`` ranks are laid at equal steps along the great circle from start to finish. Each rank is a
line of ``n_nodes`` nodes on the great circle *perpendicular* to the route at the rank's centre, spaced
``spacing_km`` apart, with the route's great circle on the middle node when ``n_nodes`` is odd. Arcs join
each node to nodes of the next rank; the start joins the first rank and the last rank joins the finish.

Two settings are independent (unlike the paper's square grid, where both equal route length / (n_ranks+1)):

- the **rank spacing** (distance between consecutive ranks along the route) follows from ``n_ranks``;
- the **lateral spacing** ``spacing_km`` between nodes of a rank, and so the domain half-width
  ``(n_nodes - 1) / 2 * spacing_km``.

Arcs may be **banded**: with ``max_deviation_deg`` an arc may deviate at most that angle from the rank
direction, so node ``i`` of one rank joins only nodes ``j`` with
``|j - i| * spacing_km <= tan(max_deviation_deg) * rank_spacing_km`` (``2k + 1`` nodes instead of all ``n``).
Without it every node joins every node of the next rank, as in the paper.

Arc storage: for each destination node ``j`` of a rank, ``src_index[j, w]`` (``w < width``) is a source node
of the previous rank and ``arc_valid[j, w]`` says whether that arc exists. The same lateral pattern serves
every pair of consecutive ranks, so the DP gathers over a dense ``(n_nodes, width)`` array per rank.

References
----------
Philpott, A. and Mason, A. (2001). Optimising yacht routes under uncertainty. Proc. 15th Chesapeake Sailing
Yacht Symposium.
Dickson, T., Blake, J. and Sear, D. (2018). Reliability informed routing for Autonomous Sailing Craft.
Proc. International Robotic Sailing Conference 2018.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from pyroute_rel import geodesy
from pyroute_rel.errors import GridError, brief, check_numbers
from pyroute_rel.resources import MemoryEstimate, check_budget, resident_bytes

if TYPE_CHECKING:
    import networkx as nx

__all__ = [
    "Grid",
    "GridCache",
    "ObstacleCache",
    "make_grid",
    "plan_grid",
    "rank_points",
    "auto_samples",
    "widened",
    "LAYOUTS",
    "START",
    "FINISH",
]

#: Most candidate arcs a grid may have (n_ranks x n_nodes x arcs per node): routing costs about 150-300 bytes per
#: arc at its peak, so 40 M arcs take 6-12 GB (the paper's square 320 x 320, 32.8 M arcs, routes in 1.1 GB without
#: failure model and samples). Larger grids are refused before anything is allocated.
MAX_ARCS = 40_000_000
#: Bytes per node while a grid's nodes are placed (:func:`rank_points`: offsets, rank centres, courses and the
#: destination points' trigonometry, about eight float64 arrays of one value per node).
NODE_BYTES = 64

#: networkx node labels of the start and finish nodes; other nodes are ``(rank, node)`` tuples.
START = "start"
FINISH = "finish"

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.intp]
BoolArray = npt.NDArray[np.bool_]


@dataclass
class ObstacleCache:
    """What obstacle masks (:mod:`pyroute_rel.obstacles.mask`) learnt about one grid's arcs for one set of
    obstacles: nothing here depends on time (zones' windows are applied afterwards).

    Attributes
    ----------
    land : ``(region, land)``: the polygon [deg] holding every arc of the grid (None across the antimeridian) and
        the (grown) land that can touch the arcs; None until first read.
    ranks : Per rank ``k``: ``(known, hit, zone_bits)`` of the arcs into rank ``k`` (shape of ``grid.arcs(k)``'s
        ``src``): which arcs were tested, which touch land or a zone without a window, and a bit per zone with a
        window they touch.
    swept : True once every arc was tested at once by rank-pair shadows (see :mod:`pyroute_rel.obstacles.strips`).
    """

    land: tuple[Any, Any] | None = None
    ranks: dict[int, tuple[BoolArray, BoolArray, npt.NDArray[np.uint64]]] = field(default_factory=dict)
    swept: bool = False


@dataclass
class GridCache:
    """Data derived from a grid, computed on first use and kept with it (what an arc touches never depends on
    time, so routing the same grid again reuses them).

    Attributes
    ----------
    node_xyz : Unit vectors of the nodes, shape (n_ranks, n_nodes, 3), or None until first used.
    geometry : Per (rank ``k``, samples per arc): the :class:`~pyroute_rel.routing.cost.ArcGeometry` of the arcs into
        rank ``k`` (:func:`pyroute_rel.routing.solve.grid_geometry`).
    crossings : Per rank ``k``: the fraction along each arc into rank ``k`` where it crosses the finish line
        (NaN: no crossing).
    obstacles : Per obstacle set (:meth:`pyroute_rel.obstacles.mask.Avoid.key`): an :class:`ObstacleCache`.
    """

    node_xyz: FloatArray | None = None
    geometry: dict[tuple[int, int], Any] = field(default_factory=dict)
    crossings: dict[int, FloatArray] = field(default_factory=dict)
    obstacles: dict[str, ObstacleCache] = field(default_factory=dict)

    def obstacles_for(self, key: str) -> ObstacleCache:
        """The :class:`ObstacleCache` of an obstacle set, made empty on first use."""
        return self.obstacles.setdefault(key, ObstacleCache())


@dataclass(frozen=True, eq=False)
class Grid:
    """A rank digraph between a start and a finish. Build it with :func:`make_grid`.

    Attributes
    ----------
    start, finish : (lon, lat) [deg].
    lon_deg, lat_deg : Node positions, shape (n_ranks, n_nodes) [deg]; node 0 lies to port (left) of the
        route's direction, node n_nodes - 1 to starboard.
    offset_km : Signed lateral offset of each node index from the great circle [km], shape (n_nodes,)
        (positive to starboard).
    route_length_km : Great-circle distance start → finish [km].
    rank_spacing_km : Distance between consecutive ranks along the great circle [km].
    spacing_km : Lateral spacing between nodes of a rank [km].
    max_deviation_deg : Maximum angle of an arc from the rank direction [deg], or None (all-to-all).
    band : Largest index offset |j - i| of an arc between consecutive ranks.
    src_index, arc_valid : Arc pattern between consecutive ranks, shape (n_nodes, width).
    start_valid, finish_valid : Which first-rank nodes the start joins / last-rank nodes join the finish.
    start_lon, start_lat : Start points [deg] (a start line sampled at the lateral spacing), or None for the
        single point ``start``. The craft may start from any of them at the departure time.
    finish_line : End points [deg] of a finish line (a great-circle segment through ``finish``), or None.
        With a line the voyage ends where a route first crosses it.
    centre_km : For a corridor grid (:func:`pyroute_rel.routing.refine.corridor_grid`), the lateral offset of each
        rank's middle [km], shape (n_ranks,): node i of rank k lies ``centre_km[k] + offset_km[i]`` from the great
        circle. None for grids centred on the great circle.
    rank_valid : Optional per-rank arc pattern, shape (n_ranks - 1, n_nodes, width): which arcs into rank k exist is
        ``rank_valid[k - 1]`` instead of ``arc_valid`` (corridor grids, whose ranks are shifted differently, keep
        the arcs within ``max_deviation_deg`` this way).
    cache : Data derived from the grid on first use (:class:`GridCache`); not an argument, not compared.
    """

    start: tuple[float, float]
    finish: tuple[float, float]
    lon_deg: FloatArray
    lat_deg: FloatArray
    offset_km: FloatArray
    route_length_km: float
    rank_spacing_km: float
    spacing_km: float
    max_deviation_deg: float | None
    band: int
    src_index: IntArray
    arc_valid: BoolArray
    start_valid: BoolArray
    finish_valid: BoolArray
    start_lon: FloatArray | None = None
    start_lat: FloatArray | None = None
    finish_line: tuple[tuple[float, float], tuple[float, float]] | None = None
    centre_km: FloatArray | None = None
    rank_valid: BoolArray | None = None
    cache: GridCache = field(default_factory=GridCache, init=False, repr=False, compare=False)

    @property
    def n_ranks(self) -> int:
        """Number of ranks."""
        return int(self.lon_deg.shape[0])

    @property
    def n_nodes(self) -> int:
        """Number of nodes per rank."""
        return int(self.lon_deg.shape[1])

    @property
    def width(self) -> int:
        """Number of candidate source nodes per destination node (columns of ``src_index``)."""
        return int(self.src_index.shape[1])

    @property
    def half_width_km(self) -> float:
        """Distance from the great circle (a corridor's middle) to the outermost node of a rank [km]."""
        return float(np.max(np.abs(self.offset_km)))

    def node_offsets_km(self) -> FloatArray:
        """Signed lateral offset of every node from the great circle [km], shape (n_ranks, n_nodes)."""
        centre = np.zeros(self.n_ranks) if self.centre_km is None else self.centre_km
        return centre[:, None] + self.offset_km[None, :]

    @property
    def aspect(self) -> float:
        """Rank spacing / lateral spacing (1 for the paper's square grid)."""
        return self.rank_spacing_km / self.spacing_km

    @property
    def n_arcs(self) -> int:
        """Number of arcs in the digraph, start and finish arcs included."""
        inner = (
            int(self.arc_valid.sum()) * (self.n_ranks - 1) if self.rank_valid is None else int(self.rank_valid.sum())
        )
        return inner + int(self.start_pattern.sum()) + int(self.finish_valid.sum())

    @property
    def start_points(self) -> tuple[FloatArray, FloatArray]:
        """Start points [deg]: the start line's samples, or the single start."""
        if self.start_lon is None or self.start_lat is None:
            return np.array([self.start[0]]), np.array([self.start[1]])
        return self.start_lon, self.start_lat

    @property
    def start_pattern(self) -> BoolArray:
        """Which start points join which first-rank nodes, shape (n_nodes, n_start_points)."""
        n_start = self.start_points[0].size
        if n_start == 1:
            return self.start_valid[:, None]
        return np.ones((self.n_nodes, n_start), dtype=bool)

    def distance_to_finish_nm(self, lon_deg: float, lat_deg: float) -> float:
        """How far a point is from the finish [nm]: from the finish line (the nearest point of its great-circle
        segment) when the grid has one, else from the finish point.

        >>> g = make_grid((0.0, 0.0), (2.0, 0.0), n_ranks=4, n_nodes=3, spacing_km=10.0)
        >>> round(g.distance_to_finish_nm(1.0, 0.0), 3)  # one degree of the equator: 60 nm
        60.04
        """
        if self.finish_line is None:
            return geodesy.distance_to_segment_nm(lon_deg, lat_deg, self.finish)
        return geodesy.distance_to_segment_nm(lon_deg, lat_deg, *self.finish_line)

    def describe(self) -> dict[str, Any]:
        """JSON-ready summary of the grid's geometry."""
        return {
            "n_ranks": self.n_ranks,
            "n_nodes": self.n_nodes,
            "spacing_km": self.spacing_km,
            "rank_spacing_km": self.rank_spacing_km,
            "half_width_km": self.half_width_km,
            "max_deviation_deg": self.max_deviation_deg,
            "band": self.band,
            "n_arcs": self.n_arcs,
        }

    def pattern(self, k: int) -> tuple[IntArray, BoolArray]:
        """Arc pattern into rank k: source index of each candidate arc and whether it exists, shape (n_dst, width)."""
        if isinstance(k, bool) or not isinstance(k, int | np.integer) or not 0 <= k <= self.n_ranks:
            raise GridError(f"rank index must be a whole number in [0, {self.n_ranks}] (got {brief(k)})")
        if k == 0:
            pattern = self.start_pattern
            return np.broadcast_to(np.arange(pattern.shape[1], dtype=np.intp)[None, :], pattern.shape), pattern
        if k == self.n_ranks:
            return np.arange(self.n_nodes, dtype=np.intp)[None, :], self.finish_valid[None, :]
        return self.src_index, (self.arc_valid if self.rank_valid is None else self.rank_valid[k - 1])

    def arcs(self, k: int) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, IntArray, BoolArray]:
        """Arcs into rank ``k`` (``k = 0`` from the start; ``k = n_ranks`` into the finish).

        Returns ``(lon0, lat0, lon1, lat1, src, valid)``: end points [deg] of shape (n_dst, width), the
        source node index of each arc, and whether the arc exists.
        """
        src, valid = self.pattern(k)
        if k == 0:
            s_lon, s_lat = self.start_points
            return (
                np.broadcast_to(s_lon[None, :], src.shape),
                np.broadcast_to(s_lat[None, :], src.shape),
                self.lon_deg[0][:, None],
                self.lat_deg[0][:, None],
                src,
                valid,
            )
        if k == self.n_ranks:
            return (
                self.lon_deg[-1][None, :],
                self.lat_deg[-1][None, :],
                np.full((1, self.n_nodes), self.finish[0]),
                np.full((1, self.n_nodes), self.finish[1]),
                src,
                valid,
            )
        return (
            self.lon_deg[k - 1][src],
            self.lat_deg[k - 1][src],
            np.broadcast_to(self.lon_deg[k][:, None], src.shape),
            np.broadcast_to(self.lat_deg[k][:, None], src.shape),
            src,
            valid,
        )

    def _weights(self, weight: Any) -> list[FloatArray]:
        """Arc weights per rank for :meth:`to_networkx`: one array of numbers per rank 0 .. n_ranks, each of the
        shape of that rank's arcs, or GridError."""
        if isinstance(weight, str | bytes | Mapping) or not isinstance(weight, Sequence | np.ndarray):
            raise GridError(f"weight must be a list of n_ranks + 1 arrays (got {brief(weight)})")
        if len(weight) != self.n_ranks + 1:
            raise GridError(f"weight must hold n_ranks + 1 = {self.n_ranks + 1} arrays (got {len(weight)})")
        out = []
        for k, w in enumerate(weight):
            arr = check_numbers(w, f"weight[{k}]", GridError, missing=False, infinite=True)
            shape = self.pattern(k)[1].shape
            if arr.shape != shape:
                raise GridError(f"weight[{k}] must have the shape {shape} of the arcs into rank {k} (got {arr.shape})")
            out.append(arr)
        return out

    def to_networkx(self, weight: npt.ArrayLike | None = None) -> nx.DiGraph:
        """Export the digraph to networkx.

        Nodes are ``"start"``, ``"finish"`` and ``(rank, node)`` tuples with ``lon``/``lat`` attributes.

        Parameters
        ----------
        weight : Optional arc weights, a sequence of ``n_ranks + 1`` arrays as returned per rank by
            :func:`pyroute_rel.routing.cost.arc_costs` (shape of :meth:`arcs`' outputs); stored as the edge
            attribute ``"weight"`` (non-finite weights drop the edge).
        """
        import networkx as nx

        g = nx.DiGraph()
        g.add_node(START, lon=self.start[0], lat=self.start[1])
        g.add_node(FINISH, lon=self.finish[0], lat=self.finish[1])
        for r in range(self.n_ranks):
            for i in range(self.n_nodes):
                g.add_node((r, i), lon=float(self.lon_deg[r, i]), lat=float(self.lat_deg[r, i]))
        weights = None if weight is None else self._weights(weight)
        for k in range(self.n_ranks + 1):
            *_, src, valid = self.arcs(k)
            w = None if weights is None else np.asarray(weights[k], dtype=float)
            for j, col in zip(*np.nonzero(valid), strict=True):
                i = int(src[j, col])
                u = START if k == 0 else (k - 1, i)
                v = FINISH if k == self.n_ranks else (k, int(j))
                if w is None:
                    g.add_edge(u, v)
                elif np.isfinite(w[j, col]):
                    g.add_edge(u, v, weight=float(w[j, col]))
        return g


def widened(layout: str, grid: Grid) -> tuple[str, dict[str, Any]]:
    """The grid twice as wide as ``grid``: the command-line option that asks for it and the scenario settings
    (:meth:`Scenario.with_options <pyroute_rel.scenario.Scenario.with_options>`) -- the angular layout's half-width
    doubled, or the square layout's nodes (``2 n - 1`` at the same spacing)."""
    if layout == "angular":
        hw = 2.0 * grid.half_width_km
        return f"--half-width-km {hw:.0f}", {"half_width_km": hw}
    return f"--n-nodes {2 * grid.n_nodes - 1}", {"n_nodes": 2 * grid.n_nodes - 1}


def make_grid(
    start: tuple[float, float],
    finish: tuple[float, float],
    *,
    n_ranks: int,
    n_nodes: int,
    spacing_km: float | None = None,
    max_deviation_deg: float | None = None,
    start_line: tuple[tuple[float, float], tuple[float, float]] | None = None,
    finish_line: tuple[tuple[float, float], tuple[float, float]] | None = None,
) -> Grid:
    """Build the rank digraph between two points.

    Parameters
    ----------
    start, finish : (lon, lat) [deg].
    n_ranks : Number of ranks (>= 1).
    n_nodes : Nodes per rank (>= 1; odd puts the great circle on the middle node).
    spacing_km : Lateral node spacing [km]. Default: the rank spacing, route length / (n_ranks + 1), so
        the domain is square as in the paper.
    max_deviation_deg : Largest angle [deg] in (0, 90) between an arc and the rank direction; None joins
        every node to every node of the next rank. Also limits the start and finish arcs.
    start_line : Optional start line ((lon, lat), (lon, lat)) [deg]: the craft may start anywhere on it
        (sampled at about the lateral spacing); ``start`` is then the grid's origin, usually the line's middle.
    finish_line : Optional finish line ((lon, lat), (lon, lat)) [deg]; the voyage ends at its first crossing.

    Examples
    --------
    >>> g = make_grid((-12.0, 45.0), (-60.0, 17.5), n_ranks=9, n_nodes=5)
    >>> g.lon_deg.shape, round(g.rank_spacing_km, 1) == round(g.spacing_km, 1)
    ((9, 5), True)
    >>> make_grid((-12.0, 45.0), (-60.0, 17.5), n_ranks=9, n_nodes=9, max_deviation_deg=50.0).band
    1
    """
    for name, value in (("n_ranks", n_ranks), ("n_nodes", n_nodes)):
        if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
            raise GridError(f"{name} must be a whole number >= 1 (got {value!r})")
    lon_s, lat_s = _checked_point(start, "start")
    lon_f, lat_f = _checked_point(finish, "finish")
    length = float(geodesy.distance_km(lon_s, lat_s, lon_f, lat_f))
    if length < 1e-6:
        raise GridError(f"start and finish must differ (both at lon {lon_s:g}, lat {lat_s:g})")
    if length > 0.99 * math.pi * geodesy.EARTH_RADIUS_KM:
        raise GridError("start and finish are (nearly) antipodal: the great circle between them is not unique")
    rank_spacing = length / (n_ranks + 1)
    if spacing_km is None:
        spacing_km = rank_spacing
    if not (_real(spacing_km) and math.isfinite(spacing_km) and spacing_km > 0):
        raise GridError(f"spacing_km must be a positive number of km (got {spacing_km!r})")
    spacing_km = float(spacing_km)
    half = (n_nodes - 1) / 2.0 * spacing_km
    if half > 0.25 * math.pi * geodesy.EARTH_RADIUS_KM:
        raise GridError(
            f"grid half-width {half:.0f} km is too wide (ranks would converge): use fewer nodes or a smaller "
            "spacing_km (at most 5000 km from the great circle)"
        )
    if max_deviation_deg is not None:
        if not (_real(max_deviation_deg) and 0.0 < max_deviation_deg < 90.0):
            raise GridError(f"max_deviation_deg must be in (0, 90) [deg] (got {max_deviation_deg!r})")
        band = int(math.floor(math.tan(math.radians(max_deviation_deg)) * rank_spacing / spacing_km + 1e-9))
        band = min(band, n_nodes - 1)
    else:
        band = n_nodes - 1

    width = min(2 * band + 1, n_nodes)
    _check_size(n_ranks, n_nodes, width)  # before the nodes are placed: a huge grid is refused at once
    offset = ((np.arange(n_nodes) - (n_nodes - 1) / 2.0) * spacing_km).astype(np.float64)
    lon, lat = rank_points((lon_s, lat_s), (lon_f, lat_f), np.broadcast_to(offset, (n_ranks, n_nodes)))

    j = np.arange(n_nodes)
    first = np.clip(j - band, 0, n_nodes - width)
    src = first[:, None] + np.arange(width)[None, :]
    valid = np.abs(src - j[:, None]) <= band
    if max_deviation_deg is None:
        start_valid = np.ones(n_nodes, dtype=bool)
    else:
        reach = math.tan(math.radians(max_deviation_deg)) * rank_spacing + 1e-6 * spacing_km
        start_valid = np.abs(offset) <= max(reach, spacing_km / 2.0)
    s_lon = s_lat = None
    if start_line is not None:
        (a_lon, a_lat), (b_lon, b_lat) = _checked_line(start_line, "start_line")
        line_km = float(geodesy.distance_km(a_lon, a_lat, b_lon, b_lat))
        n_start = int(min(max(2, math.ceil(line_km / spacing_km) + 1), 401))
        s_lon, s_lat = geodesy.intermediate_point(a_lon, a_lat, b_lon, b_lat, np.linspace(0.0, 1.0, n_start))
    fin_line = None
    if finish_line is not None:
        a, b = _checked_line(finish_line, "finish_line")
        if float(geodesy.distance_km(*a, *b)) < 1e-3:
            raise GridError("finish_line end points must differ")
        fin_line = (a, b)
    return Grid(
        start=(lon_s, lat_s),
        finish=(lon_f, lat_f),
        lon_deg=lon,
        lat_deg=lat,
        offset_km=offset,
        route_length_km=length,
        rank_spacing_km=rank_spacing,
        spacing_km=spacing_km,
        max_deviation_deg=None if max_deviation_deg is None else float(max_deviation_deg),
        band=band,
        src_index=src.astype(np.intp),
        arc_valid=valid,
        start_valid=start_valid,
        finish_valid=start_valid.copy(),
        start_lon=s_lon,
        start_lat=s_lat,
        finish_line=fin_line,
    )


def _check_size(n_ranks: int, n_nodes: int, width: int) -> None:
    """Refuse a grid with more than :data:`MAX_ARCS` candidate arcs, or whose nodes alone exceed the memory budget."""
    if n_ranks * n_nodes * width > MAX_ARCS:
        raise GridError(
            f"the grid would have {n_ranks * n_nodes * width / 1e6:.0f} M candidate arcs ({n_ranks} ranks x "
            f"{n_nodes} nodes x {width} arcs per node), more than the {MAX_ARCS / 1e6:.0f} M that fit in memory: "
            "use fewer ranks or nodes, a larger spacing_km (a smaller aspect) or a smaller max_deviation_deg"
        )
    check_budget(
        MemoryEstimate(
            parts={"process": resident_bytes(), "grid nodes": NODE_BYTES * n_ranks * n_nodes},
            what=f"grid {n_ranks} x {n_nodes}",
        ),
        knobs="use fewer ranks or nodes",
    )


def rank_points(
    start: tuple[float, float], finish: tuple[float, float], offset_km: npt.ArrayLike
) -> tuple[FloatArray, FloatArray]:
    """Points on the rank lines of the course start -> finish at given lateral offsets.

    Rank k (of ``n_ranks``, the first axis of ``offset_km``) is the great circle perpendicular to the course at the
    fraction (k + 1) / (n_ranks + 1) of its length; an offset [km] is the distance along it, positive to starboard.

    Returns lon, lat [deg] of ``offset_km``'s shape (n_ranks, ...).

    >>> lon, lat = rank_points((0.0, 0.0), (2.0, 0.0), [[0.0, 111.19]])  # one rank, halfway along the equator
    >>> [round(float(v), 3) for v in (*lon[0], *lat[0])]
    [1.0, 1.0, 0.0, -1.0]
    """
    off = np.asarray(offset_km, dtype=np.float64)
    if off.ndim < 1 or off.shape[0] < 1 or not np.all(np.isfinite(off)):
        raise GridError(f"offset_km must be finite offsets [km] with one row per rank (got shape {off.shape})")
    length = float(geodesy.distance_km(start[0], start[1], finish[0], finish[1]))
    if not (1e-6 < length < 0.99 * math.pi * geodesy.EARTH_RADIUS_KM):
        raise GridError(f"start {list(start)} and finish {list(finish)} must differ and not be antipodal")
    n_ranks = off.shape[0]
    fractions = np.arange(1, n_ranks + 1) / (n_ranks + 1)
    c_lon, c_lat = geodesy.intermediate_point(start[0], start[1], finish[0], finish[1], fractions)
    course = geodesy.initial_bearing_deg(c_lon, c_lat, finish[0], finish[1])
    shape = (n_ranks,) + (1,) * (off.ndim - 1)
    return geodesy.destination_point(
        c_lon.reshape(shape), c_lat.reshape(shape), ((course + 90.0) % 360.0).reshape(shape), off
    )


def _real(x: Any) -> bool:
    """A real number (not a bool: ``True`` is no spacing)."""
    return isinstance(x, numbers.Real) and not isinstance(x, bool | np.bool_)


def _checked_line(line: Any, name: str) -> tuple[tuple[float, float], tuple[float, float]]:
    if isinstance(line, str) or not hasattr(line, "__len__") or len(line) != 2:
        raise GridError(f"{name} must be two (lon, lat) end points [deg] (got {line!r:.60})")
    return _checked_point(line[0], f"{name} end"), _checked_point(line[1], f"{name} end")


def _checked_point(p: Any, name: str) -> tuple[float, float]:
    try:
        lon, lat = (float(v) for v in p)
    except (TypeError, ValueError):
        raise GridError(f"{name} must be a pair [lon, lat] of numbers [deg] (got {p!r})") from None
    if not (-180.0 <= lon <= 180.0 and -90.0 <= lat <= 90.0) or not (math.isfinite(lon) and math.isfinite(lat)):
        raise GridError(f"{name} must have lon in [-180, 180] and lat in [-90, 90] [deg] (got {p!r})")
    if abs(lat) > 89.0:
        raise GridError(f"{name} latitude must be within 89 deg of the equator (got {lat:g})")
    return float(geodesy.wrap_lon(lon)), lat


#: Grid layouts: "square" is the paper's grid; "angular" refines the lateral spacing (see :func:`plan_grid`).
LAYOUTS = ("angular", "square")
#: Defaults of the angular layout, chosen by measurement (README, "Convergent discretisation").
DEFAULT_ASPECT = 6.0
DEFAULT_MAX_DEVIATION_DEG = 45.0
DEFAULT_HALF_WIDTH_KM = 1000.0
DEFAULT_N_RANKS = 160
#: Default spacing of weather samples along an arc [km] (see :func:`auto_samples`).
DEFAULT_SAMPLE_KM = 25.0


def auto_samples(grid: Grid, *, sample_km: float = DEFAULT_SAMPLE_KM, max_samples: int = 16) -> int:
    """Weather samples per arc so that samples along arcs between ranks are at most ``sample_km`` apart.

    A forbidden region narrower than the sample spacing can be crossed unseen by an arc; a count that follows
    the arc length (rather than a fixed count) keeps that blind spot the same size on every grid, which makes
    grid refinement converge monotonically (README, "Convergent discretisation").

    >>> g = make_grid((-12.0, 45.0), (-60.0, 17.5), n_ranks=160, n_nodes=161, max_deviation_deg=45.0)
    >>> auto_samples(g)  # arcs of up to sqrt(2) x 33.4 km
    2
    """
    # arcs up to 45 deg off the rank direction set the count: all of them on the default banded grid; on an
    # all-to-all grid the much longer sideways arcs (seldom optimal) would multiply the cost for nothing
    lateral = min(grid.band * grid.spacing_km, grid.rank_spacing_km)
    longest = math.hypot(grid.rank_spacing_km, lateral)
    return int(min(max(1, math.ceil(longest / sample_km - 1e-9)), max_samples))


def plan_grid(
    start: tuple[float, float],
    finish: tuple[float, float],
    *,
    layout: str = "angular",
    n_ranks: int | None = None,
    n_nodes: int | None = None,
    spacing_km: float | None = None,
    aspect: float | None = None,
    half_width_km: float | None = None,
    max_deviation_deg: float | None = None,
    start_line: tuple[tuple[float, float], tuple[float, float]] | None = None,
    finish_line: tuple[tuple[float, float], tuple[float, float]] | None = None,
) -> Grid:
    """Build a grid from user-level settings (what a scenario's ``[grid]`` table says).

    ``layout = "square"`` is the paper's grid: ``n_ranks`` ranks of ``n_nodes`` nodes, lateral spacing equal
    to the rank spacing unless ``spacing_km`` is given, every node joined to every node of the next rank unless
    ``max_deviation_deg`` is given.

    ``layout = "angular"`` (default) decouples the two spacings so that refinement converges:

    - rank spacing = route length / (n_ranks + 1) (``n_ranks`` default :data:`DEFAULT_N_RANKS`);
    - lateral spacing = ``spacing_km``, else rank spacing / ``aspect`` (default :data:`DEFAULT_ASPECT`);
    - half-width = ``half_width_km``, else :data:`DEFAULT_HALF_WIDTH_KM` (``n_nodes`` belongs to the square
      layout and is not used here);
    - nodes per rank = ``2 ceil(half-width / lateral spacing) + 1`` (the great circle on the middle node);
    - arcs banded to ``max_deviation_deg`` (default :data:`DEFAULT_MAX_DEVIATION_DEG`).

    Examples
    --------
    >>> g = plan_grid((-12.0, 45.0), (-60.0, 17.5), n_ranks=20, aspect=4.0, half_width_km=500.0)
    >>> g.n_nodes, g.band, round(g.aspect, 6)
    (17, 4, 4.0)
    """
    if not isinstance(layout, str) or layout not in LAYOUTS:
        raise GridError(f"layout must be one of {list(LAYOUTS)} (got {brief(layout)})")
    if n_nodes is not None and (isinstance(n_nodes, bool) or not isinstance(n_nodes, int | np.integer)):
        raise GridError(f"n_nodes must be a whole number (got {brief(n_nodes)})")  # checked even where unused
    if n_nodes is not None and n_nodes < 1:
        raise GridError(f"n_nodes must be a whole number >= 1 (got {n_nodes})")
    if aspect is not None and not (_real(aspect) and math.isfinite(aspect) and 0.01 <= aspect <= 1000.0):
        raise GridError(f"aspect (rank spacing / lateral spacing) must be in [0.01, 1000] (got {brief(aspect)})")
    if half_width_km is not None and not (_real(half_width_km) and math.isfinite(half_width_km) and half_width_km >= 0):
        raise GridError(f"half_width_km must be a non-negative number of km (got {brief(half_width_km)})")
    _checked_point(start, "start")  # before the angular layout measures the route with them
    _checked_point(finish, "finish")
    if layout == "square":
        return make_grid(
            start,
            finish,
            n_ranks=DEFAULT_N_RANKS if n_ranks is None else n_ranks,
            n_nodes=DEFAULT_N_RANKS if n_nodes is None else n_nodes,
            spacing_km=spacing_km,
            max_deviation_deg=max_deviation_deg,
            start_line=start_line,
            finish_line=finish_line,
        )
    n_ranks = DEFAULT_N_RANKS if n_ranks is None else n_ranks
    if isinstance(n_ranks, bool) or not isinstance(n_ranks, int | np.integer) or n_ranks < 1:
        raise GridError(f"n_ranks must be a whole number >= 1 (got {n_ranks!r})")
    length = float(geodesy.distance_km(start[0], start[1], finish[0], finish[1]))
    rank_spacing = length / (n_ranks + 1)
    if spacing_km is None:
        a = DEFAULT_ASPECT if aspect is None else aspect
        if not (_real(a) and math.isfinite(a) and 0.01 <= a <= 1000.0):
            raise GridError(f"aspect (rank spacing / lateral spacing) must be in [0.01, 1000] (got {a!r})")
        spacing_km = rank_spacing / float(a)
    if half_width_km is None:
        half_width_km = DEFAULT_HALF_WIDTH_KM
    if not (_real(half_width_km) and math.isfinite(half_width_km) and half_width_km >= 0):
        raise GridError(f"half_width_km must be a non-negative number of km (got {half_width_km!r})")
    if not (_real(spacing_km) and math.isfinite(spacing_km) and spacing_km > 0):
        raise GridError(f"spacing_km must be a positive number of km (got {spacing_km!r})")
    nodes = 2 * int(math.ceil(half_width_km / spacing_km - 1e-9)) + 1
    if nodes > 20001:
        raise GridError(
            f"{nodes} nodes per rank (half-width {half_width_km:.0f} km at {spacing_km:.3g} km spacing) is too many: "
            "lower aspect or half_width_km"
        )
    dev = DEFAULT_MAX_DEVIATION_DEG if max_deviation_deg is None else max_deviation_deg
    return make_grid(
        start,
        finish,
        n_ranks=n_ranks,
        n_nodes=nodes,
        spacing_km=spacing_km,
        max_deviation_deg=dev,
        start_line=start_line,
        finish_line=finish_line,
    )
