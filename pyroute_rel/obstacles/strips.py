"""Every arc between two lines of nodes against an area at once: the exact "shadow" test of a rank pair.

A rank digraph joins the nodes of one rank (sources, on a great circle) to those of the next (targets, on
another). Testing each of its arcs against land one by one costs ~n^2 tests per pair of ranks; this module
instead computes, for each source, the *shadow* the area casts on the target line, and so finds every blocked
arc of the pair from the area's few hull vertices.

Method
------
1. **Frame.** The two rank circles meet at a point P (the pole of the route, or for a single source the point
   of the target circle 90 deg from its foot). In the gnomonic projection centred at a point C 90 deg from P,
   great circles are straight lines and both circles map to *parallel* lines; an affine change of
   coordinates puts the sources on the line t = 0 and the targets on t = 1. An arc is then the straight
   segment from (u_s, 0) to (u_j, 1).
2. **Band.** Only the area between the lines can touch an arc: each geometry near the group is projected and
   clipped to the band 0 <= t <= 1 (a rectangle clip, linear time).
3. **Shadow.** For a connected piece Q of the clipped area, the directions from a source S that meet Q form
   an interval (Q lies in the half-plane t >= 0), whose ends are taken at vertices of Q's convex hull. The
   arc S -> B_j meets Q exactly when the direction of B_j lies in that interval: Q then has a point on the ray
   S -> B_j (intermediate values on a connected set), and that point lies in the band, so on the arc itself.
   The direction of a vertex v is represented by where the ray S -> v meets t = 1:
   u_s + (u_v - u_s) / t_v (+-inf for vertices on the line t = 0; a vertex at S blocks every arc).
4. **Marking.** Each (piece, source) interval becomes a run of target indices (binary search), and the runs
   are marked through one difference array over all arcs of all groups.

Cost: (hull vertices of the clipped pieces) x (sources), independent of the number of arcs; a 160 x 160
all-to-all grid (4 M arcs) over the Atlantic coasts is tested in a fraction of a second.

Accuracy: the area's edges are taken as great-circle chords between their vertices. A lon/lat edge of length s
departs from its chord by about s^2 tan|lat| / (8 R): split long boundary edges first, as
:func:`pyroute_rel.obstacles.areas.tiles_tree` does (0.05 deg: under a metre). Edges that pieces share (cuts between
tiles) need no splitting: both pieces take the same chord, so their union is unchanged. Arcs are exact great
circles. This is the tolerance of :func:`pyroute_rel.obstacles.areas.arcs_blocked`, which densifies the arcs instead.

Limits: groups whose points are not within 80 deg of their frame centre, whose sources are not on one great
circle through P, or whose source and target lines (nearly) meet are reported as not handled, for the caller
to test arc by arc.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import shapely

from pyroute_rel.geodesy import from_xyz, to_xyz
from pyroute_rel.units import EARTH_RADIUS_KM

__all__ = ["Group", "fans_blocked"]

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]
IntArray = npt.NDArray[np.intp]

_QUERY_PAD_KM = 10.0  # the outlines that select candidate pieces are grown by this in the gnomonic plane [km]
_QUERY_STEP_KM = 25.0  # outline edges follow their great circles in steps of this [km]
_SLICE_KM = 300.0  # outlines are cut into slices at most this long [km]
_MAX_ANGLE_COS = math.cos(math.radians(80.0))  # points farther than 80 deg from a frame centre: not handled
_ON_LINE_TOL = 1e-9  # sources (targets) must lie on their great circle to this [rad]
_CHUNK = 2_000_000  # (vertex, source) pairs per chunk of the shadow computation
_MARK_CHUNK = 262_144  # arcs per chunk of the marking (its arrays stay in cache)


@dataclass(frozen=True)
class Group:
    """Arcs from sources on one great circle (or a single source) to targets in order along another.

    ``src_lon``, ``src_lat``, ``dst_lon``, ``dst_lat`` [deg] are 1-D arrays. With ``band``, only the arcs from
    source i to targets i - band ... i + band are wanted (a banded rank pattern); otherwise every arc.
    """

    src_lon: FloatArray
    src_lat: FloatArray
    dst_lon: FloatArray
    dst_lat: FloatArray
    band: int | None = None


def _norm(v: FloatArray) -> FloatArray:
    return np.sqrt(np.einsum("ij,ij->i", v, v))


def _dot(a: FloatArray, b: FloatArray) -> FloatArray:
    return np.einsum("ij,ij->i", a, b)


def _unitize(v: FloatArray) -> tuple[FloatArray, FloatArray]:
    n = _norm(v)
    return v / np.where(n > 0.0, n, 1.0)[:, None], n


@dataclass(frozen=True)
class _Points:
    """Sources (or targets) of many groups, concatenated: unit vectors, group of each point, group offsets."""

    v: FloatArray
    group: IntArray
    off: IntArray

    @property
    def count(self) -> IntArray:
        return np.diff(self.off)

    def first(self) -> FloatArray:
        return self.v[self.off[:-1]]

    def last(self) -> FloatArray:
        return self.v[self.off[1:] - 1]

    def reduce(self, ufunc: np.ufunc, values: FloatArray) -> FloatArray:
        return ufunc.reduceat(values, self.off[:-1], axis=0)


def _points(lons: list[FloatArray], lats: list[FloatArray]) -> _Points:
    counts = np.array([len(a) for a in lons], dtype=np.intp)
    off = np.concatenate([[0], np.cumsum(counts)]).astype(np.intp)
    v = to_xyz(np.concatenate(lons).astype(float), np.concatenate(lats).astype(float))
    return _Points(v, np.repeat(np.arange(len(counts)), counts), off)


@dataclass(frozen=True)
class _Frames:
    """Per group: gnomonic centre C and axes X (towards P), Y, and the affine map (u, t) of the module notes."""

    c: FloatArray
    x: FloatArray
    y: FloatArray
    u0: FloatArray
    du: FloatArray
    t0: FloatArray
    dt: FloatArray

    def project(self, v: FloatArray, g: IntArray) -> tuple[FloatArray, FloatArray]:
        w = _dot(v, self.c[g])
        return ((_dot(v, self.x[g]) / w - self.u0[g]) / self.du[g], (_dot(v, self.y[g]) / w - self.t0[g]) / self.dt[g])


def _frames(src: _Points, dst: _Points) -> tuple[_Frames, BoolArray]:
    """Every group's frame, and which groups the method handles (see the module notes)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        n_b, nb_len = _unitize(np.cross(dst.first(), dst.last()))
        ok = (dst.count >= 2) & (nb_len > 1e-12)
        ok &= dst.reduce(np.maximum, np.abs(_dot(dst.v, n_b[dst.group]))) <= _ON_LINE_TOL
        single = src.count == 1
        s0 = src.first()
        off = _dot(s0, n_b)
        foot, _ = _unitize(s0 - off[:, None] * n_b)
        n_a, na_len = _unitize(np.cross(s0, src.last()))
        on_a = src.reduce(np.maximum, np.abs(_dot(src.v, n_a[src.group]))) <= _ON_LINE_TOL
        ok &= np.where(single, np.abs(off) >= 1e-9, (na_len > 1e-12) & on_a)
        p, p_len = _unitize(np.where(single[:, None], np.cross(s0, foot), np.cross(n_a, n_b)))
        ok &= p_len > 1e-9
        m = src.reduce(np.add, src.v) / src.count[:, None] + dst.reduce(np.add, dst.v) / dst.count[:, None]
        c, c_len = _unitize(m - _dot(m, p)[:, None] * p)
        ok &= c_len > 1e-9
        y = np.cross(c, p)
        ws, wd = _dot(src.v, c[src.group]), _dot(dst.v, c[dst.group])
        ok &= (src.reduce(np.minimum, ws) > _MAX_ANGLE_COS) & (dst.reduce(np.minimum, wd) > _MAX_ANGLE_COS)
        gys, gyd = _dot(src.v, y[src.group]) / ws, _dot(dst.v, y[dst.group]) / wd
        ya, yb = src.reduce(np.add, gys) / src.count, dst.reduce(np.add, gyd) / dst.count
        sign = np.where(ya > yb, -1.0, 1.0)
        y, ya, yb = y * sign[:, None], ya * sign, yb * sign
        gys, gyd = gys * sign[src.group], gyd * sign[dst.group]
        dt = yb - ya
        ok &= dt > 1e-9
        ok &= src.reduce(np.maximum, np.abs(gys - ya[src.group])) <= 1e-6 * dt
        ok &= dst.reduce(np.maximum, np.abs(gyd - yb[dst.group])) <= 1e-6 * dt
        gxs, gxd = _dot(src.v, p[src.group]) / ws, _dot(dst.v, p[dst.group]) / wd
        # targets must be in order along their line (strictly monotone x)
        step = np.diff(gxd)
        inner = np.ones(step.size, dtype=bool)
        inner[dst.off[1:-1] - 1] = False
        sense = np.sign(gxd[dst.off[1:] - 1] - gxd[dst.off[:-1]])
        ok &= ~np.bincount(
            dst.group[1:][inner], weights=(step[inner] * sense[dst.group[1:][inner]] <= 0.0), minlength=len(ok)
        ).astype(bool)
        lo = np.minimum(src.reduce(np.minimum, gxs), dst.reduce(np.minimum, gxd))
        hi = np.maximum(src.reduce(np.maximum, gxs), dst.reduce(np.maximum, gxd))
        du = np.maximum(hi - lo, dt)
    ok &= np.isfinite(du) & np.isfinite(lo) & np.isfinite(ya)
    return _Frames(c=c, x=p, y=y, u0=lo, du=du, t0=ya, dt=dt), ok


