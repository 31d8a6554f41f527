"""Scenarios: the tables read by one parser each from the schema, weather kinds from a registry, notes, options."""

from __future__ import annotations

import copy
import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from pyroute_rel.cli import main
from pyroute_rel.config import SCHEMA, WEATHER_KINDS, parse_departure, register_weather_kind
from pyroute_rel.errors import ScenarioError
from pyroute_rel.scenario import Scenario, load_scenario, scenario_from_mapping
from pyroute_rel.weather import UniformWeather, WeatherSource

BASE: dict[str, Any] = {
    "route": {"start": [-12.0, 45.0], "finish": [-20.0, 40.0], "departure": "2018-06-01T00:00:00Z"},
    "grid": {"n_ranks": 10},
    "boat": {"polar": "maribot_vane"},
    "weather": {"kind": "uniform", "tws_kn": 15.0, "twd_deg": 0.0},
    "failure": {"model": "none"},
    "avoid": {"land": False},
}


def with_table(name: str, **keys: Any) -> dict[str, Any]:
    table = copy.deepcopy(BASE)
    table[name] = {**table.get(name, {}), **keys}
    return table


def test_round_trip_mapping_scenario_options() -> None:
    sc = scenario_from_mapping(
        with_table("grid", layout="square", n_nodes=9, spacing_km=40.0, refine=1), source="course.toml"
    )
    assert isinstance(sc, Scenario)
    assert sc.source == "course.toml" and sc.start == (-12.0, 45.0) and sc.finish == (-20.0, 40.0)
    assert sc.departure == np.datetime64("2018-06-01T00:00:00", "s")
    assert (sc.layout, sc.n_ranks, sc.n_nodes, sc.spacing_km, sc.refine) == ("square", 10, 9, 40.0, 1)
    assert sc.failure_model is None and sc.apf == 1.0 and sc.avoid.land is False and sc.notes == ()
    assert isinstance(sc.weather, UniformWeather) and sc.weather.tws_kn == 15.0
    # options: None leaves a setting, others are checked like the file's and named as on the command line
    assert sc.with_options(n_ranks=None, apf=None) == sc
    changed = sc.with_options(n_ranks=12, apf="0.5", land=True, failure_model="dickson2018", departure="2018-06-02")
    assert (changed.n_ranks, changed.apf, changed.avoid.land, changed.failure_model) == (12, 0.5, True, "dickson2018")
    assert changed.departure == np.datetime64("2018-06-02T00:00:00", "s")
    assert changed.with_options(failure_model="none").failure_model is None
    assert changed.weather is sc.weather and changed.avoid.resolution == sc.avoid.resolution
    for options, message in (
        ({"n_ranks": "20"}, "--n-ranks must be a whole number (got '20')"),
        ({"refine": -1}, "--refine must be >= 0"),
        ({"apf": 2}, "--apf must be a probability in [0, 1] (got 2)"),
        ({"sample_km": 0.0}, "--sample-km must be in [0.1, 1000] [km] (got 0)"),
        ({"layout": "hex"}, "--layout must be one of ['angular', 'square'] (got 'hex')"),
        ({"land": "no"}, "land must be True or False (got 'no')"),
        ({"failure_model": " "}, "--failure-model needs a shipped model name"),
        ({"colour": "red"}, "unknown scenario option 'colour'"),
    ):
        with pytest.raises(ScenarioError) as info:
            sc.with_options(**options)
        assert message in str(info.value)


def test_a_scenario_file_reads_like_its_mapping(tmp_path: Path) -> None:
    text = """
[route]
start = [-12.0, 45.0]
finish = [-20.0, 40.0]
departure = "2018-06-01T06:00:00+02:00"
[grid]
n_ranks = 10
[weather]
kind = "uniform"
tws_kn = 15.0
twd_deg = 0.0
[avoid]
land = false
"""
    path = tmp_path / "course.toml"
    path.write_text(text)
    sc = load_scenario(path)
    assert sc.source == str(path) and sc.base_dir == tmp_path
    assert sc.departure == np.datetime64("2018-06-01T04:00:00", "s") and sc.notes == ()


@pytest.mark.parametrize("name", [name for name, spec in SCHEMA.items() if spec])
def test_every_table_refuses_unknown_keys_naming_them(name: str) -> None:
    with pytest.raises(ScenarioError) as info:
        scenario_from_mapping(with_table(name, colour="red"), source="s.toml")
    assert str(info.value) == (f"s.toml: [{name}]: unknown key 'colour' (expected one of {', '.join(SCHEMA[name])})")


