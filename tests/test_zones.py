"""Tests of pyroute_rel.obstacles.zones: GeoJSON exclusion zones, their time windows and the arcs they block.

Independent reference for the arc test: ``pyproj.Geod`` (PROJ's geodesic code) on the same sphere densifies each
great-circle arc to points at most 0.5 km apart, and shapely's ``intersects`` tests that polyline against an
unprepared copy of the zone (once more shifted by 360 deg where the polyline runs past the antimeridian).
"""

from __future__ import annotations

import json

import numpy as np
import pytest
import shapely
from test_obstacles import random_arcs, reference_blocked  # the same slow reference serves land and zones

from pyroute_rel.errors import ScenarioError
from pyroute_rel.obstacles import zones as zn


def write(tmp_path, name, doc):
    path = tmp_path / name
    path.write_text(doc if isinstance(doc, str) else json.dumps(doc))
    return path


def square(x0, y0, x1, y1):
    return [[x0, y0], [x1, y0], [x1, y1], [x0, y1], [x0, y0]]


def feature(geometry, **properties):
    return {"type": "Feature", "properties": properties, "geometry": geometry}


# --------------------------------------------------------------------------------------------------
# Moved from test_obstacles (zones only)
# --------------------------------------------------------------------------------------------------


def test_polygon_with_hole_blocks_the_ring_not_the_hole(tmp_path):
    doc = {"type": "Polygon", "coordinates": [square(0, 0, 4, 4), square(1, 1, 3, 3)]}
    (zone,) = zn.load_zones([write(tmp_path, "ring.geojson", doc)])
    assert zone.name == "ring" and zone.valid_from is None and zone.valid_to is None
    assert zone.geometry.area == pytest.approx(16.0 - 4.0)  # square minus hole, deg^2
    lon0, lat0 = [1.5, 0.5, 5.0, -1.0, 1.2], [2.0, 2.0, 2.0, 2.0, 1.2]
    lon1, lat1 = [2.5, 2.0, 6.0, 5.0, 2.8], [2.0, 2.0, 2.0, 2.0, 2.8]
    got = zn.arcs_blocked_by_zones(lon0, lat0, lon1, lat1, [zone])
    assert got.tolist() == [False, True, False, True, False]  # inside the hole only -> free
    np.testing.assert_array_equal(got, reference_blocked(lon0, lat0, lon1, lat1, zone.geometry))


def test_multipolygon_feature_collection_and_names(tmp_path):
    doc = {
        "type": "FeatureCollection",
        "features": [
            {
                "type": "Feature",
                "properties": {"name": "two boxes"},
                "geometry": {"type": "MultiPolygon", "coordinates": [[square(0, 0, 1, 1)], [square(3, 0, 4, 1)]]},
            },
            {
                "type": "Feature",
                "properties": None,
                "geometry": {"type": "Polygon", "coordinates": [square(10, 10, 11, 11)]},
            },
        ],
    }
    zones = zn.load_zones("multi.geojson", base_dir=write(tmp_path, "multi.geojson", doc).parent)
    assert [z.name for z in zones] == ["two boxes", "multi[1]"]
    assert zones[0].geometry.geom_type == "MultiPolygon"
    got = zn.arcs_blocked_by_zones(
        [-0.5, 2.5, 1.5, 9.5], [0.5, 0.5, 0.5, 10.5], [0.5, 3.5, 2.5, 10.5], [0.5, 0.5, 0.5, 10.5], zones
    )
    assert got.tolist() == [True, True, False, True]


