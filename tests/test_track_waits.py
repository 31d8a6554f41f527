"""A track's waits and times, read from the route's own files and sailed as written (issue 34).

A route that waits out a storm at its start (the time-expanded DP: waves of 6 m until 20 h forbid every arc at
apf 0.5, so it leaves at 21 h on a 1 h lattice) is written as CSV, GPX and GeoJSON, read back and evaluated: each
file gives the route's waits (the CSV's and GeoJSON's ``leg_wait_h``, the GPX's point written twice: arrival, then
departure), and the evaluation equals the independent march of ``tests/_march.py`` leaving each point at the time
the route leaves it. Without the waits the craft would sail into the storm (the evaluation names ``p_f``).

A route departing a day after the scenario's departure re-times the same from each file: the GeoJSON's point times
are read (they were ignored, and the scenario's departure used). Tracks with repeated points are read as one point
and a wait (a GPS log's stay), and a Track refuses a zero-length leg or times that run backwards.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from _march import march_track
from test_sailed_time import assert_times, era5_scenario, gridded, sailor, scenario

from pyroute_rel.analysis.evaluate import Track, evaluate_track, read_track
from pyroute_rel.errors import TrackError
from pyroute_rel.outputs import write_outputs

LON, LAT = np.arange(-25.0, -17.0, 0.5), np.arange(27.0, 33.01, 0.5)
STORM_CLEARS_H = 20.0
#: The march of tests/_march.py against the product's: second order in the step (see test_sailed_time).
REL = 0.002


def storm_scenario(**route):
    """Waves of 6 m everywhere until 20 h (then 1 m from 21 h), a wind of 9-15 kn from 10 deg that varies in time;
    a 2 deg course west at 30 N, dickson2018 at apf 0.5, a 1 h lattice with waits up to 48 h."""
    t = [0.0, STORM_CLEARS_H, STORM_CLEARS_H + 1.0, 300.0]
    hs = np.array([6.0, 6.0, 1.0, 1.0])[:, None, None]
    tws = (12.0 + 3.0 * np.sin(np.radians(np.asarray(t) * 7.0)))[:, None, None] + 0.0 * LON
    weather = gridded(t, LON, LAT, tws, 10.0, hs_m=hs, wave_dir_deg=0.0)
    opts = {"time_step_h": 1.0, "max_wait_h": 48.0, **route}
    failure = {"model": "dickson2018", "apf": 0.5}
    return scenario(weather, (-20.0, 30.0), (-22.0, 30.0), failure=failure, route=opts, n_ranks=8, half_width_km=40.0)


@pytest.fixture(scope="module")
def routed(tmp_path_factory):
    sc = storm_scenario()
    route = sc.route()
    out = tmp_path_factory.mktemp("waits")
    write_outputs(route, out, plot=False)
    return sc, route, out


@pytest.mark.slow
def test_the_route_waits_out_the_storm_and_without_its_waits_sails_into_it(routed):
    sc, route, _ = routed
    assert route.legs.wait_h[0] >= STORM_CLEARS_H and route.legs.wait_h[1:].sum() == 0.0
    bare = evaluate_track(sc, np.column_stack([route.lon_deg, route.lat_deg]))
    assert not bare.feasible and bare.reason == "p_f"


@pytest.mark.parametrize("name", ["route.csv", "route.gpx", "route.geojson"])
@pytest.mark.slow
def test_a_routed_track_read_back_is_sailed_with_its_waits(routed, name):
    """Each file's track: the route's waits, its figures (feasible, the voyage time), and the march leaving each
    point when the route leaves it."""
    sc, route, out = routed
    track = read_track(out / name)
    np.testing.assert_allclose(track.waits_h, route.legs.wait_h, rtol=0.0, atol=1e-6)
    ev = evaluate_track(sc, track)
    assert ev.feasible, (name, ev.reason, ev.leg_reasons)
    assert ev.voyage_time_h == pytest.approx(route.voyage_time_h, rel=1e-6)
    np.testing.assert_allclose(ev.legs.wait_h, route.legs.wait_h, atol=1e-6)
    leave = np.asarray(ev.elapsed_h, float)[:-1] + np.asarray(ev.legs.wait_h, float)
    marched = march_track(sailor(sc), track.lon_deg, track.lat_deg, leave_h=leave, guess_h=ev.elapsed_h)
    assert_times(ev.elapsed_h, marched, rel=REL, lattice_h=1.0, what=name)


@pytest.mark.slow
def test_a_late_departure_re_times_the_same_from_every_file(tmp_path):
    """The route of a scenario departing a day later, evaluated in the original scenario: every file's first time is
    the departure (the GeoJSON's point times included)."""
    sc = storm_scenario()
    late = replace(sc, departure=sc.departure + np.timedelta64(24, "h"))
    route = late.route()
    write_outputs(route, tmp_path, plot=False)
    hours = {n: evaluate_track(sc, read_track(tmp_path / n)).voyage_time_h for n in ("route.csv", "route.gpx")}
    hours["route.geojson"] = evaluate_track(sc, read_track(tmp_path / "route.geojson")).voyage_time_h
    for name, h in hours.items():
        assert h == pytest.approx(route.voyage_time_h, rel=1e-6), (name, hours)
    doc = json.loads((tmp_path / "route.geojson").read_text())
    departure = doc["features"][0]["properties"]["departure"]
    assert read_track(tmp_path / "route.geojson").time[0] == np.datetime64(departure.removesuffix("Z"))


def _csv(path: Path, rows: list[str]) -> Path:
    path.write_text("lon,lat,time\n" + "\n".join(rows) + "\n")
    return path


@pytest.mark.slow
def test_a_repeated_point_is_one_point_and_a_wait(routed, tmp_path):
    """A CSV that stays at its first point from 00:00 to 21:00 (a GPS log's stay) is the route's track with its
    wait; without times a repeated point is dropped (no zero-length leg, which gave no voyage time)."""
    sc, route, _ = routed
    t0 = np.datetime64(sc.departure, "s")
    rows = [f"{route.lon_deg[0]},{route.lat_deg[0]},{t0}Z"]
    times = t0 + np.round((route.elapsed_h + np.append(route.legs.wait_h, 0.0)) * 3600).astype("timedelta64[s]")
    rows += [f"{float(lo)!r},{float(la)!r},{t}Z" for lo, la, t in zip(route.lon_deg, route.lat_deg, times, strict=True)]
    track = read_track(_csv(tmp_path / "stay.csv", rows))
    assert track.lon_deg.size == route.lon_deg.size
    assert track.waits_h[0] == pytest.approx(route.legs.wait_h[0] + route.elapsed_h[0], abs=1e-9)
    ev = evaluate_track(sc, track)
    assert ev.feasible and ev.voyage_time_h == pytest.approx(route.voyage_time_h, rel=1e-9)
    plain = tmp_path / "plain.csv"
    plain.write_text("lon,lat\n-20,30\n-20,30\n-21,30.1\n-21,30.1\n-22,30\n")
    track = read_track(plain)
    assert track.lon_deg.tolist() == [-20.0, -21.0, -22.0] and track.wait_h is None


def test_a_track_refuses_a_zero_length_leg_and_times_that_run_backwards(tmp_path):
    with pytest.raises(TrackError, match=r"track points 1 and 2 are the same place"):
        Track(np.array([0.0, 1.0, 1.0, 2.0]), np.array([0.0, 0.0, 0.0, 0.0]))
    times = np.array(["2018-06-01T00:00", "2018-06-01T05:00", "2018-06-01T04:00"], dtype="datetime64[s]")
    with pytest.raises(TrackError, match=r"must not run backwards: point 2 \(2018-06-01T04:00:00Z\) is before point 1"):
        Track(np.array([0.0, 1.0, 2.0]), np.zeros(3), times)
    path = _csv(tmp_path / "back.csv", ["0,0,2018-06-01T00:00Z", "1,0,2018-06-01T05:00Z", "2,0,2018-06-01T04:00Z"])
    with pytest.raises(TrackError, match=r"back\.csv: a track's times must not run backwards"):
        read_track(path)
    with pytest.raises(TrackError, match=r"wait_h must be one wait >= 0 per leg"):
        Track(np.array([0.0, 1.0]), np.zeros(2), wait_h=np.array([-1.0]))
    bad = tmp_path / "wait.csv"
    bad.write_text("lon,lat,leg_wait_h\n0,0,x\n1,0,\n")
    with pytest.raises(TrackError, match=r"CSV row 2: expected the wait before the leg"):
        read_track(bad)


@pytest.mark.slow
def test_a_track_starting_where_or_when_the_weather_has_no_data_is_an_error(tmp_path, capsys):
    """Issue 34: it evaluated to a null voyage time with exit 0. The weather covers 300 h from the departure over
    25 W to 17.5 W."""
    from pyroute_rel.cli.main import main
    from pyroute_rel.errors import WeatherCoverageError

    sc = storm_scenario()
    late = np.datetime64(sc.departure, "s") + np.timedelta64(400, "h")
    with pytest.raises(WeatherCoverageError):
        evaluate_track(sc, np.array([[-20.0, 30.0], [-21.0, 30.0]]), departure=late)
    with pytest.raises(WeatherCoverageError):
        evaluate_track(sc, np.array([[-40.0, 30.0], [-21.0, 30.0]]))
    assert evaluate_track(sc, np.array([[-20.0, 30.0], [-21.0, 30.0]])).voyage_time_h > 0.0  # covered
    era5_scenario()  # (writes the example's data file when it is missing)
    track = _csv(tmp_path / "t.csv", ["-12,45,2030-01-01T00:00Z", "-13,44.5,2030-01-01T12:00Z"])
    scenario_file = Path(__file__).resolve().parents[1] / "examples" / "microtransat_era5.toml"
    assert main(["evaluate", str(scenario_file), str(track), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and err.startswith("pyroute-rel: error:") and "2030-01-01" in err, err


def test_a_geojson_number_of_5000_digits_is_a_one_line_error(tmp_path):
    """Issue 34: Python's limit on integer digits ended the read as an internal error (exit 3), in a track as in a
    zones file."""
    from pyroute_rel.errors import ScenarioError
    from pyroute_rel.obstacles.zones import load_zones

    big = '{"type":"LineString","coordinates":[[' + "9" * 5000 + ",45],[-13,44]]}"
    (tmp_path / "big.geojson").write_text(big)
    with pytest.raises(TrackError, match=r"big\.geojson: not valid JSON \(Exceeds the limit"):
        read_track(tmp_path / "big.geojson")
    zone = '{"type":"Polygon","coordinates":[[[' + "9" * 5000 + ",45],[-13,44],[-13,45],[0,45]]]}"
    (tmp_path / "zone.geojson").write_text(zone)
    with pytest.raises(ScenarioError, match=r"zone\.geojson: not valid JSON \(Exceeds the limit"):
        load_zones([tmp_path / "zone.geojson"])


def test_a_file_s_waits_and_times_are_checked_where_points_repeat(tmp_path):
    """A repeated point whose times run backwards is named as such (not as a zero-length leg); a GeoJSON point's
    wait that is not a number of hours >= 0 (a word, negative, beyond the floats) is refused naming the point."""
    path = _csv(tmp_path / "back.csv", ["0,0,2018-06-01T05:00Z", "0,0,2018-06-01T04:00Z", "1,0,2018-06-01T06:00Z"])
    with pytest.raises(TrackError, match=r"times must not run backwards: point 1 \(2018-06-01T04:00:00Z\)"):
        read_track(path)
    for bad in ('"x"', "-1", "1" + "0" * 400):
        doc = (
            '{"type": "FeatureCollection", "features": ['
            '{"type": "Feature", "properties": {},'
            ' "geometry": {"type": "LineString", "coordinates": [[0, 0], [1, 0]]}},'
            '{"type": "Feature", "geometry": {"type": "Point", "coordinates": [0, 0]},'
            f' "properties": {{"index": 0, "time": "2018-06-01T00:00Z", "leg_wait_h": {bad}}}}},'
            '{"type": "Feature", "geometry": {"type": "Point", "coordinates": [1, 0]},'
            ' "properties": {"index": 1, "time": "2018-06-01T05:00Z"}}]}'
        )
        (tmp_path / "w.geojson").write_text(doc)
        with pytest.raises(TrackError, match=r"point 0's leg_wait_h: expected the wait before the leg as a number"):
            read_track(tmp_path / "w.geojson")
