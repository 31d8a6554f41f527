"""Evaluating any track (issue 19): re-timing a routed track gives the route's own figures; track files round-trip;
blocked legs are named by an independent geometric test; the CLI's JSON and errors."""

from __future__ import annotations

import importlib.util
import json
import re
import sys
from pathlib import Path

import numpy as np
import pytest
import shapely

from pyroute_rel import geodesy, load_scenario, scenario_from_mapping
from pyroute_rel.analysis.evaluate import Track, evaluate_track, read_track
from pyroute_rel.cli import main
from pyroute_rel.errors import ScenarioError, TrackError
from pyroute_rel.outputs import write_outputs
from pyroute_rel.routing.route import LEG_FIELDS

ROOT = Path(__file__).resolve().parents[1]
PATCH = {"lon": [-17.0, -15.0], "lat": [41.0, 44.0], "hs_m": 4.5}
TABLE = {
    "route": {"start": [-12.0, 45.0], "finish": [-20.0, 40.0], "departure": "2018-06-01T00:00:00Z"},
    "grid": {"n_ranks": 20},
    "weather": {"kind": "uniform", "tws_kn": 15.0, "twd_deg": 0.0, "hs_m": 1.0, "patch": [PATCH]},
    "avoid": {"land": False},
    "failure": {"model": "dickson2018", "apf": 0.95},  # the route may cross the patch (p_f 0.9): exposure counts
}