def test_time_windows(tmp_path):
    doc = {
        "type": "Feature",
        "properties": {"valid_from": "2018-06-01T02:00:00+02:00", "valid_to": "2018-06-30"},
        "geometry": {"type": "Polygon", "coordinates": [square(0, 0, 1, 1)]},
    }
    (zone,) = zn.load_zones([write(tmp_path, "timed.geojson", doc)])
    assert zone.valid_from == np.datetime64("2018-06-01T00:00:00")  # converted to UTC
    assert zone.valid_to == np.datetime64("2018-06-30T00:00:00")  # a date alone is its midnight
    arc = (-0.5, 0.5, 1.5, 0.5)
    times = np.array(
        ["2018-05-31T23:59", "2018-06-01T00:00", "2018-06-15", "2018-06-30T00:00", "2018-06-30T00:01", "NaT"],
        dtype="datetime64[m]",
    )
    got = zn.arcs_blocked_by_zones(*arc, [zone], times)
    assert got.tolist() == [False, True, True, True, False, True]  # NaT: unknown time, zone counts
    assert zn.arcs_blocked_by_zones(*arc, [zone]).item()  # time=None: every zone active
    # with arrival times, a window overlapping the passage blocks it
    dep = np.array(["2018-05-30", "2018-07-01"], dtype="datetime64[s]")
    arr = np.array(["2018-06-02", "2018-07-02"], dtype="datetime64[s]")
    assert zn.arcs_blocked_by_zones(*arc, [zone], dep, time_end=arr).tolist() == [True, False]
    # per-arc times broadcast against a 2-D array of arcs
    lon0 = np.array([[-0.5, -0.5], [5.0, -0.5]])
    t = np.array([["2018-06-10"], ["2018-07-10"]], dtype="datetime64[s]")
    assert zn.arcs_blocked_by_zones(lon0, 0.5, lon0 + 2.0, 0.5, [zone], t).tolist() == [[True, True], [False, False]]
    assert zn.zones_active([zone], np.datetime64("2018-05-20"), np.datetime64("2018-06-02")) == (zone,)
    assert zn.zones_active([zone], np.datetime64("2018-07-20")) == ()


def test_antimeridian_arcs_are_short_arcs(tmp_path):
    # a zone split at the antimeridian (RFC 7946), and one at 0 deg that a naive 358-deg line would cross
    doc = {
        "type": "FeatureCollection",
        "features": [
            {
                "type": "Feature",
                "properties": {"name": "seam"},
                "geometry": {
                    "type": "MultiPolygon",
                    "coordinates": [[square(179.5, -1, 180, 1)], [square(-180, -1, -179.5, 1)]],
                },
            },
            {
                "type": "Feature",
                "properties": {"name": "greenwich"},
                "geometry": {"type": "Polygon", "coordinates": [square(-1, 4, 1, 6)]},
            },
        ],
    }
    zones = zn.load_zones([write(tmp_path, "seam.geojson", doc)])
    lon0 = np.array([179.0, 179.0, 179.9, -179.0, 170.0, -178.0])
    lat0 = np.array([0.0, 5.0, 0.5, 0.0, 0.0, 0.0])
    lon1 = np.array([-179.0, -179.0, -179.9, 179.0, 175.0, -179.7])
    lat1 = np.array([0.0, 5.0, 0.5, 0.0, 0.0, 0.0])
    got = zn.arcs_blocked_by_zones(lon0, lat0, lon1, lat1, zones)
    assert got.tolist() == [True, False, True, True, False, True]
    np.testing.assert_array_equal(
        got, reference_blocked(lon0, lat0, lon1, lat1, shapely.union_all([z.geometry for z in zones]))
    )


def test_vectorised_zone_test_equals_slow_reference(tmp_path):
    doc = {
        "type": "Polygon",
        "coordinates": [
            [[-32, 36], [-28, 35.5], [-27, 38], [-29, 39.5], [-30, 37.5], [-32, 38.5], [-32, 36]],
            square(-29.5, 36.5, -28.5, 37.2),
        ],
    }
    (zone,) = zn.load_zones([write(tmp_path, "z.geojson", doc)])
    rng = np.random.default_rng(3)
    lon0, lat0, lon1, lat1 = random_arcs(rng, 300, (-34.0, 34.0, -25.0, 41.0), (5.0, 400.0))
    fast = zn.arcs_blocked_by_zones(lon0, lat0, lon1, lat1, [zone])
    np.testing.assert_array_equal(fast, reference_blocked(lon0, lat0, lon1, lat1, zone.geometry))
    assert 0.2 < fast.mean() < 0.8


def test_self_intersecting_polygon_is_refused_where_it_crosses(tmp_path):
    # issue 17 item 7: a figure of eight is a mistake (positions out of order), not two zones: refused, with where.
    # The edges (0,0)-(2,2) and (2,0)-(0,2) cross at (1, 1).
    bowtie = {"type": "Polygon", "coordinates": [[[0, 0], [2, 2], [2, 0], [0, 2], [0, 0]]]}
    with pytest.raises(ScenarioError, match=r"bowtie.geojson: the polygon's edges cross at lon 1, lat 1"):
        zn.load_zones([write(tmp_path, "bowtie.geojson", bowtie)])
    # (10,40)-(12,44) and (12,40)-(10,44) cross at (11, 42); a hole outside its shell is refused too
    eight = {"type": "Polygon", "coordinates": [[[10, 40], [12, 44], [12, 40], [10, 44], [10, 40]]]}
    with pytest.raises(ScenarioError, match=r"cross at lon 11, lat 42"):
        zn.load_zones([write(tmp_path, "eight.geojson", eight)])
    outside = {"type": "Polygon", "coordinates": [square(0, 0, 1, 1), square(5, 5, 6, 6)]}
    with pytest.raises(ScenarioError, match=r"invalid polygon at lon 5, lat 5 \(Hole lies outside shell"):
        zn.load_zones([write(tmp_path, "outside.geojson", outside)])
    unclosed = {"type": "Polygon", "coordinates": [[[0, 0], [1, 0], [1, 1], [0, 1]]]}
    (zone,) = zn.load_zones([write(tmp_path, "unclosed.geojson", unclosed)])
    assert zone.geometry.equals(shapely.box(0, 0, 1, 1))