def _outlines(frames: _Frames, n_src: IntArray) -> tuple[npt.NDArray[np.object_], IntArray]:
    """Lon/lat polygons [deg] that together hold each group's band 0 <= t <= 1, 0 <= u <= 1 (so its hull).

    The band is cut into slices at most ``_SLICE_KM`` long, so each outline has a small bounding box (a long
    diagonal outline would send the STRtree thousands of candidates). Outline edges are straight in the
    gnomonic plane, hence great circles; they are followed in steps of ``_QUERY_STEP_KM`` and unwrapped in
    longitude (an outline may run past +-180 deg). A lon/lat chord of such a step departs from its great
    circle by under 0.1 km (at 80 deg of latitude); the slices are grown by ``_QUERY_PAD_KM`` in the gnomonic
    plane, at least 0.3 km on the sphere within 80 deg of the centre, to cover that. Returns the polygons
    and the group of each.
    """
    n = len(n_src)
    km_u = frames.du * EARTH_RADIUS_KM  # gnomonic lengths overstate true ones, so these counts are enough
    km_t = frames.dt * EARTH_RADIUS_KM
    m = np.maximum(1, np.ceil(km_u / _SLICE_KM)).astype(np.intp)  # slices per group
    owner = np.repeat(np.arange(n), m)
    k = np.arange(owner.size) - np.repeat(np.cumsum(m) - m, m)
    pad_u, pad_t = _QUERY_PAD_KM / km_u[owner], _QUERY_PAD_KM / km_t[owner]
    u0, u1 = k / m[owner] - pad_u, (k + 1) / m[owner] + pad_u
    nu = np.maximum(1, np.ceil(km_u[owner] / m[owner] / _QUERY_STEP_KM)).astype(np.intp)
    nt = np.maximum(1, np.ceil(km_t[owner] / _QUERY_STEP_KM)).astype(np.intp)
    per = 2 * (nu + nt)  # points per slice ring (closing point left to shapely)
    sl = np.repeat(np.arange(owner.size), per)
    i = np.arange(sl.size) - np.repeat(np.cumsum(per) - per, per)
    a, b, c = nu[sl], nt[sl], 2 * nu[sl] + nt[sl]
    # walk the ring: bottom (t = 0, u0 -> u1), right (u1, t 0 -> 1), top (u1 -> u0), left (t 1 -> 0)
    frac_u = np.select([i < a, i < a + b, i < c], [i / a, 1.0, 1.0 - (i - a - b) / a], 0.0)
    frac_t = np.select([i < a, i < a + b, i < c], [0.0, (i - a) / b, 1.0], 1.0 - (i - c) / b)
    u = u0[sl] + frac_u * (u1 - u0)[sl]
    t = frac_t * (1.0 + 2.0 * pad_t[sl]) - pad_t[sl]
    g = owner[sl]
    gx, gy = u * frames.du[g] + frames.u0[g], t * frames.dt[g] + frames.t0[g]
    v = frames.c[g] + gx[:, None] * frames.x[g] + gy[:, None] * frames.y[g]
    lon, lat = from_xyz(v)
    first = np.cumsum(per) - per
    step = np.concatenate([[0.0], (np.diff(lon) + 180.0) % 360.0 - 180.0])
    run = np.cumsum(step)
    lon = lon[first][sl] + (run - run[first][sl])
    polys = shapely.polygons(shapely.linearrings(lon, lat, indices=sl))
    bad = ~shapely.is_valid(polys)
    if bad.any():
        polys[bad] = shapely.make_valid(polys[bad])
    return polys, owner


