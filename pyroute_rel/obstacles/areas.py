"""Does this great-circle arc touch that area? The vectorised arc-versus-area test, for land and zones alike.

:func:`arcs_blocked` answers, vectorised over arrays of arcs, whether each arc touches a lon/lat geometry: the
land of :mod:`pyroute_rel.obstacles.land` or an exclusion zone of :mod:`pyroute_rel.obstacles.zones`. A geometry
is indexed once (:func:`area_index`, cached on its identity): cut into 1 deg tiles in an STRtree
(:func:`tiles_tree`, also what :mod:`pyroute_rel.obstacles.strips` tests whole rank pairs against) plus two
coarse rasters (cells that may touch it, cells wholly inside it) for a quick first pass. Nothing here is
queried per arc in a Python loop.

Geometry conventions
--------------------
- Positions are longitude/latitude [deg] on the sphere R = 6371.0088 km; geometries are shapely geometries
  in lon/lat, longitudes in [-180, 180].
- An arc is the shorter great-circle arc between its end points. It is tested as a polyline of points on
  the great circle at most ``samples_km`` apart (:func:`pyroute_rel.geodesy.gc_densify`); a straight lon/lat
  chord of length s departs from the great circle by about s^2 tan|lat| / (8 R): 0.14 m for s = 2 km at
  60 deg, so the test is exact to well under a metre while islets of any size are caught (the polyline, not
  only its vertices, is tested).
- Antimeridian: each arc is unwrapped so its longitudes are continuous (they may run past +-180); the
  parts past the seam are tested again shifted by 360 deg, so an arc from 179 E to 179 W is a 2 deg arc,
  never a 358 deg line. Polygons that cross the seam must be given split into pieces on either side of
  it (a MultiPolygon), as RFC 7946 recommends.

References
----------
Butler, H. et al. (2016). The GeoJSON Format. RFC 7946, doi:10.17487/RFC7946.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
import shapely

from pyroute_rel.errors import GridError, ScenarioError
from pyroute_rel.geodesy import from_xyz, gc_densify, to_xyz
from pyroute_rel.store import Held, current_store
from pyroute_rel.units import EARTH_RADIUS_KM

__all__ = [
    "arcs_blocked",
    "arc_caps",
    "area_index",
    "as_arcs",
    "blocked_flat",
    "checked_samples",
    "polygon_parts",
    "tiles_tree",
]

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

_TILE_DEG = 1.0  # tile size the geometry is cut into for the STRtree [deg]
_MAX_CELLS = 4_000_000  # most cells of the prefilter rasters
_MIN_CELL_DEG = 0.05  # smallest cell of the prefilter rasters [deg]
_BLOCK = 5  # cells per side of the blocks the inside raster is decided by first
_LEAF_KM = 25.0  # pieces of arc longer than this near the geometry are halved before the exact test [km]
_CHUNK_POINTS = 1_000_000  # densified points per exact-test chunk (bounds the memory)
_BATCH_ARCS = 65_536  # arcs per batch of the coarse pass
_SEGMENT_DEG = 0.05  # edges of the tiles are split to at most this [deg] (chords of great circles within 1 m)


Box = tuple[FloatArray, FloatArray, FloatArray, FloatArray]


def arc_caps(p0: FloatArray, p1: FloatArray) -> tuple[Box, FloatArray, FloatArray, FloatArray, FloatArray]:
    """A lon/lat box [deg] that surely contains each great-circle arc p0 -> p1.

    Every point of an arc lies within half its length h of its midpoint M, so the arc lies inside the
    spherical cap (M, h), whose exact box is lat +- h, lon +- asin(sin h / cos lat_M) (sin h is half the
    chord). Longitudes of the box are continuous around lon_M and may leave [-180, 180]; a cap over a
    pole spans all longitudes. A straight lon/lat segment between two points of the box stays in it, so
    the box also holds the densified polyline. The box is padded by 1e-9 deg against rounding.

    Trigonometry-light: it runs on millions of pieces of arc per call.

    Parameters
    ----------
    p0, p1 : End points of the arcs as unit vectors, shape (n, 3) (:func:`pyroute_rel.geodesy.to_xyz`).

    Returns
    -------
    box : (west, south, east, north) [deg], each of shape (n,).
    mid : Midpoints of the arcs as unit vectors, shape (n, 3).
    lon_m, lat_m : Midpoints [deg].
    length : Arc lengths [km].

    Examples
    --------
    >>> box, mid, lon_m, lat_m, length = arc_caps(to_xyz([-1.0], [0.0]), to_xyz([1.0], [0.0]))
    >>> [round(float(b[0]), 6) for b in box], round(float(length[0]), 3)
    ([-1.0, -1.0, 1.0, 1.0], 222.39)
    """
    x0, y0, z0 = p0[:, 0], p0[:, 1], p0[:, 2]
    x1, y1, z1 = p1[:, 0], p1[:, 1], p1[:, 2]
    sx, sy, sz = x0 + x1, y0 + y1, z0 + z1
    norm = np.sqrt(sx * sx + sy * sy + sz * sz)
    norm[norm == 0.0] = 1.0
    mx, my, mz = sx / norm, sy / norm, sz / norm
    dx, dy, dz = x1 - x0, y1 - y0, z1 - z0
    half = np.minimum(0.5 * np.sqrt(dx * dx + dy * dy + dz * dz), 1.0)  # sin of the half angle
    h = np.arcsin(half)
    rho = np.sqrt(mx * mx + my * my)  # cos(lat_M)
    lon_m, lat_m = np.degrees(np.arctan2(my, mx)), np.degrees(np.arctan2(mz, rho))
    h_deg = np.degrees(h) + 1e-9
    ratio = (half + 1e-11) / np.maximum(rho, 1e-300)
    dlon = np.degrees(np.arcsin(np.minimum(ratio, 1.0))) + 1e-9
    dlon[(ratio >= 1.0) | (np.abs(lat_m) + h_deg >= 90.0)] = 540.0
    box = (lon_m - dlon, np.maximum(lat_m - h_deg, -90.0), lon_m + dlon, np.minimum(lat_m + h_deg, 90.0))
    return box, np.column_stack([mx, my, mz]), lon_m, lat_m, 2.0 * h * EARTH_RADIUS_KM


def polygon_parts(geoms: Any) -> npt.NDArray[np.object_]:
    """The non-empty Polygons of any geometries with a positive area, as an object array (lines, points and empty
    parts dropped; MultiPolygons and collections taken apart).

    >>> parts = polygon_parts([shapely.MultiPolygon([shapely.box(0, 0, 1, 1), shapely.box(2, 0, 3, 1)]),
    ...                        shapely.LineString([(0, 0), (1, 1)]), shapely.Polygon()])
    >>> [p.area for p in parts]
    [1.0, 1.0]
    """
    parts = shapely.get_parts(np.asarray(geoms, dtype=object))
    if len(parts) == 0:
        return parts
    parts = parts[shapely.get_type_id(parts) == shapely.GeometryType.POLYGON]
    return parts[~shapely.is_empty(parts) & (shapely.area(parts) > 0.0)]


# --------------------------------------------------------------------------------------------------
# Arc tests
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class _Index:
    """A geometry cut into small tiles in an STRtree, plus two coarse rasters for a quick first pass.

    Cells are ``cell`` [deg] squares from the origin ``x0, y0``. ``touch`` and ``inside`` are 2-D prefix
    sums over the cells that touch the geometry and that lie wholly inside it, so whether a box meets a
    touching cell, or is covered by inside cells only, is four lookups; ``inside_mask`` is the raster.
    """

    tree: shapely.STRtree
    x0: float
    y0: float
    cell: float
    touch: npt.NDArray[np.int32]
    inside: npt.NDArray[np.int32]
    inside_mask: BoolArray

    @property
    def empty(self) -> bool:
        return bool(self.touch[-1, -1] == 0)

    def classify(self, box: Box) -> tuple[BoolArray, BoolArray, npt.NDArray[np.int32]]:
        """For boxes (w, s, e, n) [deg]: may touch the geometry, surely inside it, inside cells met."""
        maybe, sure, score = self._classify(*box)
        seam = np.flatnonzero((box[0] < -180.0) | (box[2] > 180.0))
        if seam.size:  # the part of a box past the antimeridian, shifted back by 360 deg
            w, s, e, n = (b[seam] for b in box)
            for shift in (-360.0, 360.0):
                mb, su, sc = self._classify(w + shift, s, e + shift, n)
                maybe[seam] |= mb
                sure[seam] |= su
                score[seam] += sc
        return maybe, sure, score

    def _classify(
        self, w: FloatArray, s: FloatArray, e: FloatArray, n: FloatArray
    ) -> tuple[BoolArray, BoolArray, npt.NDArray[np.int32]]:
        ny, nx = self.inside_mask.shape
        i0 = np.floor((w - self.x0) / self.cell)
        i1 = np.floor((e - self.x0) / self.cell)
        j0 = np.floor((s - self.y0) / self.cell)
        j1 = np.floor((n - self.y0) / self.cell)
        overlap = (i1 >= 0) & (i0 < nx) & (j1 >= 0) & (j0 < ny)
        within = (i0 >= 0) & (i1 < nx) & (j0 >= 0) & (j1 < ny)
        width = nx + 1
        a0 = np.clip(i0, 0, nx - 1).astype(np.intp)
        a1 = np.clip(i1, 0, nx - 1).astype(np.intp) + 1
        b0 = np.clip(j0, 0, ny - 1).astype(np.intp) * width
        b1 = (np.clip(j1, 0, ny - 1).astype(np.intp) + 1) * width
        corners = (b1 + a1, b0 + a1, b1 + a0, b0 + a0)
        t, ins = self.touch.ravel(), self.inside.ravel()
        n_touch = t[corners[0]] - t[corners[1]] - t[corners[2]] + t[corners[3]]
        n_inside = ins[corners[0]] - ins[corners[1]] - ins[corners[2]] + ins[corners[3]]
        maybe = overlap & (n_touch > 0)
        sure = within & (n_inside == (a1 - a0) * (b1 - b0) // width)
        return maybe, sure, np.where(overlap, n_inside, 0)

    def point_inside(self, lon: FloatArray, lat: FloatArray) -> BoolArray:
        """True where the point [deg] lies in a cell wholly inside the geometry."""
        ny, nx = self.inside_mask.shape
        i = np.floor((lon - self.x0) / self.cell)
        j = np.floor((lat - self.y0) / self.cell)
        ok = (i >= 0) & (i < nx) & (j >= 0) & (j < ny)
        flat = np.where(ok, j * nx + i, 0).astype(np.intp)
        return ok & self.inside_mask.ravel()[flat]


def _prefix_sum(mask: BoolArray) -> npt.NDArray[np.int32]:
    out = np.zeros((mask.shape[0] + 1, mask.shape[1] + 1), dtype=np.int32)
    out[1:, 1:] = mask.cumsum(0, dtype=np.int32).cumsum(1, dtype=np.int32)
    return out


#: Indexes and tile trees kept per geometry (the most recent), in the current store's shelves, found by the
#: geometry itself (:class:`~pyroute_rel.store.Held`: shapely hashes a geometry by its WKB, which for a coastline
#: of a few hundred thousand vertices costs milliseconds on every lookup).
KEPT_PER_SHELF = 32


def area_index(geometry: shapely.Geometry) -> _Index:
    """The cached :class:`_Index` of a geometry."""
    shelf = current_store().shelf("obstacles.indexes", limit=KEPT_PER_SHELF)
    return shelf.get_or_make(Held(geometry), lambda: _build_index(geometry))  # type: ignore[no-any-return]


def tiles_tree(geometry: shapely.Geometry) -> shapely.STRtree:
    """The geometry cut into 1 deg tiles, in an STRtree (cached on the geometry's identity).

    Edges longer than 0.05 deg are split first, so a tile's edges along the geometry's boundary depart from the
    great-circle chords between their vertices by under a metre (s^2 tan|lat| / (8 R)); the cut lines between
    tiles are not split (they are shared by neighbouring tiles and lie inside the geometry).
    """
    shelf = current_store().shelf("obstacles.trees", limit=KEPT_PER_SHELF)
    return shelf.get_or_make(Held(geometry), lambda: _build_tree(geometry))  # type: ignore[no-any-return]


def _build_tree(geometry: shapely.Geometry) -> shapely.STRtree:
    parts = shapely.get_parts(geometry)
    parts = parts[~shapely.is_empty(parts)] if len(parts) else parts
    if len(parts) == 0:
        return shapely.STRtree(parts)
    # edges are split before the cut, so each tile's own (coastline) edges are short and the cut lines between
    # tiles stay single segments (see pyroute_rel.obstacles.strips: edges count as great-circle chords there)
    return shapely.STRtree(_tiles(shapely.segmentize(parts, _SEGMENT_DEG)))


def _build_index(geometry: shapely.Geometry) -> _Index:
    parts = shapely.get_parts(geometry)
    parts = parts[~shapely.is_empty(parts)] if len(parts) else parts
    if len(parts) == 0:
        zero = np.zeros((2, 2), dtype=np.int32)
        return _Index(shapely.STRtree([]), 0.0, 0.0, 1.0, zero, zero, np.zeros((1, 1), dtype=bool))
    tree = tiles_tree(geometry)
    tiles = tree.geometries
    xmin, ymin, xmax, ymax = shapely.total_bounds(tiles)
    span = max(xmax - xmin, 1e-9) * max(ymax - ymin, 1e-9)
    cell = max(_MIN_CELL_DEG, math.sqrt(span / _MAX_CELLS))
    cell = 1.0 / math.floor(1.0 / cell) if cell < 1.0 else float(math.ceil(cell))  # aligned with the tiles
    x0, y0 = math.floor(xmin / cell) * cell, math.floor(ymin / cell) * cell
    nx, ny = math.floor((xmax - x0) / cell) + 1, math.floor((ymax - y0) / cell) + 1
    touch, inside = _raster_flags(parts, geometry, x0, y0, cell, nx, ny)
    return _Index(tree, x0, y0, cell, _prefix_sum(touch), _prefix_sum(inside), inside)


def _raster_flags(
    parts: npt.NDArray[np.object_], geometry: shapely.Geometry, x0: float, y0: float, cell: float, nx: int, ny: int
) -> tuple[BoolArray, BoolArray]:
    """Cells (ny, nx) that may touch the geometry, and cells wholly inside it, without a predicate per cell.

    The boundary (every ring, densified to half a cell) marks the cells its points fall in and their eight
    neighbours: a piece of boundary between two points half a cell apart cannot leave that 3 x 3 block, so every
    cell the boundary crosses is marked (and some more: a superset is safe, it only sends arcs to the exact
    test). A cell left unmarked holds no boundary, so it lies wholly inside or wholly outside and its centre
    tells which; a block of _BLOCK x _BLOCK unmarked cells is decided by one centre, the cells of the other
    blocks one by one (a few point-in-polygon tests per coastline cell, not one per cell of the raster).
    """
    r = _BLOCK
    my, mx = -(-ny // r) * r, -(-nx // r) * r  # padded to whole blocks; the padding is outside the box
    ring = shapely.segmentize(shapely.boundary(parts), 0.5 * cell)
    xy = shapely.get_coordinates(ring)
    i = np.clip(np.floor((xy[:, 0] - x0) / cell), 0, nx - 1).astype(np.intp)
    j = np.clip(np.floor((xy[:, 1] - y0) / cell), 0, ny - 1).astype(np.intp)
    mark = np.zeros((my + 2, mx + 2), dtype=bool)
    mark[j + 1, i + 1] = True
    edge = np.zeros((my, mx), dtype=bool)
    for dj in range(3):  # dilate by one cell in the eight directions
        for di in range(3):
            edge |= mark[dj : dj + my, di : di + mx]
    blocks = edge.reshape(my // r, r, mx // r, r)
    open_block = ~blocks.any(axis=(1, 3))
    bj, bi = np.nonzero(open_block)
    inside = np.zeros((my // r, r, mx // r, r), dtype=bool)
    whole = shapely.contains_xy(geometry, x0 + (bi + 0.5) * r * cell, y0 + (bj + 0.5) * r * cell)
    inside[bj[whole], :, bi[whole], :] = True
    fj, fi = np.nonzero(~edge & ~np.repeat(np.repeat(open_block, r, axis=0), r, axis=1))
    inside.reshape(my, mx)[fj, fi] = shapely.contains_xy(geometry, x0 + (fi + 0.5) * cell, y0 + (fj + 0.5) * cell)
    inside = inside.reshape(my, mx)[:ny, :nx]
    return edge[:ny, :nx] | inside, np.ascontiguousarray(inside)


def _tiles(parts: npt.NDArray[np.object_]) -> npt.NDArray[np.object_]:
    """Cut geometries on a ``_TILE_DEG`` grid so each STRtree entry is small (fast exact predicates).

    Cut first on an 8x coarser grid, so no single cut has to walk a whole continent per tile.
    """
    for size in (8.0 * _TILE_DEG, _TILE_DEG):
        parts = _cut(parts, size)
    return parts


def _cut(parts: npt.NDArray[np.object_], size: float) -> npt.NDArray[np.object_]:
    """Polygons cut on a ``size`` [deg] grid: rectangle clips (linear time), one vectorised call per grid cell."""
    b = shapely.bounds(parts)
    i0, j0 = np.floor(b[:, 0] / size), np.floor(b[:, 1] / size)
    i1, j1 = np.ceil(b[:, 2] / size), np.ceil(b[:, 3] / size)
    nx, ny = np.maximum(i1 - i0, 1).astype(np.intp), np.maximum(j1 - j0, 1).astype(np.intp)
    small = (nx * ny) == 1
    big = np.flatnonzero(~small)
    if big.size == 0:
        return parts
    count = nx[big] * ny[big]
    owner = np.repeat(big, count)
    k = np.arange(owner.size) - np.repeat(np.cumsum(count) - count, count)
    jj, ii = np.divmod(k, nx[owner])
    span = 1 << 20  # cell indices offset to be non-negative, then packed into one key
    key = (i0[owner] + ii + span // 2).astype(np.int64) * span + (j0[owner] + jj + span // 2).astype(np.int64)
    order = np.argsort(key, kind="stable")
    cells, first = np.unique(key[order], return_index=True)
    last = np.append(first[1:], order.size)
    pieces = []
    for cell, lo, hi in zip(cells.tolist(), first.tolist(), last.tolist(), strict=True):
        x, y = (cell // span - span // 2) * size, (cell % span - span // 2) * size
        pieces.append(shapely.clip_by_rect(parts[owner[order[lo:hi]]], x, y, x + size, y + size))
    cut = shapely.get_parts(np.concatenate(pieces))
    cut = cut[(shapely.get_type_id(cut) == shapely.GeometryType.POLYGON) & ~shapely.is_empty(cut)]
    return np.concatenate([parts[small], cut])


def as_arcs(
    lon0: npt.ArrayLike, lat0: npt.ArrayLike, lon1: npt.ArrayLike, lat1: npt.ArrayLike
) -> tuple[tuple[int, ...], FloatArray, FloatArray, FloatArray, FloatArray]:
    """End points of arcs [deg] broadcast together and flattened, longitudes wrapped into [-180, 180).

    Returns the broadcast shape and the four flat arrays (lon0, lat0, lon1, lat1). Points that are not finite, or
    latitudes off [-90, 90]: :class:`~pyroute_rel.errors.GridError`.

    >>> as_arcs([190.0, 0.0], 10.0, 5.0, [20.0, 30.0])[:2]
    ((2,), array([-170.,    0.]))
    """
    arrays = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in (lon0, lat0, lon1, lat1)))
    shape = arrays[0].shape
    flat = [a.ravel() for a in arrays]
    if not all(np.isfinite(a).all() for a in flat):
        raise GridError("arc end points must be finite longitudes/latitudes [deg] (got NaN or inf)")
    if np.any(np.abs(flat[1]) > 90.0) or np.any(np.abs(flat[3]) > 90.0):
        raise GridError("arc end-point latitudes must be in [-90, 90] [deg]")
    lon_a = (flat[0] + 180.0) % 360.0 - 180.0
    lon_b = (flat[2] + 180.0) % 360.0 - 180.0
    return shape, lon_a, flat[1], lon_b, flat[3]


def blocked_flat(
    lon0: FloatArray, lat0: FloatArray, lon1: FloatArray, lat1: FloatArray, index: _Index, samples_km: float
) -> BoolArray:
    """The kernel of :func:`arcs_blocked` on flat, validated arrays.

    1. Coarse pass, level by level: the cap box of each piece of arc is looked up in the index's
       rasters; pieces far from the geometry are free, pieces in cells wholly inside it block their
       arc, and pieces near its edge longer than ``_LEAF_KM`` are halved at their midpoint and looked
       up again. Long arcs (an all-to-all grid has arcs of thousands of km) are so refined only near
       coasts, and an arc is dropped as soon as one of its pieces is known to be blocked.
    2. Exact pass on the remaining short pieces, in chunks, most likely hits first: densified along the
       great circle, made into LineStrings and tested with ``STRtree.query(predicate="intersects")``
       against the tiles.
    """
    m = lon0.size
    blocked = np.zeros(m, dtype=bool)
    if index.empty or m == 0:
        return blocked
    for lo in range(0, m, _BATCH_ARCS):  # batches keep the temporaries small and in cache
        sl = slice(lo, lo + _BATCH_ARCS)
        blocked[sl] = _blocked_batch(lon0[sl], lat0[sl], lon1[sl], lat1[sl], index, samples_km)
    return blocked


def _blocked_batch(
    lon0: FloatArray, lat0: FloatArray, lon1: FloatArray, lat1: FloatArray, index: _Index, samples_km: float
) -> BoolArray:
    blocked = np.zeros(lon0.size, dtype=bool)
    owner = np.arange(lon0.size)
    p0, p1 = to_xyz(lon0, lat0), to_xyz(lon1, lat1)
    leaves = []
    first = True
    while owner.size:  # one pass per halving level (about log2(longest arc / _LEAF_KM)), not per arc
        box, mid, lon_m, lat_m, length = arc_caps(p0, p1)
        if first and np.any(length > (math.pi - 1e-9) * EARTH_RADIUS_KM):
            raise GridError("arc end points are antipodal: the great circle between them is not unique")
        first = False
        maybe, sure, score = index.classify(box)
        sure |= maybe & index.point_inside(lon_m, lat_m)
        blocked[owner[sure]] = True
        keep = maybe & ~blocked[owner]
        split = keep & (length > _LEAF_KM)
        leaf = np.flatnonzero(keep & ~split)
        leaves.append((owner[leaf], score[leaf], p0[leaf], p1[leaf]))
        owner = np.concatenate([owner[split], owner[split]])
        # first halves, then second halves
        p0, p1 = np.concatenate([p0[split], mid[split]]), np.concatenate([mid[split], p1[split]])
    own, score, a, b = (np.concatenate(x) for x in zip(*leaves, strict=True))
    order = np.argsort(-score, kind="stable")  # pieces over more land first: arcs they block drop out
    own = own[order]
    lon_a, lat_a = from_xyz(a[order], wrap=False)
    lon_b, lat_b = from_xyz(b[order], wrap=False)
    per_chunk = max(1, int(_CHUNK_POINTS / (_LEAF_KM / samples_km + 2)))
    for lo in range(0, own.size, per_chunk):  # chunks bound the memory, a few per million arcs
        sl = np.arange(lo, min(lo + per_chunk, own.size))
        sl = sl[~blocked[own[sl]]]
        hit = _exact_hits(lon_a[sl], lat_a[sl], lon_b[sl], lat_b[sl], index, samples_km)
        blocked[own[sl][hit]] = True
    return blocked


def _exact_hits(
    lon0: FloatArray, lat0: FloatArray, lon1: FloatArray, lat1: FloatArray, index: _Index, samples_km: float
) -> BoolArray:
    """Densified great-circle pieces that intersect the index's tiles (seam-crossing pieces twice)."""
    k = lon0.size
    hit = np.zeros(k, dtype=bool)
    if k == 0:
        return hit
    lon, lat, arc = gc_densify(lon0, lat0, lon1, lat1, max_step_km=samples_km)
    xs, ys, ids = [lon], [lat], [arc]
    for shift, past in ((-360.0, lon > 180.0), (360.0, lon < -180.0)):
        seam = np.unique(arc[past])  # pieces running past the seam: test them again, shifted
        if seam.size:
            pick = np.isin(arc, seam)
            xs.append(lon[pick] + shift)
            ys.append(lat[pick])
            ids.append(arc[pick] + (k if shift < 0 else 2 * k))
    line_id, dense = np.unique(np.concatenate(ids), return_inverse=True)  # ids come in increasing blocks
    lines = shapely.linestrings(np.concatenate(xs), np.concatenate(ys), indices=dense)
    touched = index.tree.query(lines, predicate="intersects")[0]
    hit[np.unique(line_id[touched] % k)] = True
    return hit


def checked_samples(samples_km: float) -> float:
    """``samples_km`` [km] as a float, checked to lie in [0.01, 1000] (else :class:`ScenarioError`)."""
    step = float(samples_km)
    if not (0.01 <= step <= 1000.0):
        raise ScenarioError(f"samples_km must be in [0.01, 1000] [km] (got {samples_km!r})")
    return step


def arcs_blocked(
    lon0: npt.ArrayLike,
    lat0: npt.ArrayLike,
    lon1: npt.ArrayLike,
    lat1: npt.ArrayLike,
    geometry: shapely.Geometry,
    *,
    samples_km: float = 2.0,
) -> BoolArray:
    """Which great-circle arcs touch (intersect) a lon/lat geometry.

    Vectorised: a coarse raster of the geometry drops the arcs whose bounding cap is far from it, the
    rest are densified along their great circles and tested exactly against the geometry cut into
    1 deg tiles in a shapely STRtree. The index of a geometry is cached.

    Parameters
    ----------
    lon0, lat0, lon1, lat1 : End points of the arcs [deg]; broadcast together.
    geometry : shapely geometry in lon/lat [deg], e.g. land (:mod:`pyroute_rel.obstacles.land`) or a zone's.
    samples_km : Largest spacing of the points along each arc [km] (see the module notes).

    Returns
    -------
    Bool array of the broadcast shape: True where the arc touches the geometry (boundary included).

    Examples
    --------
    >>> from pyroute_rel.obstacles.land import land_geometry
    >>> land = land_geometry((-65.0, 14.0, -56.0, 18.0))
    >>> arcs_blocked([-57.0, -57.0], [16.25, 15.0], [-64.0, -64.0], [16.25, 15.0], land).tolist()
    [True, False]
    """
    shape, a, b, c, d = as_arcs(lon0, lat0, lon1, lat1)
    step = checked_samples(samples_km)
    return blocked_flat(a, b, c, d, area_index(geometry), step).reshape(shape)