def test_unknown_tables_and_tables_that_are_not_tables_are_refused() -> None:
    with pytest.raises(ScenarioError, match=r"unknown table \[boats\] \(expected \[route\], \[grid\]"):
        scenario_from_mapping({**BASE, "boats": {}})
    with pytest.raises(ScenarioError, match=r"\[grid\] must be a table"):
        scenario_from_mapping({**BASE, "grid": 3})


@pytest.mark.parametrize(
    ("name", "key"), [(name, key) for name, spec in SCHEMA.items() for key, k in spec.items() if k.check is not None]
)
def test_every_checked_key_refuses_a_wrong_type_naming_the_field(name: str, key: str) -> None:
    with pytest.raises(ScenarioError) as info:
        scenario_from_mapping(with_table(name, **{key: {"a": 1}}))
    assert f"[{name}].{key}" in str(info.value)


@pytest.mark.parametrize(
    ("name", "key", "value", "message"),
    [
        ("route", "time_step_h", 49.0, "[route].time_step_h must be in (0, 48] [h] (got 49)"),
        ("route", "time_step_h", 0.0, "[route].time_step_h must be positive (got 0.0)"),
        ("route", "max_wait_h", -1.0, "[route].max_wait_h must be >= 0 [h] (got -1)"),
        ("route", "max_wait_h", 2.0, "[route].max_wait_h needs [route].time_step_h"),
        ("route", "departure", "June", "[route].departure must be an ISO 8601 time such as"),
        ("route", "waypoints", "x", "[route].waypoints must be a list of [lon, lat] points [deg]"),
        ("grid", "aspect", 0.001, "[grid].aspect (rank spacing / lateral spacing) must be in [0.01, 1000] (got 0.001)"),
        ("grid", "half_width_km", -5, "[grid].half_width_km must be >= 0 [km] (got -5)"),
        ("grid", "max_deviation_deg", 90, "[grid].max_deviation_deg must be in (0, 90) [deg] (got 90)"),
        ("grid", "samples_per_arc", 65, "[grid].samples_per_arc must be at most 64 (got 65)"),
        ("grid", "n_ranks", 0, "[grid].n_ranks must be >= 1 (got 0)"),
        ("avoid", "margin_km", 300, "[avoid].margin_km must be in [0, 200] [km] (got 300)"),
        ("failure", "apf", 1.5, "[failure].apf must be a probability in [0, 1] (got 1.5)"),
        ("boat", "beyond", "wrap", "[boat].beyond must be one of ['clamp', 'forbid'] (got 'wrap')"),
    ],
)
def test_ranges_are_checked_with_the_field_named(name: str, key: str, value: Any, message: str) -> None:
    with pytest.raises(ScenarioError) as info:
        scenario_from_mapping(with_table(name, **{key: value}), source="s.toml")
    assert str(info.value).startswith("s.toml: ") and message in str(info.value)


def test_samples_per_arc_and_sample_km_exclude_each_other() -> None:
    with pytest.raises(ScenarioError, match="give samples_per_arc .* or sample_km .*, not both"):
        scenario_from_mapping(with_table("grid", samples_per_arc=2, sample_km=10.0))


def test_a_registered_weather_kind_routes() -> None:
    seen: dict[str, Any] = {}

    def steady_breeze(
        table: Mapping[str, Any], *, base_dir: Path, bbox: tuple[float, float, float, float], departure: Any
    ) -> WeatherSource:
        seen.update(table=dict(table), bbox=bbox, departure=departure)
        unknown = set(table) - {"kind", "knots"}
        if unknown:
            raise ScenarioError(f"[weather]: unknown key {sorted(unknown)[0]!r}")
        return UniformWeather(tws_kn=float(table["knots"]), twd_deg=0.0)

    register_weather_kind("breeze", steady_breeze)
    try:
        with pytest.raises(ScenarioError, match="'breeze' is already registered"):
            register_weather_kind("breeze", steady_breeze)
        sc = scenario_from_mapping({**BASE, "weather": {"kind": "breeze", "knots": 15.0}})
        assert seen["table"] == {"kind": "breeze", "knots": 15.0}
        assert seen["departure"] == np.datetime64("2018-06-01T00:00:00", "s")
        west, south, east, north = seen["bbox"]
        assert west < -20.0 < -12.0 < east and south < 40.0 < 45.0 < north
        # the same weather as the uniform kind: the same route
        uniform = scenario_from_mapping(BASE).route()
        breeze = sc.route()
        assert breeze.voyage_time_h == uniform.voyage_time_h
        np.testing.assert_array_equal(breeze.lon_deg, uniform.lon_deg)
        with pytest.raises(ScenarioError, match="unknown key 'gusts'"):
            scenario_from_mapping({**BASE, "weather": {"kind": "breeze", "knots": 15.0, "gusts": 3}})
        with pytest.raises(ScenarioError, match=r"\[weather\].kind must be one of \['uniform', 'file', 'breeze'\]"):
            scenario_from_mapping({**BASE, "weather": {"kind": "gale"}})
    finally:
        del WEATHER_KINDS["breeze"]
    with pytest.raises(ScenarioError, match=r"\[weather\].kind must be one of \['uniform', 'file'\] \(got 'breeze'\)"):
        scenario_from_mapping({**BASE, "weather": {"kind": "breeze", "knots": 15.0}})
    for kind, builder in (("", steady_breeze), ("x", 3)):
        with pytest.raises(ScenarioError):  # the domain error (a ValueError), not a bare ValueError
            register_weather_kind(kind, builder)  # type: ignore[arg-type]