def _candidates(outlines: npt.NDArray[np.object_], owner: IntArray, tree: shapely.STRtree) -> tuple[IntArray, IntArray]:
    """(group, piece) pairs whose lon/lat outline meets a piece of the tree (outlines past the seam shifted)."""
    geoms = outlines
    b = shapely.bounds(geoms)
    extra_g, extra_o = [], []
    for shift, past in ((-360.0, b[:, 2] > 180.0), (360.0, b[:, 0] < -180.0)):
        if past.any():
            extra_g.append(shapely.transform(geoms[past], lambda xy, s=shift: xy + (s, 0.0)))
            extra_o.append(owner[past])
    if extra_g:
        geoms = np.concatenate([geoms, *extra_g])
        owner = np.concatenate([owner, *extra_o])
    q = tree.query(geoms, predicate="intersects")
    n_pieces = len(tree)
    pairs = np.unique(owner[q[0]] * n_pieces + q[1])
    return pairs // n_pieces, pairs % n_pieces


def fans_blocked(groups: Sequence[Group], trees: Sequence[shapely.STRtree]) -> list[list[BoolArray | None]]:
    """For each area and each group, which arcs touch the area (its pieces in an STRtree, lon/lat [deg]).

    Parameters
    ----------
    groups : Sources on one great circle (or a single source) and targets in order along another; at least
        one of each.
    trees : One STRtree per area, of small lon/lat polygons (e.g. land cut into 1 deg tiles); pieces may
        overlap. The groups' frames are computed once for all areas.

    Returns
    -------
    Per area, per group a bool array, True where the great-circle arc from source i to target j touches the
    area: of shape (n_targets, n_sources), or with ``band`` of shape (n_sources, 2 band + 1), column w holding
    target i - band + w (False outside the targets). None for groups this method does not handle (see the
    module notes).

    Examples
    --------
    Two "ranks" 1 deg of longitude apart across an island 0.2 deg wide at 0.5 E, 0 N:

    >>> island = shapely.Point(0.5, 0.0).buffer(0.1)
    >>> lat = np.array([-1.0, 0.0, 1.0])
    >>> g = Group(np.zeros(3), lat, np.ones(3), lat)
    >>> fans_blocked([g], [shapely.STRtree([island])])[0][0].astype(int).tolist()  # [target][source]
    [[0, 0, 1], [0, 1, 0], [1, 0, 0]]
    """
    out: list[list[BoolArray | None]] = [[None] * len(groups) for _ in trees]
    if not groups or not trees:
        return out
    for g in groups:
        if len(g.src_lon) == 0 or len(g.dst_lon) == 0:
            raise ValueError("every group needs at least one source and one target")
    src = _points([g.src_lon for g in groups], [g.src_lat for g in groups])
    dst = _points([g.dst_lon for g in groups], [g.dst_lat for g in groups])
    frames, ok = _frames(src, dst)
    keep = [int(i) for i in np.flatnonzero(ok)]
    if not keep:
        return out
    if len(keep) < len(groups):
        src = _points([groups[i].src_lon for i in keep], [groups[i].src_lat for i in keep])
        dst = _points([groups[i].dst_lon for i in keep], [groups[i].dst_lat for i in keep])
        frames, _ = _frames(src, dst)
    outlines = _outlines(frames, src.count)
    shapely.prepare(outlines[0])  # queried once per area
    bands = [groups[i].band for i in keep]
    for t, tree in enumerate(trees):
        blocked = _shadows(frames, src, dst, bands, outlines, tree)
        for h, gi in enumerate(keep):
            out[t][gi] = blocked[h]
    return out


