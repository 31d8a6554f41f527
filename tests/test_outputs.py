"""A route's files (:mod:`pyroute_rel.outputs`): the GPX read back with gpxpy, and the turning points of its route."""

from __future__ import annotations

import dataclasses
import datetime as dt
import json
from pathlib import Path
from types import SimpleNamespace

import gpxpy
import numpy as np
import pytest

from pyroute_rel import geodesy
from pyroute_rel.outputs import (
    OUTPUT_FILES,
    TURN_THRESHOLD_DEG,
    forbidden_geojson,
    to_gpx,
    turning_points,
    write_outputs,
)
from pyroute_rel.routing.route import ForbiddenArcs, Legs
from pyroute_rel.scenario import load_scenario
from pyroute_rel.times import iso_utc
from pyroute_rel.units import KN_PER_MS

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "microtransat_control.toml"
OPENCPN = "{http://www.opencpn.org}"
GPXTPX = "{http://www.garmin.com/xmlschemas/TrackPointExtension/v2}"


@pytest.fixture(scope="module")
def route():
    sc = load_scenario(EXAMPLE).with_options(layout="square", n_nodes=21, n_ranks=21, land=False, apf=0.5)
    return sc.route(progress=False)


def _utc(t: np.datetime64) -> dt.datetime:
    return dt.datetime.fromisoformat(iso_utc(t).removesuffix("Z")).replace(tzinfo=dt.UTC)


def _with_wait(route, at: int, wait_h: float):
    """The same track with a wait of ``wait_h`` [h] at point ``at`` before its leg (later times shifted)."""
    legs = dict(route.legs)
    legs["wait_h"] = legs["wait_h"].copy()
    legs["wait_h"][at] += wait_h
    elapsed = route.elapsed_h.copy()
    elapsed[at + 1 :] += wait_h
    return dataclasses.replace(route, legs=Legs(**legs), elapsed_h=elapsed)


def test_gpx_round_trip_track_points_times_and_speeds(route) -> None:
    """GPX 1.1 written with gpxpy and read back with gpxpy: every track point, its time and its leg's speed."""
    gpx = gpxpy.parse(to_gpx(route))
    assert gpx.version == "1.1" and len(gpx.tracks) == 1 and len(gpx.routes) == 1
    points = gpx.tracks[0].segments[0].points
    assert len(points) == len(route.lon_deg)
    # coordinates are written to 1e-6 deg (0.1 m)
    np.testing.assert_allclose([p.longitude for p in points], route.lon_deg, rtol=0, atol=5e-7)
    np.testing.assert_allclose([p.latitude for p in points], route.lat_deg, rtol=0, atol=5e-7)
    assert [p.time for p in points] == [_utc(t) for t in route.time]
    assert points[-1].time == _utc(route.arrival)
    speeds = []
    for p in points[:-1]:
        (ext,) = p.extensions
        assert ext.tag == f"{GPXTPX}TrackPointExtension"
        speeds.append(float(ext.find(f"{GPXTPX}speed").text))
    # the speed over ground of the leg sailed from each point [m/s], written to 1e-4 m/s
    np.testing.assert_allclose(speeds, route.legs["sog_kn"] / KN_PER_MS, rtol=0, atol=5e-5)
    assert points[-1].extensions == []  # the finish starts no leg


def test_gpx_route_holds_the_turning_points_with_opencpn_speeds_and_departures(route) -> None:
    routed = _with_wait(route, 7, 3.0)
    gpx = gpxpy.parse(to_gpx(routed))
    rte = gpx.routes[0]
    turns = turning_points(routed)
    assert 7 in turns  # a wait is a turning point: its departure time differs from its arrival
    assert [p.name for p in rte.points] == ["start", *(f"T{i}" for i in turns[1:-1]), "finish"]
    np.testing.assert_allclose([p.longitude for p in rte.points], routed.lon_deg[turns], rtol=0, atol=5e-7)
    np.testing.assert_allclose([p.latitude for p in rte.points], routed.lat_deg[turns], rtol=0, atol=5e-7)
    assert [p.time for p in rte.points] == [_utc(routed.time[i]) for i in turns]
    ext = {e.tag: e.text for e in rte.extensions}
    assert ext[f"{OPENCPN}planned_departure"] == "2018-06-01T00:00:00Z"
    sail_h = routed.legs["time_h"]
    assert float(ext[f"{OPENCPN}planned_speed"]) == pytest.approx(routed.distance_nm / sail_h.sum(), abs=5e-5)
    props = [p.extensions[0].attrib for p in rte.points]
    assert "planned_speed" not in props[0] and "etd" not in props[-1]
    for j in range(1, len(turns)):
        k, i = turns[j - 1], turns[j]
        # OpenCPN reads a point's planned speed as that of the leg ending at it [kn]; sailing time, waits excluded
        want = routed.legs["distance_nm"][k:i].sum() / sail_h[k:i].sum()
        assert float(props[j]["planned_speed"]) == pytest.approx(want, abs=5e-5)
    for j, i in enumerate(turns[:-1]):
        wait_s = round(float(routed.legs["wait_h"][i]) * 3600.0)
        assert props[j]["etd"] == iso_utc(routed.time[i] + np.timedelta64(wait_s, "s"))
    j7 = list(turns).index(7)
    assert props[j7]["etd"] == iso_utc(routed.time[7] + np.timedelta64(3 * 3600, "s"))


