"""Great-circle geometry on a spherical Earth, vectorised over numpy arrays.

All functions broadcast their array arguments. Positions are longitude/latitude [deg]; bearings are
clockwise from true north [deg] in [0, 360); distances are [km] unless the name says ``_nm``.
The sphere has the IUGG mean radius R = 6371.0088 km, whose great-circle distances differ from the
WGS84 geodesic by at most about 0.5 %; :func:`geodesic_distance_km` gives the ellipsoidal value via
``pyproj.Geod`` where that matters.

References
----------
Williams, E. Aviation Formulary V1.47, https://edwilliams.org/avform147.htm (great-circle formulae).
Moritz, H. (2000). Geodetic Reference System 1980. J. Geodesy 74, 128-133, doi:10.1007/s001900050278
(mean radius R1 = 6371.0088 km).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from pyroute_rel.errors import CoordinateError, GridError
from pyroute_rel.units import EARTH_RADIUS_KM, KM_PER_NM

__all__ = [
    "EARTH_RADIUS_KM",
    "KM_PER_NM",
    "distance_km",
    "distance_nm",
    "initial_bearing_deg",
    "intermediate_point",
    "destination_point",
    "cross_track_km",
    "along_track_km",
    "wrap_lon",
    "to_xyz",
    "from_xyz",
    "angle_between",
    "gc_densify",
    "angle_diff_deg",
    "fold_angle_deg",
    "bearing_deg",
    "geodesic_distance_km",
    "crossing_fraction",
    "distance_to_segment_nm",
]


FloatArray = npt.NDArray[np.float64]


def wrap_lon(lon_deg: npt.ArrayLike) -> FloatArray:
    """Wrap longitudes into [-180, 180) [deg].

    >>> wrap_lon([180.0, 190.0, -181.0]).tolist()
    [-180.0, -170.0, 179.0]
    """
    return (np.asarray(lon_deg, dtype=float) + 180.0) % 360.0 - 180.0


def angle_diff_deg(a_deg: npt.ArrayLike, b_deg: npt.ArrayLike) -> FloatArray:
    """Smallest unsigned angle between two directions [deg], in [0, 180].

    >>> angle_diff_deg([350.0, 10.0], [10.0, 190.0]).tolist()
    [20.0, 180.0]
    """
    return fold_angle_deg(np.subtract(a_deg, b_deg, dtype=float))


def fold_angle_deg(angle_deg: npt.ArrayLike) -> FloatArray:
    """The unsigned angle in [0, 180] [deg] equivalent to any angle (-30 and 330 give 30); NaN gives NaN.

    >>> fold_angle_deg([-30.0, 330.0, 190.0, 540.0]).tolist()
    [30.0, 30.0, 170.0, 180.0]
    """
    d = np.abs(np.asarray(angle_deg, dtype=float))
    if np.fmax.reduce(d, axis=None, initial=0.0) > 360.0:  # float remainder is ~20x slower: only if needed
        with np.errstate(invalid="ignore"):
            d = np.remainder(d, 360.0)
    return np.minimum(d, 360.0 - d, out=d) if d.ndim else np.minimum(d, 360.0 - d)


def bearing_deg(east: npt.ArrayLike, north: npt.ArrayLike) -> FloatArray:
    """Bearing of the vector (east, north), clockwise from north, in [0, 360) [deg].

    >>> bearing_deg([1.0, -1.0, 0.0, -1e-300], [0.0, 0.0, -1.0, 1.0]).tolist()
    [90.0, 270.0, 180.0, 0.0]
    """
    d = np.asarray(np.degrees(np.arctan2(east, north)))  # in [-180, 180]: no float remainder (it is slow)
    d += 360.0 * (d < 0.0)  # also turns -0.0 into 0.0
    d[d >= 360.0] = 0.0  # -1e-15 + 360 rounds to 360
    return d


def _lat(lat_deg: npt.ArrayLike) -> FloatArray:
    """Latitudes [deg] as a float array; :class:`~pyroute_rel.errors.CoordinateError` off [-90, 90] (NaN passes:
    it gives NaN results, as documented)."""
    lat = np.asarray(lat_deg, dtype=float)
    if np.any(np.abs(lat) > 90.0):
        bad = lat[np.abs(lat) > 90.0].ravel()[0]
        raise CoordinateError(f"latitude must be in [-90, 90] [deg] (got {bad:g})")
    return lat


def _central_angle(lon1: FloatArray, lat1: FloatArray, lon2: FloatArray, lat2: FloatArray) -> FloatArray:
    """Central angle [rad] by the haversine formula (well conditioned for short arcs)."""
    phi1, phi2 = np.radians(_lat(lat1)), np.radians(_lat(lat2))
    dphi = phi2 - phi1
    dlmb = np.radians(np.asarray(lon2, dtype=float) - lon1)
    h = np.sin(dphi / 2.0) ** 2 + np.cos(phi1) * np.cos(phi2) * np.sin(dlmb / 2.0) ** 2
    return 2.0 * np.arcsin(np.sqrt(np.clip(h, 0.0, 1.0)))


def distance_km(
    lon1_deg: npt.ArrayLike, lat1_deg: npt.ArrayLike, lon2_deg: npt.ArrayLike, lat2_deg: npt.ArrayLike
) -> FloatArray:
    """Great-circle distance on the sphere [km].

    Parameters
    ----------
    lon1_deg, lat1_deg : Start position [deg].
    lon2_deg, lat2_deg : End position [deg].

    Returns
    -------
    Distance [km], shape of the broadcast inputs.

    Examples
    --------
    >>> round(float(distance_km(0.0, 0.0, 1.0, 0.0)), 3)  # one degree of the equator
    111.195
    """
    lon1, lat1, lon2, lat2 = (np.asarray(a, dtype=float) for a in (lon1_deg, lat1_deg, lon2_deg, lat2_deg))
    return EARTH_RADIUS_KM * _central_angle(lon1, lat1, lon2, lat2)


def distance_nm(
    lon1_deg: npt.ArrayLike, lat1_deg: npt.ArrayLike, lon2_deg: npt.ArrayLike, lat2_deg: npt.ArrayLike
) -> FloatArray:
    """Great-circle distance on the sphere [nm] (1 nm = 1.852 km)."""
    return distance_km(lon1_deg, lat1_deg, lon2_deg, lat2_deg) / KM_PER_NM


def initial_bearing_deg(
    lon1_deg: npt.ArrayLike, lat1_deg: npt.ArrayLike, lon2_deg: npt.ArrayLike, lat2_deg: npt.ArrayLike
) -> FloatArray:
    """Initial great-circle bearing from point 1 towards point 2, clockwise from true north [deg].

    >>> initial_bearing_deg(0.0, 0.0, [1.0, 0.0], [0.0, 1.0]).round(6).tolist()
    [90.0, 0.0]
    """
    phi1 = np.radians(_lat(lat1_deg))
    phi2 = np.radians(_lat(lat2_deg))
    dlmb = np.radians(np.asarray(lon2_deg, dtype=float) - np.asarray(lon1_deg, dtype=float))
    y = np.sin(dlmb) * np.cos(phi2)
    x = np.cos(phi1) * np.sin(phi2) - np.sin(phi1) * np.cos(phi2) * np.cos(dlmb)
    return np.degrees(np.arctan2(y, x)) % 360.0


def to_xyz(lon_deg: npt.ArrayLike, lat_deg: npt.ArrayLike) -> FloatArray:
    """Unit vectors of positions on the sphere (x towards lon 0 on the equator, z towards the north pole).

    Parameters
    ----------
    lon_deg, lat_deg : Positions [deg]; broadcast together. Latitudes off [-90, 90]:
        :class:`~pyroute_rel.errors.CoordinateError`.

    Returns
    -------
    Unit vectors [-], shape (..., 3) of the broadcast inputs.

    >>> to_xyz(90.0, 0.0).round(12).tolist()
    [0.0, 1.0, 0.0]
    """
    lmb = np.radians(np.asarray(lon_deg, dtype=float))
    phi = np.radians(_lat(lat_deg))
    cphi = np.cos(phi)
    return np.stack(np.broadcast_arrays(cphi * np.cos(lmb), cphi * np.sin(lmb), np.sin(phi)), axis=-1)


def from_xyz(xyz: FloatArray, *, wrap: bool = True) -> tuple[FloatArray, FloatArray]:
    """Positions of vectors (the inverse of :func:`to_xyz`; the vectors need not be of unit length).

    Parameters
    ----------
    xyz : Vectors, shape (..., 3).
    wrap : Longitudes wrapped into [-180, 180) by :func:`wrap_lon` (the default), or as ``arctan2`` gives them,
        in [-180, 180] (no rounding from the wrap; for callers that unwrap longitudes along a path).

    Returns
    -------
    (lon [deg], lat [deg]), each of shape (...).

    >>> lon, lat = from_xyz(np.array([[0.0, 1.0, 1.0], [-1.0, -0.0, 0.0]]))
    >>> lon.tolist(), lat.round(12).tolist()
    ([90.0, -180.0], [45.0, 0.0])
    >>> from_xyz(np.array([-1.0, -0.0, 0.0]), wrap=False)[0].item()
    -180.0
    """
    x, y, z = xyz[..., 0], xyz[..., 1], xyz[..., 2]
    lat = np.degrees(np.arctan2(z, np.hypot(x, y)))
    lon = np.degrees(np.arctan2(y, x))
    return (wrap_lon(lon) if wrap else lon), lat


def angle_between(a: FloatArray, b: FloatArray) -> FloatArray:
    """Angle between unit vectors [rad], in [0, pi]: atan2(|a x b|, a . b), accurate for tiny and
    near-antipodal angles alike (unlike ``arccos`` of the dot product).

    Parameters
    ----------
    a, b : Unit vectors, shape (..., 3) (:func:`to_xyz`); broadcast together.

    Returns
    -------
    Central angle [rad] of the broadcast shape (...); times :data:`EARTH_RADIUS_KM`, the great-circle
    distance [km].

    >>> round(float(angle_between(to_xyz(0.0, 0.0), to_xyz(0.0, 90.0))), 12) == round(np.pi / 2, 12)
    True
    >>> float(angle_between(to_xyz(10.0, 20.0), to_xyz(10.0, 20.0)))
    0.0
    """
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    cx = a1 * b2 - a2 * b1
    cy = a2 * b0 - a0 * b2
    cz = a0 * b1 - a1 * b0
    return np.arctan2(np.sqrt(cx * cx + cy * cy + cz * cz), a0 * b0 + a1 * b1 + a2 * b2)


def gc_densify(
    lon0_deg: npt.ArrayLike,
    lat0_deg: npt.ArrayLike,
    lon1_deg: npt.ArrayLike,
    lat1_deg: npt.ArrayLike,
    *,
    max_step_km: float,
) -> tuple[FloatArray, FloatArray, npt.NDArray[np.intp]]:
    """Points along many great-circle arcs, end points included, at most ``max_step_km`` apart.

    Spherical linear interpolation of the unit vectors, each arc cut into equal steps (at least one). Each
    arc's longitudes are unwrapped to run continuously from ``lon0`` (they may leave [-180, 180]: an arc from
    179 E to 179 W runs 179 -> 181). The end points are returned exactly as given.

    Parameters
    ----------
    lon0_deg, lat0_deg : Starts of the arcs [deg], 1-D.
    lon1_deg, lat1_deg : Ends of the arcs [deg], 1-D, as many.
    max_step_km : Largest distance between consecutive points of an arc [km].

    Returns
    -------
    lon, lat : The points of all arcs, concatenated [deg], arc by arc from start to end.
    arc : For every point, the index of its arc.

    Raises
    ------
    GridError
        Antipodal end points (no unique great circle between them).

    Examples
    --------
    >>> lon, lat, arc = gc_densify(np.array([179.0]), np.array([0.0]), np.array([-179.0]), np.array([0.0]),
    ...                            max_step_km=100.0)
    >>> lon.round(6).tolist(), arc.tolist()
    ([179.0, 179.666667, 180.333333, 181.0], [0, 0, 0, 0])
    """
    lon0, lat0, lon1, lat1 = (np.asarray(v, dtype=float) for v in (lon0_deg, lat0_deg, lon1_deg, lat1_deg))
    p0, p1 = to_xyz(lon0, lat0), to_xyz(lon1, lat1)
    omega = angle_between(p0, p1)
    if np.any(omega > np.pi - 1e-9):
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
    lon, lat = from_xyz(w0[:, None] * p0[arc] + w1[:, None] * p1[arc], wrap=False)
    end = start + n - 1
    lon[start], lat[start], lon[end], lat[end] = lon0, lat0, lon1, lat1  # exact end points
    # unwrap along each arc: consecutive points are close, so each step is the wrapped difference
    step = (np.diff(lon) + 180.0) % 360.0 - 180.0
    run = np.concatenate([[0.0], np.cumsum(step)])
    lon = lon0[arc] + (run - run[start][arc])
    return lon, lat, arc


def intermediate_point(
    lon1_deg: npt.ArrayLike,
    lat1_deg: npt.ArrayLike,
    lon2_deg: npt.ArrayLike,
    lat2_deg: npt.ArrayLike,
    fraction: npt.ArrayLike,
) -> tuple[FloatArray, FloatArray]:
    """Point a given fraction of the way along the great circle from point 1 to point 2.

    Spherical linear interpolation of the unit vectors; exact for any fraction (0 gives point 1,
    1 gives point 2; values outside [0, 1] extrapolate along the same great circle). Antipodal
    end points have no unique great circle and give NaN.

    Returns
    -------
    (lon [deg] in [-180, 180), lat [deg]), each of the broadcast shape.

    >>> lon, lat = intermediate_point(0.0, 0.0, 90.0, 0.0, 0.5)
    >>> round(float(lon), 9), round(float(lat), 9)
    (45.0, 0.0)
    """
    a = to_xyz(lon1_deg, lat1_deg)
    b = to_xyz(lon2_deg, lat2_deg)
    f = np.asarray(fraction, dtype=float)[..., None]
    omega = np.arccos(np.clip(np.sum(a * b, axis=-1), -1.0, 1.0))[..., None]
    with np.errstate(invalid="ignore", divide="ignore"):
        so = np.sin(omega)
        small = omega < 1e-12
        wa = np.where(small, 1.0 - f, np.sin((1.0 - f) * omega) / np.where(small, 1.0, so))
        wb = np.where(small, f, np.sin(f * omega) / np.where(small, 1.0, so))
    anti = np.abs(omega - np.pi) < 1e-12
    p = wa * a + wb * b
    p = np.where(anti, np.nan, p)
    return from_xyz(p)


def destination_point(
    lon_deg: npt.ArrayLike, lat_deg: npt.ArrayLike, bearing_deg: npt.ArrayLike, dist_km: npt.ArrayLike
) -> tuple[FloatArray, FloatArray]:
    """Point reached by following a great circle from a start point with an initial bearing.

    Parameters
    ----------
    lon_deg, lat_deg : Start [deg].
    bearing_deg : Initial bearing, clockwise from north [deg].
    dist_km : Distance along the great circle [km] (negative goes the other way).

    Returns
    -------
    (lon [deg] in [-180, 180), lat [deg]).

    >>> lon, lat = destination_point(0.0, 0.0, 90.0, 111.19508)
    >>> round(float(lon), 4), round(float(lat), 4)
    (1.0, 0.0)
    """
    phi1 = np.radians(_lat(lat_deg))
    lmb1 = np.radians(np.asarray(lon_deg, dtype=float))
    theta = np.radians(np.asarray(bearing_deg, dtype=float))
    delta = np.asarray(dist_km, dtype=float) / EARTH_RADIUS_KM
    sphi2 = np.sin(phi1) * np.cos(delta) + np.cos(phi1) * np.sin(delta) * np.cos(theta)
    phi2 = np.arcsin(np.clip(sphi2, -1.0, 1.0))
    lmb2 = lmb1 + np.arctan2(np.sin(theta) * np.sin(delta) * np.cos(phi1), np.cos(delta) - np.sin(phi1) * np.sin(phi2))
    return wrap_lon(np.degrees(lmb2)), np.degrees(phi2)


def cross_track_km(
    lon1_deg: npt.ArrayLike,
    lat1_deg: npt.ArrayLike,
    lon2_deg: npt.ArrayLike,
    lat2_deg: npt.ArrayLike,
    lon_deg: npt.ArrayLike,
    lat_deg: npt.ArrayLike,
) -> FloatArray:
    """Signed distance [km] of a point from the great circle through points 1 and 2.

    Positive to the right (starboard) of the direction 1 → 2, negative to the left.

    >>> round(float(cross_track_km(0.0, 0.0, 10.0, 0.0, 5.0, -1.0)), 3)  # 1 degree south of an eastward track
    111.195
    """
    d13 = _central_angle(
        np.asarray(lon1_deg, float),
        np.asarray(lat1_deg, float),
        np.asarray(lon_deg, float),
        np.asarray(lat_deg, float),
    )
    t13 = np.radians(initial_bearing_deg(lon1_deg, lat1_deg, lon_deg, lat_deg))
    t12 = np.radians(initial_bearing_deg(lon1_deg, lat1_deg, lon2_deg, lat2_deg))
    return EARTH_RADIUS_KM * np.arcsin(np.clip(np.sin(d13) * np.sin(t13 - t12), -1.0, 1.0))


def along_track_km(
    lon1_deg: npt.ArrayLike,
    lat1_deg: npt.ArrayLike,
    lon2_deg: npt.ArrayLike,
    lat2_deg: npt.ArrayLike,
    lon_deg: npt.ArrayLike,
    lat_deg: npt.ArrayLike,
) -> FloatArray:
    """Distance [km] from point 1 along the great circle 1 → 2 to the foot of the perpendicular from a point.

    >>> round(float(along_track_km(0.0, 0.0, 10.0, 0.0, 5.0, -1.0)), 1)
    556.0
    """
    d13 = _central_angle(
        np.asarray(lon1_deg, float),
        np.asarray(lat1_deg, float),
        np.asarray(lon_deg, float),
        np.asarray(lat_deg, float),
    )
    xt = cross_track_km(lon1_deg, lat1_deg, lon2_deg, lat2_deg, lon_deg, lat_deg) / EARTH_RADIUS_KM
    t13 = np.radians(initial_bearing_deg(lon1_deg, lat1_deg, lon_deg, lat_deg))
    t12 = np.radians(initial_bearing_deg(lon1_deg, lat1_deg, lon2_deg, lat2_deg))
    sign = np.sign(np.cos(t13 - t12))
    return sign * EARTH_RADIUS_KM * np.arccos(np.clip(np.cos(d13) / np.cos(xt), -1.0, 1.0))


def geodesic_distance_km(
    lon1_deg: npt.ArrayLike, lat1_deg: npt.ArrayLike, lon2_deg: npt.ArrayLike, lat2_deg: npt.ArrayLike
) -> FloatArray:
    """Geodesic distance on the WGS84 ellipsoid [km] (``pyproj.Geod``; Karney 2013, doi:10.1007/s00190-012-0578-z)."""
    from pyproj import Geod

    lon1, lat1, lon2, lat2 = np.broadcast_arrays(
        *(np.asarray(a, dtype=float) for a in (lon1_deg, lat1_deg, lon2_deg, lat2_deg))
    )
    _, _, dist_m = Geod(ellps="WGS84").inv(lon1, lat1, lon2, lat2)
    return np.asarray(dist_m, dtype=float) / 1000.0


def distance_to_segment_nm(
    lon_deg: float, lat_deg: float, a: tuple[float, float], b: tuple[float, float] | None = None
) -> float:
    """Distance [nm] from a point to the great-circle segment from ``a`` to ``b`` (``(lon, lat)`` [deg]): to its
    nearest point, the foot of the perpendicular where that lies on the segment, else the nearer end. ``b`` None: to
    the point ``a``.

    >>> round(distance_to_segment_nm(1.0, 1.0, (0.0, 0.0), (2.0, 0.0)), 2)  # one degree north of the middle
    60.04
    >>> round(distance_to_segment_nm(3.0, 0.0, (0.0, 0.0), (2.0, 0.0)), 2)  # beyond the end (2, 0)
    60.04
    """
    ends = float(distance_nm(lon_deg, lat_deg, *a))
    if b is None:
        return ends
    ends = min(ends, float(distance_nm(lon_deg, lat_deg, *b)))
    along = float(along_track_km(*a, *b, lon_deg, lat_deg))
    if 0.0 <= along <= float(distance_km(*a, *b)):
        return min(ends, abs(float(cross_track_km(*a, *b, lon_deg, lat_deg))) / KM_PER_NM)
    return ends


def crossing_fraction(
    lon0_deg: npt.ArrayLike,
    lat0_deg: npt.ArrayLike,
    lon1_deg: npt.ArrayLike,
    lat1_deg: npt.ArrayLike,
    lon_c_deg: float,
    lat_c_deg: float,
    lon_d_deg: float,
    lat_d_deg: float,
) -> FloatArray:
    """Where great-circle arcs 0 → 1 cross the great-circle segment c → d: fraction of the arc's length.

    Returns the fraction in [0, 1] along each arc at which it meets the segment, NaN where it does not
    (parallel arcs included). Both segments must be shorter than half a great circle.

    >>> float(crossing_fraction(-1.0, 0.0, 1.0, 0.0, 0.0, -1.0, 0.0, 1.0))  # the equator crosses lon 0 midway
    0.5
    >>> bool(np.isnan(crossing_fraction(-1.0, 0.0, -0.5, 0.0, 0.0, -1.0, 0.0, 1.0)))
    True
    """
    a = to_xyz(lon0_deg, lat0_deg)
    b = to_xyz(lon1_deg, lat1_deg)
    a, b = np.broadcast_arrays(a, b)
    c = to_xyz(lon_c_deg, lat_c_deg)
    d = to_xyz(lon_d_deg, lat_d_deg)
    n1 = np.cross(a, b)
    n2 = np.cross(c, d)
    p = np.cross(n1, n2)
    norm = np.linalg.norm(p, axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        p = p / norm[..., None]
    # of the two antipodal intersections, keep the one nearer the arc's midpoint
    mid = a + b
    p = np.where((np.einsum("...i,...i->...", p, mid) < 0)[..., None], -p, p)
    tol = 1e-12

    def between(u: FloatArray, v: FloatArray, q: FloatArray, n: FloatArray) -> npt.NDArray[np.bool_]:
        return (np.einsum("...i,...i->...", np.cross(u, q), n) >= -tol) & (
            np.einsum("...i,...i->...", np.cross(q, v), n) >= -tol
        )

    on_both = between(a, b, p, n1) & between(np.broadcast_to(c, a.shape), np.broadcast_to(d, a.shape), p, n2)
    on_both &= norm > 1e-15
    ang_ab = np.arctan2(np.linalg.norm(n1, axis=-1), np.einsum("...i,...i->...", a, b))
    ang_ap = np.arctan2(np.linalg.norm(np.cross(a, p), axis=-1), np.einsum("...i,...i->...", a, p))
    with np.errstate(invalid="ignore", divide="ignore"):
        frac = ang_ap / ang_ab
    return np.where(on_both & np.isfinite(frac), np.clip(frac, 0.0, 1.0), np.nan)