def _shadows(
    frames: _Frames,
    src: _Points,
    dst: _Points,
    bands: list[int | None],
    outlines: tuple[npt.NDArray[np.object_], IntArray],
    tree: shapely.STRtree,
) -> list[BoolArray]:
    """Per group, which arcs touch the area of ``tree`` (the steps of the module notes, laid out as
    :func:`fans_blocked` returns them)."""
    n_src, n_dst = src.count, dst.count
    result = [
        np.zeros((int(b), int(a)) if w is None else (int(a), 2 * w + 1), dtype=bool)
        for a, b, w in zip(n_src, n_dst, bands, strict=True)
    ]
    if len(tree) == 0:
        return result
    parts, part_group = _band_pieces(frames, outlines, tree)
    if parts.size == 0:
        return result
    g_row, i_row, lo, hi = _shadow_intervals(frames, src, parts, part_group)
    band = np.array([-1 if b is None else int(b) for b in bands], dtype=np.intp)
    width = np.where(band < 0, n_dst, 2 * band + 1)
    runs = _target_runs(frames, dst, band, width, (g_row, i_row, lo, hi))
    _mark_runs(result, n_src, band, width, runs)
    return result


def _band_pieces(
    frames: _Frames, outlines: tuple[npt.NDArray[np.object_], IntArray], tree: shapely.STRtree
) -> tuple[npt.NDArray[np.object_], IntArray]:
    """Step 2: the candidate pieces projected into their group's (u, t) plane and clipped to the band
    0 <= t <= 1; the non-empty parts and the group of each."""
    grp, piece = _candidates(*outlines, tree)
    if grp.size == 0:
        return np.empty(0, dtype=object), grp
    geoms = tree.geometries.take(piece)
    owner = np.repeat(grp, shapely.get_num_coordinates(geoms))

    def project(lonlat: FloatArray) -> FloatArray:
        u, t = frames.project(to_xyz(lonlat[:, 0], lonlat[:, 1]), owner)
        return np.column_stack([u, t])

    clipped = shapely.clip_by_rect(shapely.transform(geoms, project), -0.01, 0.0, 1.01, 1.0)
    parts, part_of = shapely.get_parts(clipped, return_index=True)
    keep = ~shapely.is_empty(parts)
    return parts[keep], grp[part_of[keep]]