POLY = {"type": "Polygon", "coordinates": [square(0, 0, 1, 1)]}


@pytest.mark.parametrize(
    ("content", "match"),
    [
        ("{not json", "not valid JSON"),
        ([1, 2], "GeoJSON object"),
        ({"type": "Point", "coordinates": [0, 0]}, "FeatureCollection, Feature, Polygon or MultiPolygon"),
        (
            {"type": "Feature", "properties": {}, "geometry": {"type": "LineString", "coordinates": [[0, 0], [1, 1]]}},
            "Polygon or MultiPolygon",
        ),
        (
            {
                "type": "FeatureCollection",
                "features": [{"type": "Feature", "geometry": POLY}, {"type": "Feature", "geometry": None}],
            },
            "feature 1",
        ),
        ({"type": "FeatureCollection", "features": []}, "no features"),
        ({"type": "Polygon", "coordinates": [square(170, 0, 200, 1)]}, r"lon in \[-180, 180\].*200"),
        ({"type": "Polygon", "coordinates": [[[0, 0], [1, 1], [2, 2], [0, 0]]]}, "edges cross at lon 1, lat 1"),
        ({"type": "Polygon", "coordinates": [[[0, 0], [1, "a"], [2, 2], [0, 0]]]}, "number pairs"),
        ({"type": "Polygon", "coordinates": [[[0, 0], [1, 1], [0, 0]]]}, "at least 3 distinct"),
        ({"type": "Feature", "properties": {"valid_from": "June 2018"}, "geometry": POLY}, "ISO 8601"),
        (
            {"type": "Feature", "properties": {"valid_from": "2018-07-01", "valid_to": "2018-06-01"}, "geometry": POLY},
            "before valid_from",
        ),
        ({"type": "Feature", "properties": {"name": 3}, "geometry": POLY}, "'name' must be a non-empty string"),
        ({**POLY, "crs": {"type": "name", "properties": {"name": "EPSG:3857"}}}, "CRS84"),
        # drawn across the antimeridian without splitting: in planar lon/lat it is a band round the globe, which
        # blocked an Atlantic course (QA)
        (
            {"type": "Polygon", "coordinates": [[[179, 36], [-179, 36], [-179, 39], [179, 39], [179, 36]]]},
            r"edge from \[179, 36\] to \[-179, 36\] spans 358 deg of longitude.*split.*RFC 7946",
        ),
    ],
)
def test_bad_geojson_raises_scenario_error_naming_the_file(tmp_path, content, match):
    path = write(tmp_path, "bad_zone.geojson", content)
    with pytest.raises(ScenarioError, match=match) as info:
        zn.load_zones([path])
    assert "bad_zone.geojson" in str(info.value)
    assert "\n" not in str(info.value)


def test_missing_zone_file(tmp_path):
    with pytest.raises(ScenarioError, match=r"nowhere\.geojson: zone file not found"):
        zn.load_zones(["nowhere.geojson"], base_dir=tmp_path)


# --------------------------------------------------------------------------------------------------
# Loading
# --------------------------------------------------------------------------------------------------