def load_example(name: str):
    spec = importlib.util.spec_from_file_location(f"example_{name}", ROOT / "examples" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def write_ensemble_scenario(folder: Path, n_members: int = 4, spread: float = 1.0, **extra_route) -> Path:
    """A small synthetic ensemble file and a scenario routing it (the example's course, a coarse grid)."""
    make = load_example("make_ensemble_example")
    make.write_ensemble(folder / "ens.nc", n_members, spread=spread, resolution_deg=2.0, step_h=12.0)
    route = {"start": [-14.0, 31.0], "finish": [-22.0, 25.0], "departure": "2018-06-01T00:00:00Z", **extra_route}
    text = (
        "[route]\n"
        + "".join(f"{k} = {json.dumps(v)}\n" for k, v in route.items())
        + '[grid]\nn_ranks = 16\n[avoid]\nland = false\n[weather]\nkind = "file"\npaths = ["ens.nc"]\n'
        + '[failure]\nmodel = "dickson2018"\napf = 0.5\n'
    )
    path = folder / "ens.toml"
    path.write_text(text)
    return path


def assert_same_legs(route, ev, rtol=1e-9):
    for name in LEG_FIELDS:
        np.testing.assert_allclose(ev.legs[name], route.legs[name], rtol=rtol, atol=1e-12, err_msg=name)


def test_retiming_a_routed_track_gives_the_routes_figures():
    sc = scenario_from_mapping(TABLE)
    route = sc.route()
    assert route.max_failure_probability == 0.9 and 0.0 < route.voyage_failure_probability < 1.0  # exposure counts
    ev = evaluate_track(sc, np.column_stack([route.lon_deg, route.lat_deg]))
    assert_same_legs(route, ev)
    assert ev.voyage_time_h == pytest.approx(route.voyage_time_h, rel=1e-12)
    assert ev.distance_nm == pytest.approx(route.distance_nm, rel=1e-12)
    assert ev.voyage_failure_probability == pytest.approx(route.voyage_failure_probability, rel=1e-9)
    assert ev.exposure_by_criterion_h == pytest.approx(route.exposure_by_criterion_h, rel=1e-9)
    assert ev.arrival == route.arrival and ev.feasible and ev.reason is None and ev.blocked_leg is None
    rs, es = route.summary(), ev.summary()
    shared = set(rs) & set(es)
    assert shared >= {"voyage_time_h", "distance_nm", "departure", "arrival", "max_failure_probability", "apf", "track"}
    for key in shared - {"track"}:
        assert es[key] == pytest.approx(rs[key], rel=1e-9) if isinstance(rs[key], float) else es[key] == rs[key], key
    assert [(p["lon"], p["lat"], p["time"]) for p in es["track"]] == [
        (p["lon"], p["lat"], p["time"]) for p in rs["track"]
    ]


@pytest.mark.slow
def test_retiming_in_time_varying_member_weather(tmp_path: Path):
    """An ensemble member's route, re-timed in the same member's (time-varying) weather, with its track read back
    from the route's own GPX file: the same figures (the file keeps 6 decimals of a degree: to 1e-6 relative)."""
    path = write_ensemble_scenario(tmp_path)
    from pyroute_rel.analysis.members import member_scenario

    sc = member_scenario(path, 2)
    assert not sc.weather.steady
    route = sc.route()
    exact = evaluate_track(path, np.column_stack([route.lon_deg, route.lat_deg]), member=2)
    assert_same_legs(route, exact)
    assert exact.voyage_time_h == pytest.approx(route.voyage_time_h, rel=1e-12)
    write_outputs(route, tmp_path / "out", plot=False)
    ev = evaluate_track(sc, read_track(tmp_path / "out" / "route.gpx"))
    assert ev.voyage_time_h == pytest.approx(route.voyage_time_h, rel=1e-6)
    other = evaluate_track(path, exact.track, member=0)  # another member's weather: another time
    assert abs(other.voyage_time_h - route.voyage_time_h) > 1e-3


@pytest.mark.slow
@pytest.mark.parametrize("name", ["route.gpx", "route.geojson", "route.csv"])
def test_route_files_read_back_as_the_track(tmp_path: Path, name: str):
    route = scenario_from_mapping(TABLE).route()
    write_outputs(route, tmp_path, plot=False)
    track = read_track(tmp_path / name)
    np.testing.assert_allclose(track.lon_deg, route.lon_deg, atol=5e-7)
    np.testing.assert_allclose(track.lat_deg, route.lat_deg, atol=5e-7)
    assert (track.time == route.time).all()  # the GeoJSON's from its points (issue 34: they were not read)
    assert (track.waits_h == route.legs.wait_h).all()


def test_geojson_split_at_the_antimeridian_is_joined(tmp_path: Path):
    line = {"type": "MultiLineString", "coordinates": [[[178.0, 0.0], [180.0, 0.0]], [[-180.0, 0.0], [-178.0, 0.5]]]}
    (tmp_path / "t.geojson").write_text(json.dumps({"type": "Feature", "geometry": line, "properties": {}}))
    track = read_track(tmp_path / "t.geojson")
    assert track.lon_deg.tolist() == [178.0, -178.0] and track.lat_deg.tolist() == [0.0, 0.5]


@pytest.mark.parametrize(
    ("name", "text", "message"),
    [
        ("a.csv", "lon,lat\n1,2\n", "1 point(s)"),
        ("a.csv", "lon,lat\n1,2\n3,x\n", "CSV row 3: expected numbers"),
        ("a.csv", "a,b\n1,2\n3,4\n", "needs lon and lat columns"),
        ("a.csv", "1,2,2018-06-01\n3,4,soon\n", "CSV row 2: expected an ISO 8601 UTC time"),
        ("a.csv", "1,95\n3,4\n", "off the globe"),
        ("a.geojson", '{"type": "Point", "coordinates": [1, 2]}', "found 0"),
        ("a.geojson", "{", "not valid JSON"),
        ("a.gpx", "<gpx><wpt lat='1' lon='2'/></gpx>", "no track or route"),
        ("a.gpx", "<gpx", "not a readable GPX file"),
    ],
)
def test_bad_track_files_are_one_line_errors_naming_the_file(tmp_path: Path, name: str, text: str, message: str):
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(TrackError, match=re.escape(message)) as exc:
        read_track(path)
    assert "\n" not in str(exc.value) and str(exc.value).startswith(str(path))


def test_csv_without_header_and_with_times(tmp_path: Path):
    (tmp_path / "t.csv").write_text("-12,45,2018-06-02T00:00:00Z\n-20,40,2018-06-05T00:00:00Z\n")
    track = read_track(tmp_path / "t.csv")
    assert track.lon_deg.tolist() == [-12.0, -20.0] and str(track.time[0]) == "2018-06-02T00:00:00"
    ev = evaluate_track(scenario_from_mapping(TABLE), track)
    assert str(ev.departure) == "2018-06-02T00:00:00"  # the track's first time is the departure


def _samples_in_patch(lon: np.ndarray, lat: np.ndarray, samples: int) -> np.ndarray:
    """Which legs have a weather sample in the patch: the router samples a leg at the midpoints of its ``samples``
    equal sub-segments (the cost module's notes); here each point is tested against the patch box."""
    box = shapely.box(PATCH["lon"][0], PATCH["lat"][0], PATCH["lon"][1], PATCH["lat"][1])
    out = []
    for i in range(lon.size - 1):
        x, y = geodesy.intermediate_point(lon[i], lat[i], lon[i + 1], lat[i + 1], (np.arange(samples) + 0.5) / samples)
        out.append(bool(shapely.contains_xy(box, x, y).any()))
    return np.array(out)


def test_a_track_through_forbidden_conditions_is_sailed_and_its_legs_named():
    sc = scenario_from_mapping({**TABLE, "failure": {"model": "dickson2018", "apf": 0.5}})
    lon = np.linspace(-12.0, -20.0, 9)
    lat = np.linspace(45.0, 40.0, 9)
    ev = evaluate_track(sc, Track(lon, lat))
    hit = _samples_in_patch(lon, lat, 2000)  # every ~40 m: a leg is judged on everything it crosses (no clipping)
    assert hit.any() and not hit.all()
    assert [("p_f",) if h else () for h in hit] == list(ev.leg_reasons)
    assert not ev.feasible and ev.reason == "p_f" and ev.blocked_leg == int(np.flatnonzero(hit)[0])
    assert np.isfinite(ev.voyage_time_h) and ev.max_failure_probability == pytest.approx(0.9)  # sailed anyway
    loose = evaluate_track(sc, Track(lon, lat), apf=0.95)
    assert loose.feasible and loose.voyage_time_h == ev.voyage_time_h


@pytest.mark.slow
def test_land_zone_and_the_end_of_the_weather_are_named(tmp_path: Path):
    table = {**TABLE, "avoid": {"land": True}}
    across_iberia = Track(np.array([-12.0, -9.0, 2.0]), np.array([40.0, 40.0, 40.5]))
    ev = evaluate_track(scenario_from_mapping(table), across_iberia)
    assert ev.leg_reasons == ((), ("land",)) and ev.reason == "land" and ev.blocked_leg == 1
    zone = {"type": "Polygon", "coordinates": [[[-16, 41], [-14, 41], [-14, 43], [-16, 43], [-16, 41]]]}
    (tmp_path / "z.geojson").write_text(json.dumps({"type": "Feature", "geometry": zone, "properties": {}}))
    zoned = {**TABLE, "avoid": {"land": False, "zones": [str(tmp_path / "z.geojson")]}}
    lon, lat = np.linspace(-12.0, -20.0, 5), np.linspace(45.0, 40.0, 5)
    ev = evaluate_track(scenario_from_mapping(zoned), Track(lon, lat), apf=1.0)
    box = shapely.box(-16, 41, -14, 43)
    expect = [
        ("zone",) if shapely.LineString([(lon[i], lat[i]), (lon[i + 1], lat[i + 1])]).intersects(box) else ()
        for i in range(4)
    ]
    assert list(ev.leg_reasons) == expect and ev.reason == "zone"
    # beyond the weather's last time: the craft cannot go on
    path = write_ensemble_scenario(tmp_path, n_members=2)
    long = Track(np.array([-14.0, -22.0, -14.0, -22.0, -14.0]), np.array([31.0, 25.0, 31.0, 25.0, 31.0]))
    ev = evaluate_track(path, long, member=0, apf=1.0)  # p_f never blocks: the end of the weather does
    k = ev.blocked_leg
    assert ev.reason == "weather" and ev.voyage_time_h == np.inf and not ev.feasible
    assert np.isfinite(ev.elapsed_h[: k + 1]).all() and np.isinf(ev.elapsed_h[k + 1 :]).all()
    assert ev.legs.time_h[k] == np.inf and np.isnan(ev.legs.time_h[k + 1 :]).all()
    assert np.isnat(ev.arrival) and ev.summary()["voyage_time_h"] is None and ev.summary()["arrival"] is None


def test_member_of_a_scenario_built_in_code_is_refused():
    with pytest.raises(ScenarioError, match="read from the scenario's file"):
        evaluate_track(scenario_from_mapping(TABLE), [[-12, 45], [-20, 40]], member=0)


@pytest.mark.slow
def test_cli_evaluate_json_out_and_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str]):
    scenario = tmp_path / "s.toml"
    scenario.write_text(
        '[route]\nstart = [-12.0, 45.0]\nfinish = [-20.0, 40.0]\ndeparture = "2018-06-01T00:00:00Z"\n'
        '[grid]\nn_ranks = 20\n[avoid]\nland = false\n[weather]\nkind = "uniform"\ntws_kn = 15.0\ntwd_deg = 0.0\n'
        "hs_m = 1.0\n[[weather.patch]]\nlon = [-17.0, -15.0]\nlat = [41.0, 44.0]\nhs_m = 4.5\n"
        '[failure]\nmodel = "dickson2018"\napf = 0.5\n'
    )
    route = load_scenario(scenario).route()
    write_outputs(route, tmp_path / "r", plot=False)
    code = main(["evaluate", str(scenario), str(tmp_path / "r" / "route.gpx"), "--json", "--out", str(tmp_path / "e")])
    out, err = capsys.readouterr()
    assert code == 0, err
    d = json.loads(out)
    assert d["voyage_time_h"] == pytest.approx(route.voyage_time_h, rel=1e-6) and d["feasible"] is True
    assert d["reason"] is None and len(d["track"]) == route.lon_deg.size
    assert sorted(p.name for p in (tmp_path / "e").iterdir()) == ["evaluation.csv", "evaluation.json"]
    assert json.loads((tmp_path / "e" / "evaluation.json").read_text())["arrival"] == d["arrival"]
    (tmp_path / "bad.csv").write_text("lon,lat\n1,2\n")
    code = main(["evaluate", str(scenario), str(tmp_path / "bad.csv")])
    out, err = capsys.readouterr()
    assert code == 2 and err.count("\n") == 1 and "bad.csv" in err and out == ""
