"""Great-circle geometry against pyproj.Geod on the same sphere (an independent implementation)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pyproj import Geod

from pyroute_rel import geodesy
from pyroute_rel.errors import GridError

SPHERE = Geod(a=geodesy.EARTH_RADIUS_KM * 1000.0, b=geodesy.EARTH_RADIUS_KM * 1000.0)

lons = st.floats(-179.0, 179.0)
lats = st.floats(-80.0, 80.0)


def _points(seed: int, n: int = 500) -> tuple[np.ndarray, ...]:
    rng = np.random.default_rng(seed)
    lon1, lon2 = rng.uniform(-180, 180, (2, n))
    lat1, lat2 = rng.uniform(-85, 85, (2, n))
    return lon1, lat1, lon2, lat2


def test_distance_and_bearing_match_pyproj_sphere() -> None:
    lon1, lat1, lon2, lat2 = _points(1)
    az, _, dist_m = SPHERE.inv(lon1, lat1, lon2, lat2)
    np.testing.assert_allclose(geodesy.distance_km(lon1, lat1, lon2, lat2), dist_m / 1000.0, rtol=1e-9, atol=1e-6)
    np.testing.assert_allclose(geodesy.distance_nm(lon1, lat1, lon2, lat2), dist_m / 1852.0, rtol=1e-9, atol=1e-6)
    diff = geodesy.angle_diff_deg(geodesy.initial_bearing_deg(lon1, lat1, lon2, lat2), np.asarray(az) % 360.0)
    assert np.max(diff) < 1e-7


def test_destination_matches_pyproj_fwd() -> None:
    rng = np.random.default_rng(2)
    lon, lat = rng.uniform(-180, 180, 300), rng.uniform(-80, 80, 300)
    brg, d_km = rng.uniform(0, 360, 300), rng.uniform(0, 5000, 300)
    lon2, lat2, _ = SPHERE.fwd(lon, lat, brg, d_km * 1000.0)
    got_lon, got_lat = geodesy.destination_point(lon, lat, brg, d_km)
    np.testing.assert_allclose(got_lat, lat2, atol=1e-8)
    assert np.max(geodesy.angle_diff_deg(got_lon, lon2)) < 1e-8


@pytest.mark.slow
@given(lons, lats, lons, lats, st.floats(0.0, 1.0))
@settings(max_examples=200, deadline=None)
def test_intermediate_point_lies_on_great_circle_at_fraction(lo1, la1, lo2, la2, f) -> None:
    d = float(geodesy.distance_km(lo1, la1, lo2, la2))
    if d < 1e-3 or d > 19000.0:
        return
    lon, lat = geodesy.intermediate_point(lo1, la1, lo2, la2, f)
    # pyproj: the point at distance f*d along the initial azimuth
    az, _, _ = SPHERE.inv(lo1, la1, lo2, la2)
    ref_lon, ref_lat, _ = SPHERE.fwd(lo1, la1, az, f * d * 1000.0)
    assert float(geodesy.distance_km(lon, lat, ref_lon, ref_lat)) < 1e-6


def test_cross_and_along_track_against_dense_great_circle() -> None:
    """Brute force: the nearest of 20001 points along the great circle (pyproj.npts) gives |xtd| and atd."""
    lon1, lat1, lon2, lat2 = -12.0, 45.0, -60.0, 17.5
    pts = np.array([(lon1, lat1), *SPHERE.npts(lon1, lat1, lon2, lat2, 19999), (lon2, lat2)])
    total = float(geodesy.distance_km(lon1, lat1, lon2, lat2))
    s = np.linspace(0.0, total, len(pts))
    rng = np.random.default_rng(3)
    for lon, lat in zip(rng.uniform(-55, -15, 20), rng.uniform(20, 42, 20), strict=True):
        d = geodesy.distance_km(lon, lat, pts[:, 0], pts[:, 1])
        i = int(np.argmin(d))
        xt = float(geodesy.cross_track_km(lon1, lat1, lon2, lat2, lon, lat))
        at = float(geodesy.along_track_km(lon1, lat1, lon2, lat2, lon, lat))
        assert abs(abs(xt) - d[i]) < 0.05  # 20001 points are ~0.3 km apart; the minimum is flat
        assert abs(at - s[i]) < 0.5
        # sign: positive when the point lies to starboard of the course at the foot of the perpendicular
        j = min(i, len(pts) - 2)
        course = geodesy.initial_bearing_deg(pts[j, 0], pts[j, 1], pts[j + 1, 0], pts[j + 1, 1])
        to_point = geodesy.initial_bearing_deg(pts[i, 0], pts[i, 1], lon, lat)
        starboard = geodesy.angle_diff_deg(to_point, course + 90.0) < 90.0
        assert (xt > 0) == bool(starboard)


def test_cross_track_sign_starboard_positive() -> None:
    # heading east along the equator, a point south is to starboard (right)
    assert geodesy.cross_track_km(0.0, 0.0, 10.0, 0.0, 5.0, -1.0) > 0
    assert geodesy.cross_track_km(0.0, 0.0, 10.0, 0.0, 5.0, 1.0) < 0


def test_geodesic_distance_is_ellipsoidal() -> None:
    # pyproj WGS84 geodesic vs sphere differ by < 0.5 % on the Microtransat course
    e = float(geodesy.geodesic_distance_km(-12.0, 45.0, -60.0, 17.5))
    s = float(geodesy.distance_km(-12.0, 45.0, -60.0, 17.5))
    _, _, ref = Geod(ellps="WGS84").inv(-12.0, 45.0, -60.0, 17.5)
    assert e == pytest.approx(ref / 1000.0, rel=1e-12)
    assert abs(e - s) / e < 0.005


@given(st.floats(-1000, 1000), st.floats(-1000, 1000))
def test_angle_diff_is_symmetric_and_bounded(a, b) -> None:
    d = float(geodesy.angle_diff_deg(a, b))
    assert 0.0 <= d <= 180.0
    assert d == pytest.approx(float(geodesy.angle_diff_deg(b, a)), abs=1e-9)
    assert d == pytest.approx(float(geodesy.angle_diff_deg(a + 360.0, b)), abs=1e-9)


def test_latitudes_off_the_globe_are_refused() -> None:
    from pyroute_rel.errors import CoordinateError

    # distance_km(0, 91, 1, 0) returned 10118.7 km
    for call in (
        lambda: geodesy.distance_km(0.0, 91.0, 1.0, 0.0),
        lambda: geodesy.initial_bearing_deg(0.0, 0.0, 1.0, -90.5),
        lambda: geodesy.to_xyz([0.0, 1.0], [0.0, 95.0]),
        lambda: geodesy.destination_point(0.0, 120.0, 90.0, 10.0),
        lambda: geodesy.cross_track_km(0.0, 0.0, 10.0, 0.0, 5.0, 91.0),
    ):
        with pytest.raises(CoordinateError, match=r"latitude must be in \[-90, 90\] \[deg\]"):
            call()
    assert np.isnan(geodesy.distance_km(0.0, np.nan, 1.0, 0.0))  # NaN passes through, as documented
    assert float(geodesy.distance_km(0.0, 90.0, 180.0, 90.0)) == pytest.approx(0.0, abs=1e-9)


# gc_densify (moved here from test_obstacles with the function: pyroute_rel.obstacles.land -> geodesy)

densify_lons = st.floats(-180.0, 179.999)


@pytest.mark.slow
@settings(max_examples=60, deadline=None)
@given(lon0=densify_lons, lat0=lats, lon1=densify_lons, lat1=lats, step=st.floats(0.5, 400.0))
def test_gc_densify_matches_proj_great_circle(lon0, lat0, lon1, lat1, step):
    length = SPHERE.inv(lon0, lat0, lon1, lat1)[2] / 1000.0
    if length > 0.95 * np.pi * geodesy.EARTH_RADIUS_KM:  # near-antipodal: no unique great circle
        return
    a = [np.array([v]) for v in (lon0, lat0, lon1, lat1)]
    lon, lat, arc = geodesy.gc_densify(*a, max_step_km=step)
    assert (arc == 0).all()
    assert (lon[0], lat[0], lat[-1]) == (lon0, lat0, lat1)
    assert (lon[-1] - lon1) % 360.0 == pytest.approx(0.0, abs=1e-9) or (lon[-1] - lon1) % 360.0 == pytest.approx(
        360.0, abs=1e-9
    )
    assert np.all(np.abs(np.diff(lon)) < 180.0)  # unwrapped: continuous longitudes
    gaps = SPHERE.inv(lon[:-1], lat[:-1], lon[1:], lat[1:])[2] / 1000.0
    assert gaps.max() <= step * (1 + 1e-9) + 1e-9
    if lon.size > 2:
        ref = np.array(SPHERE.npts(lon0, lat0, lon1, lat1, lon.size - 2))
        np.testing.assert_allclose(lat[1:-1], ref[:, 1], atol=1e-7)
        dlon = (lon[1:-1] - ref[:, 0] + 180.0) % 360.0 - 180.0
        np.testing.assert_allclose(dlon * np.cos(np.radians(ref[:, 1])), 0.0, atol=1e-7)


def test_gc_densify_refuses_antipodal_end_points() -> None:
    with pytest.raises(GridError, match="antipodal"):
        geodesy.gc_densify(np.array([0.0]), np.array([0.0]), np.array([180.0]), np.array([0.0]), max_step_km=10.0)


def test_angle_between_matches_haversine_and_is_accurate_for_tiny_angles() -> None:
    lon1, lat1, lon2, lat2 = _points(7)
    got = geodesy.angle_between(geodesy.to_xyz(lon1, lat1), geodesy.to_xyz(lon2, lat2)) * geodesy.EARTH_RADIUS_KM
    np.testing.assert_allclose(got, SPHERE.inv(lon1, lat1, lon2, lat2)[2] / 1000.0, rtol=1e-9, atol=1e-6)
    # 1 mm apart: arccos of the dot product would round to 0 or to ~0.1 km
    tiny = geodesy.angle_between(geodesy.to_xyz(10.0, 20.0), geodesy.to_xyz(10.0, 20.0 + 1e-6 / 111.19508))
    assert float(tiny) * geodesy.EARTH_RADIUS_KM * 1e6 == pytest.approx(1.0, rel=1e-6)


def test_from_xyz_inverts_to_xyz_with_and_without_the_wrap() -> None:
    lon, lat = np.array([-180.0, -45.0, 0.0, 135.0, 179.5]), np.array([-60.0, 0.0, 30.0, 89.0, -1.0])
    xyz = geodesy.to_xyz(lon, lat)
    got_lon, got_lat = geodesy.from_xyz(xyz)
    np.testing.assert_allclose(got_lat, lat, atol=1e-12)
    np.testing.assert_allclose(got_lon, lon, atol=1e-12)
    assert ((got_lon >= -180.0) & (got_lon < 180.0)).all()
    raw_lon, raw_lat = geodesy.from_xyz(3.0 * xyz, wrap=False)  # vectors need not be unit
    np.testing.assert_allclose(raw_lat, got_lat, atol=1e-12)
    assert raw_lon[0] in (-180.0, 180.0)  # arctan2's own branch, not wrapped
    np.testing.assert_allclose(raw_lon[1:], lon[1:], atol=1e-12)