def test_bare_multipolygon_and_several_files_in_order(tmp_path):
    multi = {
        "type": "MultiPolygon",
        "coordinates": [[square(0, 0, 1, 1)], [square(2, 0, 3, 1), square(2.2, 0.2, 2.8, 0.8)]],
    }
    a = write(tmp_path, "a.geojson", multi)
    b = write(tmp_path, "b.geojson", feature({"type": "Polygon", "coordinates": [square(5, 5, 6, 6)]}, name="B"))
    zones = zn.load_zones([a, b])
    assert [z.name for z in zones] == ["a", "B"]
    assert zones[0].geometry.geom_type == "MultiPolygon"
    assert zones[0].geometry.area == pytest.approx(1.0 + 1.0 - 0.36)  # the hole of the second part is free water
    assert zones[1].geometry.geom_type == "Polygon"
    assert all(z.valid_from is None and z.valid_to is None for z in zones)
    assert zn.load_zones(a) == zn.load_zones([a])[:1]  # one path, not only a list


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("2018-06-01T00:00:00Z", "2018-06-01T00:00:00"),
        ("2018-06-01T12:30:00-03:00", "2018-06-01T15:30:00"),  # offsets converted to UTC
        (" 2018-06-01T06:00 ", "2018-06-01T06:00:00"),  # naive: UTC; surrounding blanks ignored
        ("2018-06-01", "2018-06-01T00:00:00"),  # a date alone is its midnight
    ],
)
def test_time_window_strings_are_read_as_utc(tmp_path, text, expected):
    doc = feature({"type": "Polygon", "coordinates": [square(0, 0, 1, 1)]}, valid_from=text)
    (zone,) = zn.load_zones([write(tmp_path, "t.geojson", doc)])
    assert zone.valid_from == np.datetime64(expected)
    assert zone.valid_to is None


def test_a_crs84_member_is_accepted(tmp_path):
    doc = {
        "type": "Polygon",
        "coordinates": [square(0, 0, 1, 1)],
        "crs": {"type": "name", "properties": {"name": "urn:ogc:def:crs:OGC:1.3:CRS84"}},
    }
    (zone,) = zn.load_zones([write(tmp_path, "crs.geojson", doc)])
    assert zone.geometry.equals(shapely.box(0, 0, 1, 1))


# --------------------------------------------------------------------------------------------------
# Time windows
# --------------------------------------------------------------------------------------------------

JUNE = zn.Zone(
    "june", shapely.box(0, 0, 1, 1), np.datetime64("2018-06-01T00:00:00"), np.datetime64("2018-06-30T00:00:00")
)


@pytest.mark.parametrize(
    ("t0", "t1", "active"),
    [
        ("2018-05-15", None, False),  # before the window
        ("2018-05-31T23:59:59.999999999", None, False),  # one nanosecond before it opens
        ("2018-06-01T00:00:00", None, True),  # the opening instant belongs to the window
        ("2018-06-15T12:00", None, True),  # inside
        ("2018-06-30T00:00:00", None, True),  # the closing instant too
        ("2018-06-30T00:00:00.000000001", None, False),  # one nanosecond after it closes
        ("2018-07-15", None, False),  # after
        ("2018-05-20", "2018-05-31T23:59:59", False),  # a passage ending just before it opens
        ("2018-05-20", "2018-06-01T00:00:00", True),  # ... ending as it opens
        ("2018-06-30T00:00:00", "2018-07-05", True),  # a passage starting as it closes
        ("2018-06-30T00:00:01", "2018-07-05", False),  # ... just after
        ("2018-05-01", "2018-08-01", True),  # a passage spanning the whole window
    ],
)
def test_zones_active_inside_outside_and_at_the_boundaries(t0, t1, active):
    got = zn.zones_active([JUNE], np.datetime64(t0), None if t1 is None else np.datetime64(t1))
    assert got == ((JUNE,) if active else ())
    assert bool(JUNE.active(np.datetime64(t0), None if t1 is None else np.datetime64(t1))) is active


def test_open_ended_windows_and_zones_without_a_window():
    always = zn.Zone("always", shapely.box(0, 0, 1, 1))
    from_july = zn.Zone("from july", shapely.box(0, 0, 1, 1), valid_from=np.datetime64("2018-07-01"))
    until_july = zn.Zone("until july", shapely.box(0, 0, 1, 1), valid_to=np.datetime64("2018-07-01"))
    zones = [always, from_july, until_july]
    assert zn.zones_active(zones, np.datetime64("1900-01-01")) == (always, until_july)
    assert zn.zones_active(zones, np.datetime64("2018-07-01")) == (always, from_july, until_july)
    assert zn.zones_active(zones, np.datetime64("2100-01-01")) == (always, from_july)
    # vectorised over times; NaT (time unknown) counts as active
    t = np.array(["2018-06-30", "2018-07-01", "2018-07-02", "NaT"], dtype="datetime64[s]")
    assert from_july.active(t).tolist() == [False, True, True, True]
    assert until_july.active(t).tolist() == [True, True, False, True]
    assert always.active(t).tolist() == [True, True, True, True]


# --------------------------------------------------------------------------------------------------
# Arcs against an independent reference
# --------------------------------------------------------------------------------------------------