def _shadow_intervals(
    frames: _Frames, src: _Points, parts: npt.NDArray[np.object_], part_group: IntArray
) -> tuple[IntArray, IntArray, FloatArray, FloatArray]:
    """Step 3: for each (piece, source) the interval [lo, hi] of target-line positions u the piece hides, from the
    vertices of the piece's convex hull. Returns the group and source index of each row, and lo, hi.

    Pieces are bucketed by hull size (padded by repeating a vertex) and source count, so each bucket is one
    broadcast."""
    n_src = src.count
    hulls = shapely.convex_hull(parts)
    xy, vert_part = shapely.get_coordinates(hulls, return_index=True)
    nv = np.bincount(vert_part, minlength=parts.size)
    v_start = np.cumsum(nv) - nv
    nv = np.where(shapely.get_type_id(hulls) == shapely.GeometryType.POLYGON, nv - 1, nv)  # not the closing vertex
    inv_t = 1.0 / np.maximum(xy[:, 1], 1e-200)
    src_u, _ = frames.project(src.v, src.group)
    bucket = np.where(nv <= 16, nv, 2 ** np.ceil(np.log2(np.maximum(nv, 1)))).astype(np.intp)
    rows_g, rows_i, lo_all, hi_all = [], [], [], []
    for kk in np.unique(bucket):
        in_k = bucket == kk
        for ns in np.unique(n_src[part_group[in_k]]):
            ps = np.flatnonzero(in_k & (n_src[part_group] == ns))
            per = max(1, _CHUNK // int(ns * kk))
            for c0 in range(0, ps.size, per):
                pc = ps[c0 : c0 + per]
                vi = v_start[pc][:, None] + np.minimum(np.arange(kk)[None, :], nv[pc][:, None] - 1)
                u_v, it = xy[vi, 0], inv_t[vi]
                s_u = src_u[src.off[part_group[pc]][:, None] + np.arange(ns)[None, :]]  # (P, ns)
                shadow = s_u[:, :, None] + (u_v[:, None, :] - s_u[:, :, None]) * it[:, None, :]
                lo_all.append(shadow.min(axis=2).ravel())
                hi_all.append(shadow.max(axis=2).ravel())
                rows_g.append(np.repeat(part_group[pc], ns))
                rows_i.append(np.tile(np.arange(ns), pc.size))
    return np.concatenate(rows_g), np.concatenate(rows_i), np.concatenate(lo_all), np.concatenate(hi_all)


def _target_runs(
    frames: _Frames,
    dst: _Points,
    band: IntArray,
    width: IntArray,
    rows: tuple[IntArray, IntArray, FloatArray, FloatArray],
) -> tuple[IntArray, IntArray, IntArray, IntArray]:
    """Step 4: intervals -> runs [j0, j1) of target columns within each source's window (all targets, or
    i - band ... i + band); the non-empty runs (group, source, j0, j1), sorted by group."""
    g_row, i_row, lo, hi = rows
    n_dst = dst.count
    # targets are in order along their line, u increasing or decreasing; keys arctan(u) / pi + group increase
    # across groups, so one binary search serves all
    dst_u, _ = frames.project(dst.v, dst.group)
    first, last = dst.off[:-1], dst.off[1:] - 1
    down = dst_u[last] < dst_u[first]
    pos = np.arange(dst.v.shape[0])
    order = np.where(down[dst.group], first[dst.group] + last[dst.group] - pos, pos)  # sorted position -> point
    key = np.arctan(dst_u[order]) / math.pi + dst.group
    j0 = np.searchsorted(key, np.arctan(lo) / math.pi + g_row, side="left") - dst.off[g_row]
    j1 = np.searchsorted(key, np.arctan(hi) / math.pi + g_row, side="right") - dst.off[g_row]
    nd = n_dst[g_row]
    j0, j1 = np.where(down[g_row], nd - j1, j0), np.where(down[g_row], nd - j0, j1)  # [j0, j1) in target order
    w0 = np.where(band[g_row] < 0, 0, i_row - band[g_row])
    j0, j1 = np.maximum(j0 - w0, 0), np.minimum(j1 - w0, width[g_row])
    run = j1 > j0
    g_row, i_row, j0, j1 = g_row[run], i_row[run], j0[run], j1[run]
    by_group = np.argsort(g_row, kind="stable")
    return g_row[by_group], i_row[by_group], j0[by_group], j1[by_group]


def _mark_runs(
    result: list[BoolArray],
    n_src: IntArray,
    band: IntArray,
    width: IntArray,
    runs: tuple[IntArray, IntArray, IntArray, IntArray],
) -> None:
    """Step 4, marking: the runs into ``result`` through a difference array over the arcs, a chunk of whole
    groups at a time (bounded memory); groups without a run stay all False."""
    g_row, i_row, j0, j1 = runs
    size = n_src * width
    busy = np.unique(g_row)
    b = 0
    while b < busy.size:
        g_lo = int(busy[b])
        e = b + 1
        while e < busy.size and size[g_lo : busy[e] + 1].sum() <= _MARK_CHUNK:
            e += 1
        g_hi = int(busy[e - 1]) + 1
        b = e
        arc_off = np.concatenate([[0], np.cumsum(size[g_lo:g_hi])])
        r0, r1 = np.searchsorted(g_row, [g_lo, g_hi])
        base = arc_off[g_row[r0:r1] - g_lo] + i_row[r0:r1] * width[g_row[r0:r1]]
        total = int(arc_off[-1])
        diff = np.bincount(base + j0[r0:r1], minlength=total + 1) - np.bincount(base + j1[r0:r1], minlength=total + 1)
        flat = np.cumsum(diff[:total]) > 0
        for g in range(g_lo, g_hi):
            block = flat[arc_off[g - g_lo] : arc_off[g - g_lo + 1]].reshape(int(n_src[g]), int(width[g]))
            result[g] = np.ascontiguousarray(block.T) if band[g] < 0 else block