def test_a_time_without_zone_is_read_as_utc_with_a_note() -> None:
    notes: list[str] = []
    assert parse_departure("2018-06-01T00:00:00", "[route].departure", notes=notes) == np.datetime64(
        "2018-06-01T00:00:00", "s"
    )
    assert notes == ["[route].departure '2018-06-01T00:00:00' has no time zone: read as UTC"]
    parse_departure("2018-06-01T00:00:00Z", notes=notes)
    parse_departure("2018-06-01T02:00:00+02:00", notes=notes)
    assert len(notes) == 1
    naive = scenario_from_mapping(with_table("route", departure="2018-06-01T00:00:00"), source="s.toml")
    assert naive.notes == ("s.toml: [route].departure '2018-06-01T00:00:00' has no time zone: read as UTC",)
    assert naive.departure == scenario_from_mapping(BASE).departure
    assert scenario_from_mapping(BASE).notes == ()


def test_the_command_line_prints_the_notes_once(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "naive.toml"
    path.write_text(
        "[route]\nstart = [-12.0, 45.0]\nfinish = [-20.0, 40.0]\ndeparture = 2018-06-01T00:00:00\n"
        "[grid]\nn_ranks = 10\n"
        '[weather]\nkind = "uniform"\ntws_kn = 15.0\ntwd_deg = 0.0\n[avoid]\nland = false\n'
    )
    assert main(["route", str(path), "--json", "--quiet"]) == 0
    out, err = capsys.readouterr()
    assert json.loads(out)["departure"] == "2018-06-01T00:00:00Z"
    assert err == (
        f"pyroute-rel: note: {path}: [route].departure '2018-06-01T00:00:00' has no time zone: read as UTC\n"
    )


@pytest.mark.parametrize("path", [b"scenario.toml", ["a.toml"], float("nan"), None, 5])
def test_load_scenario_refuses_a_path_of_the_wrong_type(path: object) -> None:
    # bytes, lists, numbers and None raised TypeError from pathlib (not the domain error).
    with pytest.raises(ScenarioError, match="a scenario path must be a str or pathlib.Path"):
        load_scenario(path)  # type: ignore[arg-type]


@pytest.mark.parametrize("table", [None, 5, [], "route"])
def test_scenario_from_mapping_refuses_what_is_not_a_mapping(table: object) -> None:
    # None and 5 raised TypeError, [] AttributeError, and "route" read its letters as tables ("unknown table [r]").
    with pytest.raises(ScenarioError, match=r"<scenario>: a scenario must be a mapping of tables"):
        scenario_from_mapping(table)  # type: ignore[arg-type]


def test_route_refuses_grids_that_are_not_one_grid_per_leg() -> None:
    # grids=5 raised TypeError, grids="x" AttributeError; a list shorter than the legs routed only the first legs.
    sc = scenario_from_mapping(with_table("route", waypoints=[[-16.0, 43.0]]))  # two legs
    grids = sc.leg_grids()
    assert len(grids) == 2
    for bad in (5, "x", [None, None]):
        with pytest.raises(ScenarioError, match="grids must be a list of Grid from leg_grids"):
            sc.route(grids=bad)  # type: ignore[arg-type]
    with pytest.raises(ScenarioError, match=r"one Grid per leg of the course \(2\), from leg_grids\(\) \(got 1\)"):
        sc.route(grids=grids[:1])
    assert sc.route(grids=grids).voyage_time_h == sc.route().voyage_time_h  # the same grids route the same