def test_multipolygon_with_hole_equals_densified_reference():
    geom = shapely.MultiPolygon(
        [
            shapely.Polygon(
                [(-20, 40), (-17, 40.5), (-16, 43), (-19, 43.5)], [[(-18.5, 41), (-17.2, 41.2), (-18, 42.5)]]
            ),
            shapely.Polygon([(-14, 38), (-13, 38), (-13.5, 39.5)]),
        ]
    )
    zone = zn.Zone("multi", geom)
    rng = np.random.default_rng(11)
    lon0, lat0, lon1, lat1 = random_arcs(rng, 400, (-22.0, 37.0, -11.0, 45.0), (2.0, 500.0))
    fast = zn.arcs_blocked_by_zones(lon0, lat0, lon1, lat1, [zone])
    np.testing.assert_array_equal(fast, reference_blocked(lon0, lat0, lon1, lat1, geom))
    assert 0.1 < fast.mean() < 0.9


def test_timed_zones_block_an_arc_only_when_one_that_it_touches_is_active():
    a = zn.Zone("a", shapely.box(-30, 35, -28, 37), np.datetime64("2018-06-01"), np.datetime64("2018-06-30"))
    b = zn.Zone("b", shapely.box(-26, 35, -24, 37), np.datetime64("2018-07-01"), np.datetime64("2018-07-31"))
    rng = np.random.default_rng(12)
    lon0, lat0, lon1, lat1 = random_arcs(rng, 200, (-32.0, 33.0, -22.0, 39.0), (5.0, 600.0))
    times = np.array(["2018-05-15", "2018-06-15", "2018-07-15"], dtype="datetime64[s]")[rng.integers(0, 3, lon0.size)]
    got = zn.arcs_blocked_by_zones(lon0, lat0, lon1, lat1, [a, b], times)
    touch_a = reference_blocked(lon0, lat0, lon1, lat1, a.geometry)
    touch_b = reference_blocked(lon0, lat0, lon1, lat1, b.geometry)
    june, july = times == np.datetime64("2018-06-15"), times == np.datetime64("2018-07-15")
    np.testing.assert_array_equal(got, (touch_a & june) | (touch_b & july))
    assert got.any() and (touch_a & ~june).any()  # some arcs touch a zone out of its window: free


def test_no_zones_and_no_arcs():
    assert zn.arcs_blocked_by_zones([0.0, 1.0], 0.0, [1.0, 2.0], 0.0, []).tolist() == [False, False]
    empty = zn.arcs_blocked_by_zones(np.empty((0, 3)), 0.0, 1.0, 0.0, [JUNE])
    assert empty.shape == (0, 3)


# --------------------------------------------------------------------------------------------------
# Bad files: one line naming the file and the field
# --------------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("content", "field"),
    [
        ({"coordinates": []}, "'type'"),
        ({"type": "FeatureCollection", "features": {}}, "'features'"),
        ({"type": "MultiPolygon", "coordinates": []}, "'coordinates'"),
        ({"type": "Feature", "properties": [1], "geometry": POLY}, "'properties'"),
        (feature(POLY, name=""), "'name'"),
        (feature(POLY, valid_from=20180601), "'valid_from'"),
        (feature(POLY, valid_to="end of June"), "'valid_to'"),
        (feature(POLY, valid_from="2018-07-01", valid_to="2018-06-01"), "valid_to"),
        ({"type": "Polygon", "coordinates": [square(0, 0, 1, 100)]}, "lat in [-90, 90]"),
    ],
)
def test_bad_fields_are_named_in_a_one_line_error(tmp_path, content, field):
    path = write(tmp_path, "fields.geojson", content)
    with pytest.raises(ScenarioError) as info:
        zn.load_zones([path])
    message = str(info.value)
    assert message.startswith(f"{path}:")
    assert field in message
    assert "\n" not in message


def test_unreadable_zone_file_names_the_file(tmp_path):
    path = tmp_path / "latin1.geojson"
    path.write_bytes(b'{"type": "Polygon", "name": "\xe9"}')
    with pytest.raises(ScenarioError, match=r"latin1\.geojson: cannot read zone file") as info:
        zn.load_zones([path])
    assert "\n" not in str(info.value)


@pytest.mark.parametrize("paths", [None, 5, [None], ["a.geojson", 3]])
def test_load_zones_refuses_what_is_not_a_path(paths: object) -> None:
    # None and 5 raised TypeError ("not iterable"), [None] TypeError from pathlib.
    with pytest.raises(ScenarioError, match=r"zone files? must be a path"):
        zn.load_zones(paths)  # type: ignore[arg-type]
