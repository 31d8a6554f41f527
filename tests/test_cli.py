"""The pyroute-rel command: JSON contract, output files, exit codes and one-line errors."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from pyroute_rel.cli import main

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "microtransat_control.toml"
SMALL = ["--layout", "square", "--n-nodes", "21", "--n-ranks", "21"]


def run(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    code = main(args)
    out, err = capsys.readouterr()
    return code, out, err


def test_route_json_contract(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run(["route", str(EXAMPLE), *SMALL, "--json", "--quiet", "--no-land", "--no-prune"], capsys)
    assert code == 0, err
    d = json.loads(out)
    for key, typ in [
        ("voyage_time_h", float),
        ("distance_nm", float),
        ("departure", str),
        ("arrival", str),
        ("max_failure_probability", float),
        ("voyage_failure_probability", float),
    ]:
        assert isinstance(d[key], typ), key
    assert d["grid"]["n_ranks"] == 21 and d["grid"]["n_nodes"] == 21 and d["grid"]["spacing_km"] > 0
    assert d["arcs"]["evaluated"] == 21 + 20 * 21 * 21 + 21
    assert d["departure"] == "2018-06-01T00:00:00Z"
    track = d["track"]
    assert len(track) == 23 and track[0]["lon"] == -12.0 and track[-1]["lat"] == 17.5
    assert set(track[0]) == {"lon", "lat", "time", "p_f"}
    assert track[-1]["time"] == d["arrival"]


@pytest.mark.slow
def test_route_prune_gives_the_same_route_with_fewer_arcs(capsys: pytest.CaptureFixture[str], monkeypatch) -> None:
    monkeypatch.setattr("pyroute_rel.routing.solve.PRUNE_MIN_WIDTH", 0)  # the 21-node test grid is pruned too
    args = ["route", str(EXAMPLE), *SMALL, "--json", "--quiet", "--no-land"]
    code, out, err = run([*args, "--no-prune"], capsys)
    assert code == 0, err
    full = json.loads(out)
    code, out, err = run(args, capsys)  # pruning is the default
    assert code == 0, err
    pruned = json.loads(out)
    assert pruned["voyage_time_h"] == full["voyage_time_h"] and pruned["track"] == full["track"]
    assert pruned["arcs"]["evaluated"] < full["arcs"]["evaluated"] / 2
    assert pruned["arcs"]["evaluated"] + pruned["arcs"]["pruned"] == full["arcs"]["evaluated"]
    assert full["arcs"]["pruned"] == 0


def test_route_out_writes_every_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "out"
    code, stdout, err = run(["route", str(EXAMPLE), *SMALL, "--out", str(out), "--quiet"], capsys)
    assert code == 0, err
    names = sorted(p.name for p in out.iterdir())
    assert names == ["forbidden.geojson", "route.csv", "route.geojson", "route.gpx", "route.png", "summary.json"]
    assert (out / "route.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    gj = json.loads((out / "route.geojson").read_text())
    assert gj["features"][0]["geometry"]["type"] == "LineString"
    summary = json.loads((out / "summary.json").read_text())
    assert summary["voyage_time_h"] == pytest.approx(float(gj["features"][0]["properties"]["voyage_time_h"]))
    import xml.etree.ElementTree as ET

    ns = {"g": "http://www.topografix.com/GPX/1/1"}
    pts = ET.parse(out / "route.gpx").getroot().findall(".//g:trkpt", ns)
    assert len(pts) == len(summary["track"])
    rows = (out / "route.csv").read_text().splitlines()
    assert len(rows) == len(summary["track"]) + 1 and rows[0].startswith("index,lon_deg,lat_deg,time_utc")
    assert "voyage time" in stdout


def write(tmp_path: Path, text: str, name: str = "s.toml") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


GOOD = EXAMPLE.read_text()


@pytest.mark.parametrize(
    "make,message",
    [
        (lambda d: d / "missing.toml", "scenario file not found"),
        (lambda d: write(d, GOOD.replace("n_nodes = 160", "n_nodez = 160")), "unknown key 'n_nodez'"),
        (lambda d: write(d, GOOD.replace("finish = [-60.0, 17.5]", "finish = [-12.0, 45.0]")), "are the same point"),
        (lambda d: write(d, GOOD.replace('departure = "2018-06-01T00:00:00Z"', 'departure = "June 1st"')), "ISO 8601"),
        (lambda d: write(d, GOOD.replace("apf = 1.0", "apf = 1.5")), r"\[failure\].apf must be a probability"),
        (lambda d: write(d, GOOD.replace("start = [-12.0, 45.0]", "start = [-12.0, 95.0]")), "latitude"),
        (lambda d: write(d, GOOD.replace("n_ranks = 160", "n_ranks = 0")), r"n_ranks must be >= 1"),
        (lambda d: write(d, GOOD + "\n[extra]\nx = 1\n"), r"unknown table \[extra\]"),
        (lambda d: write(d, "[route\nstart = 1"), "not valid TOML"),
        # QA: these named no field before
        (
            lambda d: write(d, GOOD.replace("[route]", "[route]\ntime_step_h = 100", 1)),
            r"s\.toml: \[route\]\.time_step_h must be in \(0, 48\] \[h\] \(got 100\)",
        ),
        (
            lambda d: write(d, GOOD.replace("[route]", "[route]\ntime_step_h = 0.01\nmax_wait_h = 5000", 1)),
            r"\[route\]\.max_wait_h / \[route\]\.time_step_h must be at most 10000",
        ),
        (lambda d: write(d, GOOD.replace("[grid]", "[grid]\naspect = 1e6", 1)), r"\[grid\]\.aspect .* \(got 1e\+06\)"),
        (
            lambda d: write(d, GOOD.replace('model = "dickson2018"', 'model = "nope.toml"')),
            r"s\.toml: \[failure\]\.model 'nope\.toml': .*nope\.toml: file not found",
        ),
        (
            lambda d: write(d, GOOD.split("[weather]")[0] + '[weather]\nkind = "file"\npaths = ["."]\n'),
            r"is a folder: list the NetCDF or GRIB files in it under \[weather\]\.paths",
        ),
        (
            lambda d: (
                write(d, GOOD.replace('polar = "maribot_vane"', 'polar = "bad.pol"'))
                and write(d, "TWA\\TWS\t8\t4\n45\t1\t2\n90\t1\t2\n", "bad.pol")
                and d / "s.toml"
            ),
            "increasing",
        ),
    ],
)
def test_bad_input_exit_2_one_line_no_output(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], make, message: str
) -> None:
    scenario = make(tmp_path)
    out = tmp_path / "out"
    code, stdout, err = run(["route", str(scenario), "--out", str(out), "--quiet"], capsys)
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("pyroute-rel: error: ")
    import re

    assert re.search(message, lines[0]), lines[0]
    assert "Traceback" not in err
    assert not out.exists() or not any(out.iterdir())


def test_start_on_land_and_everything_forbidden_are_explained(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    on_land = write(tmp_path, GOOD.replace("start = [-12.0, 45.0]", "start = [2.35, 48.85]"))  # Paris
    code, _, err = run(["route", str(on_land), "--out", str(out), "--quiet"], capsys)
    assert code == 2 and "[route].start [2.35, 48.85] is on land" in err and err.count("\n") == 1
    # 5 m waves everywhere at apf 0.5: WH fires on every arc, so nothing is allowed; the message says so
    storm = write(tmp_path, GOOD.replace("hs_m = 1.0", "hs_m = 5.0"), "storm.toml")
    code, _, err = run(["route", str(storm), "--apf", "0.5", "--out", str(out), "--quiet"], capsys)
    assert code == 2 and err.count("\n") == 1
    assert "no feasible route" in err and "front died at rank 1 " in err
    assert "failure model 'dickson2018'" in err and "WH: hs_m >= 4 m on" in err and "it routes with --apf 0.9" in err
    # --out holds what would route, and no partial route: the front died before reaching any node
    assert sorted(p.name for p in out.iterdir()) == ["summary.json"]
    written = json.loads((out / "summary.json").read_text())
    assert (
        written["feasible"] is False
        and written["relaxation"]["apf"] == 0.9
        and written["relaxation"]["partial"] is None
    )


def test_failure_command(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(["failure", "dickson2018", "--json"], capsys)
    assert code == 0
    d = json.loads(out)
    assert d["model"] == "dickson2018" and len(d["criteria"]) == 2
    # the paper's Table 1: P(fail) = 0, 0.9, 0.9, 1.0 for no, one, the other, both criteria
    p = sorted(round(row["p_fail"], 9) for row in d["table"])
    assert p == [0.0, 0.9, 0.9, 1.0]
    code, out, _ = run(["failure"], capsys)
    assert code == 0 and "dickson2018" in out.split() and "wind_wave_multistate" in out.split()
    code, _, err = run(["failure", "no_such_model"], capsys)
    assert code == 2 and "no_such_model" in err and err.count("\n") == 1


def test_usage_error_is_exit_2(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["route"])
    assert exc.value.code == 2


@pytest.mark.slow
def test_console_script_runs_as_a_subprocess(tmp_path: Path) -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "pyroute_rel.cli", "route", str(tmp_path / "nope.toml")], capture_output=True, text=True
    )
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "not found" in proc.stderr


def test_bad_thread_count_in_the_environment_is_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("PYROUTE_REL_THREADS", "two")
    out = tmp_path / "out"
    code, _, err = run(["route", str(write(tmp_path, GOOD)), "--out", str(out), "--quiet"], capsys)
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err
    assert "environment variable PYROUTE_REL_THREADS must be a whole number >= 1 (got 'two')" in err
    assert not out.exists() or not any(out.iterdir())


def test_route_prune_must_be_a_boolean() -> None:
    from pyroute_rel.errors import ScenarioError
    from pyroute_rel.scenario import scenario_from_mapping

    with pytest.raises(ScenarioError, match=r"\[route\]\.prune must be true or false \(got 'yes'\)"):
        scenario_from_mapping(
            {
                "route": {"start": [-12.0, 45.0], "finish": [-60.0, 17.5], "prune": "yes"},
                "weather": {"kind": "uniform", "tws_kn": 15.0, "twd_deg": 0.0},
            }
        )


def test_departure_sweep_routes_each_departure_like_a_single_route(capsys) -> None:
    """--departures with land on (the default) and a refinement: each row equals the same single route."""
    args = ["route", str(EXAMPLE), "--n-ranks", "40", "--quiet", "--refine", "1"]
    assert main([*args, "--json"]) == 0
    single = json.loads(capsys.readouterr().out)
    assert main([*args, "--json", "--departures", "2018-06-01T00:00:00Z,2018-06-03T12:00:00Z"]) == 0
    rows = json.loads(capsys.readouterr().out)["departures"]
    assert [r["departure"] for r in rows] == ["2018-06-01T00:00:00Z", "2018-06-03T12:00:00Z"]
    assert rows[0]["voyage_time_h"] == pytest.approx(single["voyage_time_h"], rel=1e-12)
    assert rows[0]["arrival"] == single["arrival"]
    assert rows[0]["grid_voyage_time_h"] == pytest.approx(single["refine"]["grid_voyage_time_h"], rel=1e-12)
    assert rows[1]["voyage_time_h"] == pytest.approx(single["voyage_time_h"], rel=1e-12)  # steady weather
    assert main([*args, "--departures", "2018-06-01T00:00:00Z,June"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "--departures" in err


def test_out_that_cannot_be_a_folder_is_refused_before_routing(tmp_path, capsys) -> None:
    a_file = tmp_path / "a_file"
    a_file.write_text("x")
    for out in (a_file, a_file / "sub"):
        assert main(["route", str(EXAMPLE), "--n-ranks", "10", "--quiet", "--out", str(out)]) == 2
        err = capsys.readouterr().err.strip()
        assert err.count("\n") == 0 and "--out" in err and "is a file, not a folder" in err
    assert a_file.read_text() == "x"
    assert (
        main(
            [
                "route",
                str(EXAMPLE),
                "--n-ranks",
                "10",
                "--quiet",
                "--departures",
                "2018-06-01T00:00:00Z",
                "--out",
                str(tmp_path / "o"),
            ]
        )
        == 2
    )
    assert "--departures" in capsys.readouterr().err and not (tmp_path / "o").exists()


@pytest.mark.slow
def test_output_files_get_the_usual_file_mode(tmp_path) -> None:
    import os
    import stat

    assert main(["route", str(EXAMPLE), "--n-ranks", "10", "--quiet", "--out", str(tmp_path / "o")]) == 0
    mask = os.umask(0)
    os.umask(mask)
    modes = {p.name: stat.S_IMODE(p.stat().st_mode) for p in (tmp_path / "o").iterdir()}
    assert len(modes) == 6 and set(modes.values()) == {0o666 & ~mask}, modes  # route.png was 0o600


def test_a_grid_too_big_for_memory_is_refused(tmp_path, capsys) -> None:
    # max_deviation_deg = 89.99 was accepted and made an all-to-all grid of 1857 nodes per rank (552 M arcs)
    assert main(["route", str(EXAMPLE), "--quiet", "--aspect", "30", "--max-deviation", "89.99"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "M candidate arcs (160 ranks x 1797 nodes x 1797" in err
    assert "max_deviation_deg" in err


def test_toml_date_literal_departs_at_midnight_utc(tmp_path, capsys) -> None:
    path = write(tmp_path, GOOD.replace('departure = "2018-06-01T00:00:00Z"', "departure = 2018-06-02"))
    assert main(["route", str(path), "--n-ranks", "10", "--quiet", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["departure"] == "2018-06-02T00:00:00Z"


def test_empty_failure_model_names_are_refused(capsys) -> None:
    assert main(["route", str(EXAMPLE), "--quiet", "--failure-model", ""]) == 2
    assert "--failure-model needs a shipped model name" in capsys.readouterr().err
    assert main(["failure", ""]) == 2
    assert "failure model name is empty" in capsys.readouterr().err  # was ".: cannot read (Is a directory)"


def test_n_nodes_note_only_for_the_command_line_option(capsys) -> None:
    assert main(["route", str(EXAMPLE), "--n-ranks", "10", "--quiet"]) == 0  # the file sets n_nodes: no note
    assert "note" not in capsys.readouterr().err
    assert main(["route", str(EXAMPLE), "--n-ranks", "10", "--quiet", "--n-nodes", "31"]) == 0
    err = capsys.readouterr().err
    assert "--n-nodes 31 applies to layout = 'square'" in err and "nodes per rank" in err


@pytest.mark.slow
def test_write_outputs_without_a_plot_leaves_no_stale_map(tmp_path) -> None:
    from pyroute_rel.errors import OutputError, ScenarioError
    from pyroute_rel.files import write_together
    from pyroute_rel.outputs import write_outputs
    from pyroute_rel.scenario import load_scenario

    route = load_scenario(EXAMPLE).with_options(n_ranks=10, land=False).route()
    write_outputs(route, tmp_path / "o")
    assert (tmp_path / "o" / "route.png").exists()
    write_outputs(route, tmp_path / "o", plot=False)
    assert not (tmp_path / "o" / "route.png").exists()  # it described the earlier run
    with pytest.raises(OutputError, match="plain names"):
        write_together(tmp_path / "o", {"../escape.txt": lambda p: p.write_text("x")})
    assert not (tmp_path / "escape.txt").exists()
    with pytest.raises(ScenarioError, match="land must be True or False"):
        load_scenario(EXAMPLE).with_options(land="no")  # was read as True


def test_sample_km_sets_the_spacing_and_is_never_capped(tmp_path, capsys) -> None:
    from pyroute_rel.errors import ScenarioError
    from pyroute_rel.routing.grid import auto_samples
    from pyroute_rel.scenario import load_scenario

    sc = load_scenario(EXAMPLE).with_options(n_ranks=20, land=False, failure_model="none")
    grid = sc.make_grid()
    assert sc.problem(grid=grid).samples == auto_samples(grid)  # default: 25 km
    # 20 ranks: arcs up to sqrt(2) x 256 km = 362 km; 10 km apart needs 37 samples (the automatic rule stops at 16)
    assert sc.with_options(sample_km=10.0).problem(grid=grid).samples == 37
    with pytest.raises(ScenarioError, match=r"sample_km = 5 needs 73 weather samples per arc on this grid \(at most"):
        sc.with_options(sample_km=5.0).problem(grid=grid)
    path = write(tmp_path, GOOD.replace("[grid]", "[grid]\nsample_km = 10\nsamples_per_arc = 3", 1))
    assert main(["route", str(path), "--quiet"]) == 2
    assert "samples_per_arc (a count) or sample_km (a spacing), not both" in capsys.readouterr().err


def test_runtime_covers_loading_the_scenario_and_weather(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch
) -> None:
    """Issue 15: the printed and JSON runtime left out loading the scenario and opening its weather."""
    import time

    import pyroute_rel.scenario as scenario_module

    load = scenario_module.load_scenario

    def slow_load(*args, **kwargs):
        time.sleep(0.3)
        return load(*args, **kwargs)

    monkeypatch.setattr(scenario_module, "load_scenario", slow_load)
    code, out, err = run(["route", str(EXAMPLE), *SMALL, "--json", "--quiet", "--no-land"], capsys)
    assert code == 0, err
    assert json.loads(out)["runtime_s"] >= 0.3
    code, out, err = run(["route", str(EXAMPLE), *SMALL, "--quiet", "--no-land", "--out", str(tmp_path / "o")], capsys)
    assert code == 0, err
    line = next(x for x in out.splitlines() if x.startswith("runtime"))
    printed = float(line.split()[1])
    assert printed >= 0.3 and "loading the scenario and its weather" in line
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert summary["runtime_s"] == pytest.approx(printed, abs=0.006)  # the same figure, printed to 0.01 s


@pytest.mark.parametrize("value", ["-inf", "-nan", "-1", "-0.5e1"])
def test_a_negative_or_non_finite_time_step_is_a_value_not_an_option(value, capsys) -> None:
    """argparse read '--time-step -inf' as a missing argument; it is a bad value, refused by name."""
    code = main(["route", str(EXAMPLE), "--time-step", value, "--max-wait", "2"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1
    assert "time_step_h must be in (0, 48] [h]" in err[0]