def _track(lon, lat) -> SimpleNamespace:
    lon, lat = np.asarray(lon, dtype=float), np.asarray(lat, dtype=float)
    return SimpleNamespace(lon_deg=lon, lat_deg=lat, legs={"wait_h": np.zeros(len(lon) - 1)})


def test_a_great_circle_has_no_turning_point_and_a_corner_has_one() -> None:
    f = np.linspace(0.0, 1.0, 30)
    lon, lat = geodesy.intermediate_point(-12.0, 45.0, -60.0, 17.5, f)
    assert turning_points(_track(lon, lat)).tolist() == [0, 29]
    lon2, lat2 = geodesy.intermediate_point(-60.0, 17.5, -70.0, 40.0, f[1:])
    both = _track(np.r_[lon, lon2], np.r_[lat, lat2])
    assert turning_points(both).tolist() == [0, 29, 58]


def test_small_bends_add_up_to_turning_points() -> None:
    """A track bending by 0.4 deg at every point (under the 1 deg threshold) still turns: the bends add up, so the
    straight legs between its turning points never leave the track's course by more than the threshold."""
    course = 90.0 + 0.4 * np.arange(60)
    lon, lat = [0.0], [0.0]
    for c in course:
        lo, la = geodesy.destination_point(lon[-1], lat[-1], c, 20.0)
        lon.append(float(lo))
        lat.append(float(la))
    track = _track(lon, lat)
    turns = turning_points(track)
    assert turns[0] == 0 and turns[-1] == len(lon) - 1 and 5 < len(turns) < 40
    for k, i in zip(turns[:-1], turns[1:], strict=True):
        chord = geodesy.initial_bearing_deg(lon[k], lat[k], lon[i], lat[i])
        for j in range(k, i):  # every track leg between two turning points, against the route leg
            leg = geodesy.initial_bearing_deg(lon[j], lat[j], lon[j + 1], lat[j + 1])
            assert geodesy.angle_diff_deg(leg, chord) < 2 * TURN_THRESHOLD_DEG
    assert len(turning_points(track, threshold_deg=0.1)) == len(lon)  # every bend exceeds 0.1 deg


def test_forbidden_geojson_holds_the_forbidden_arcs_table(route, tmp_path: Path) -> None:
    """``--out`` writes forbidden.geojson: read back with json, its features are Route.forbidden_arcs() row by row
    (count, end points, every property)."""
    written = write_outputs(route, tmp_path / "out", plot=False)
    assert tmp_path / "out" / "forbidden.geojson" in written and "forbidden.geojson" in OUTPUT_FILES
    doc = json.loads((tmp_path / "out" / "forbidden.geojson").read_text(encoding="utf-8"))
    arcs = route.forbidden_arcs()
    assert doc["type"] == "FeatureCollection" and len(doc["features"]) == len(arcs) > 0
    assert {"failure"} <= set(arcs.reason.tolist())  # apf 0.5 forbids the arcs through the patches
    for i, f in enumerate(doc["features"]):
        assert f["type"] == "Feature" and f["geometry"]["type"] == "LineString"  # no arc crosses +-180 here
        assert f["geometry"]["coordinates"] == [
            [float(arcs.from_lon_deg[i]), float(arcs.from_lat_deg[i])],
            [float(arcs.to_lon_deg[i]), float(arcs.to_lat_deg[i])],
        ]
        p = f["properties"]
        assert (p["leg"], p["rank"], p["src"], p["dst"]) == (
            int(arcs.leg[i]),
            int(arcs.rank[i]),
            int(arcs.src[i]),
            int(arcs.dst[i]),
        )
        assert p["departure_h"] == float(arcs.departure_h[i]) and p["departure"] == iso_utc(arcs.departure[i])
        assert p["p_f"] == (float(arcs.p_f[i]) if np.isfinite(arcs.p_f[i]) else None)
        assert p["reason"] == str(arcs.reason[i]) and p["criteria"] == str(arcs.criteria[i])
        assert set(p) == {"leg", "rank", "src", "dst", "departure_h", "departure", "p_f", "reason", "criteria"}
    fired = [f["properties"]["criteria"] for f in doc["features"] if f["properties"]["reason"] == "failure"]
    assert fired and all(c for c in fired)  # every arc the model forbids names the criteria that fired


def test_forbidden_geojson_splits_arcs_at_the_antimeridian() -> None:
    """An arc from 179 E to 179 W along the equator crosses +-180 at latitude 0: two parts, as RFC 7946 asks."""
    one = {"leg": [0], "rank": [3], "src": [1], "dst": [2]}
    table = ForbiddenArcs(
        **{k: np.array(v, dtype=np.intp) for k, v in one.items()},
        from_lon_deg=np.array([179.0]),
        from_lat_deg=np.array([0.0]),
        to_lon_deg=np.array([-179.0]),
        to_lat_deg=np.array([0.0]),
        departure_h=np.array([1.5]),
        departure=np.array(["2018-06-01T01:30:00"], dtype="datetime64[s]"),
        p_f=np.array([np.nan]),
        reason=np.array(["weather"]),
        criteria=np.array([""]),
    )
    doc = forbidden_geojson(SimpleNamespace(forbidden_arcs=lambda: table))
    (f,) = doc["features"]
    assert f["geometry"] == {
        "type": "MultiLineString",
        "coordinates": [[[179.0, 0.0], [180.0, 0.0]], [[-180.0, 0.0], [-179.0, 0.0]]],
    }
    assert f["properties"]["p_f"] is None and f["properties"]["departure"] == "2018-06-01T01:30:00Z"
