"""Sweeps against the command line (the parts tests/test_sweep.py does not reach; issue 18): rows over grids (with a
refinement), polars and failure models equal `pyroute-rel route --json` on the scenario file edited by hand; the
progress bar counts the runs done and failed and shows the rate; `route --departures` routes through the sweep
library; the printed table has a row per run."""

from __future__ import annotations

import functools
import io
import json
import re
import sys
from pathlib import Path

import pytest

from pyroute_rel.cli.main import main

ROOT = Path(__file__).resolve().parents[1]

#: A fast scenario: steady wind, one wave patch that dickson2018 at apf 0.5 forbids (so the failure model matters).
SCENARIO = """[route]
start = [-12.0, 45.0]
finish = [-20.0, 40.0]
departure = "2018-06-01T00:00:00Z"

[grid]
n_ranks = 12

[boat]
polar = "maribot_vane"

[avoid]
land = false

[weather]
kind = "uniform"
tws_kn = 15.0
twd_deg = 0.0
hs_m = 1.0

[[weather.patch]]
lon = [-17.0, -15.0]
lat = [41.0, 44.0]
hs_m = 4.5

[failure]
model = "dickson2018"
apf = 0.5
"""


def _slow_polar(path: Path) -> Path:
    """The shipped maribot_vane polar with every speed times 0.8, written as text (another boat)."""
    rows = (ROOT / "examples" / "maribot_vane.pol").read_text().splitlines()
    out = [rows[0]]
    for line in rows[1:]:
        cells = line.split("\t")
        out.append("\t".join([cells[0], *(f"{0.8 * float(c):g}" for c in cells[1:])]))
    path.write_text("\n".join(out) + "\n")
    return path


def _edited(folder: Path, row: dict, polar_file: Path) -> Path:
    """The scenario with the row's grid, polar and failure model written in by text (independently of the sweep)."""
    grid = json.loads(row["grid"])
    text = SCENARIO.replace("n_ranks = 12", "\n".join(f"{k} = {v}" for k, v in grid.items()))
    if row["polar"] != "maribot_vane":
        assert row["polar"] == str(polar_file)
        text = text.replace('polar = "maribot_vane"', f'polar = "{polar_file.name}"')
    text = text.replace('model = "dickson2018"', f'model = "{row["failure_model"]}"')
    if row["failure_model"] == "none":
        text = text.replace("apf = 0.5\n", "")
    path = folder / f"edited_{row['key']}.toml"
    path.write_text(text)
    return path


@pytest.mark.slow
def test_rows_over_grids_polars_and_failure_models_equal_single_routes(tmp_path: Path, capsys) -> None:
    """8 runs (2 grids, one refined; 2 polars; 2 failure models): each row's voyage time within 1e-9 h of `route
    --json` on the edited file, the same track point by point; and every dimension changes the result."""
    from pyroute_rel.batch.sweep import read_runs

    (tmp_path / "s.toml").write_text(SCENARIO)
    polar = _slow_polar(tmp_path / "slow.pol")
    (tmp_path / "spec.toml").write_text(
        '[sweep]\nscenario = "s.toml"\ngrids = [{n_ranks = 10}, {n_ranks = 14, refine = 1}]\n'
        'polars = ["maribot_vane", "slow.pol"]\nfailure_models = ["dickson2018", "none"]\n'
    )
    out = tmp_path / "out"
    assert main(["sweep", str(tmp_path / "spec.toml"), "--out", str(out), "--quiet"]) == 0
    printed = capsys.readouterr().out
    rows = read_runs(out).to_pylist()
    assert len(rows) == 8 and {r["status"] for r in rows} == {"ok"}
    assert "8 runs: 8 routed, 0 without a route" in printed
    assert sum(1 for line in printed.splitlines() if " ok " in f" {line} ") == 8  # the table: a line per run
    for row in rows:
        code = main(["route", str(_edited(tmp_path, row, polar)), "--json", "--quiet"])
        single_text, err = capsys.readouterr()
        assert code == 0, err
        single = json.loads(single_text)
        assert abs(row["voyage_time_h"] - single["voyage_time_h"]) <= 1e-9
        assert row["arrival"] == single["arrival"] and row["arcs"] == single["arcs"]["evaluated"]
        assert row["max_failure_probability"] == single["max_failure_probability"]
        if "refine" in single:
            assert row["grid_voyage_time_h"] == single["refine"]["grid_voyage_time_h"]
        else:
            assert row["grid_voyage_time_h"] is None
        track = json.loads((out / row["track"]).read_text())
        assert track["geometry"]["coordinates"] == [[p["lon"], p["lat"]] for p in single["track"]]
    for column, values in (("grid", 2), ("polar", 2), ("failure_model", 2)):
        assert len({r[column] for r in rows}) == values
        # two runs that differ in this setting alone route differently
        for r in rows:
            twins = [s for s in rows if s[column] != r[column] and all(
                s[c] == r[c] for c in ("grid", "polar", "failure_model") if c != column)]  # fmt: skip
            assert len(twins) == 1
            if column != "failure_model" or r["polar"] == "maribot_vane":
                assert twins[0]["voyage_time_h"] != r["voyage_time_h"] or twins[0]["track"] != r["track"], column


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


@pytest.mark.slow
def test_progress_bar_shows_runs_done_failed_and_rate(tmp_path: Path, monkeypatch) -> None:
    """On a terminal the sweep's bar counts the runs (n/total), the failed ones (a user error and a run without a
    route) and the rate; quiet when not a terminal."""
    from pyroute_rel.batch.sweep import Run, run_sweep

    (tmp_path / "s.toml").write_text(SCENARIO)
    s = str(tmp_path / "s.toml")
    stormy = SCENARIO.replace("lon = [-17.0, -15.0]\nlat = [41.0, 44.0]", "lon = [-13.0, -11.0]\nlat = [44.0, 46.0]")
    (tmp_path / "stormy_start.toml").write_text(stormy)
    runs = [
        Run(s, polar=str(tmp_path / "missing.pol")),  # a user error: status error
        Run(str(tmp_path / "stormy_start.toml")),  # 4.5 m waves at the start, apf 0.5: no route
        Run(s, grid=(("n_ranks", 8),)),
        Run(s, grid=(("n_ranks", 9),)),
        Run(s, grid=(("n_ranks", 10),)),
    ]
    import tqdm as tqdm_package

    # every update drawn (not only every 0.1 s), so that the last counts are on the stream however fast the runs
    monkeypatch.setattr(tqdm_package, "tqdm", functools.partial(tqdm_package.tqdm, mininterval=0.0))
    term = _Terminal()
    monkeypatch.setattr(sys, "stderr", term)
    table = run_sweep(runs, progress=True)
    statuses = table.column("status").to_pylist()
    assert statuses[:2] == ["error", "no_route"] and statuses[2:] == ["ok"] * 3
    text = term.getvalue()
    assert "sweep" in text and "5/5" in text
    assert re.search(r"failed 2", text), text
    assert re.search(r"\d(\.\d+)?(run/s|s/run)", text), text
    quiet = _Terminal()
    monkeypatch.setattr(sys, "stderr", quiet)
    run_sweep(runs[2:3], progress=False)
    assert quiet.getvalue() == ""


@pytest.mark.slow
def test_route_departures_is_a_use_of_the_sweep_library(monkeypatch, capsys) -> None:
    """`route --departures` routes each departure with pyroute_rel.batch.sweep.run_one (one call per departure, the
    departure and the command's options in the Run) and prints the sweep's figures."""
    import pyroute_rel.batch.sweep as sweep

    calls: list[sweep.Run] = []
    rows: list[dict] = []
    real = sweep.run_one

    def spy(run, key=""):
        calls.append(run)
        rows.append(real(run, key))
        return rows[-1]

    monkeypatch.setattr(sweep, "run_one", spy)
    control = ROOT / "examples" / "microtransat_control.toml"
    deps = ["2018-06-01T00:00:00Z", "2018-06-02T06:00:00Z"]
    assert main(["route", str(control), "--n-ranks", "10", "--quiet", "--json", "--departures", ",".join(deps)]) == 0
    printed = json.loads(capsys.readouterr().out)["departures"]
    assert [c.departure for c in calls] == deps
    assert all(dict(c.options).get("n_ranks") == 10 for c in calls)
    assert [p["voyage_time_h"] for p in printed] == [r["voyage_time_h"] for r in rows]
    assert [p["arrival"] for p in printed] == [r["arrival"] for r in rows]


@pytest.mark.slow
def test_workers_alone_start_a_dask_local_cluster_with_the_inline_rows(tmp_path: Path, monkeypatch, capsys) -> None:
    """`sweep --workers 2` (no --engine) routes on a dask LocalCluster of 2 one-thread processes; the rows are the
    inline engine's."""
    import distributed

    from pyroute_rel.batch.sweep import load_sweep, read_runs, run_sweep

    started: list[dict] = []
    real = distributed.LocalCluster

    def spy(*args, **kwargs):
        started.append(dict(kwargs))
        # With dashboard_address=None the scheduler's HTTP server still tries port 8787 and, when another cluster on
        # this machine holds it, warns (an error here) and leaks a socket: not this test's subject (reported).
        return real(*args, **{**kwargs, "dashboard_address": ":0"})

    monkeypatch.setattr(distributed, "LocalCluster", spy)
    (tmp_path / "s.toml").write_text(SCENARIO)
    spec = tmp_path / "spec.toml"
    spec.write_text('[sweep]\nscenario = "s.toml"\napf = [1.0, 0.5]\ngrids = [{n_ranks = 8}, {n_ranks = 10}]\n')
    out = tmp_path / "out"
    assert main(["sweep", str(spec), "--workers", "2", "--out", str(out), "--quiet"]) == 0
    capsys.readouterr()
    assert len(started) == 1 and started[0]["n_workers"] == 2 and started[0]["threads_per_worker"] == 1
    inline = run_sweep(load_sweep(spec).runs, engine="inline").to_pylist()
    dask_rows = {r["key"]: r for r in read_runs(out).to_pylist()}
    assert len(dask_rows) == 4
    for row in inline:
        other = dask_rows[row["key"]]
        assert {k: v for k, v in other.items() if k not in ("runtime_s", "track")} == {
            k: v for k, v in row.items() if k not in ("runtime_s", "track")
        }
        assert (out / other["track"]).is_file()


def test_a_runs_key_follows_every_file_it_reads(tmp_path: Path) -> None:
    """Re-running skips a run only when nothing it reads changed: the key changes with the scenario file, a polar
    file (the scenario's or the run's), a zones file, a failure-model file and the network it names (issue 34: an
    edited .bif behind an unchanged TOML kept the old rows), and not when another file changes."""
    import shutil

    from pyroute_rel.batch.sweep import Run, run_key

    shutil.copy(ROOT / "failure_models" / "dickson2018.toml", tmp_path / "model.toml")
    shutil.copy(ROOT / "failure_models" / "dickson2018.bif", tmp_path / "dickson2018.bif")
    _slow_polar(tmp_path / "boat.pol")
    _slow_polar(tmp_path / "other.pol")
    zone = {"type": "Polygon", "coordinates": [[[-16, 41], [-15, 41], [-15, 42], [-16, 42], [-16, 41]]]}
    (tmp_path / "zone.geojson").write_text(json.dumps({"type": "Feature", "geometry": zone, "properties": {}}))
    text = SCENARIO.replace('polar = "maribot_vane"', 'polar = "boat.pol"').replace(
        "land = false", 'land = false\nzones = ["zone.geojson"]'
    )
    text = text.replace('model = "dickson2018"', 'model = "model.toml"')
    (tmp_path / "s.toml").write_text(text)
    (tmp_path / "unrelated.txt").write_text("a")
    run = Run(str(tmp_path / "s.toml"))
    other_polar = Run(str(tmp_path / "s.toml"), polar=str(tmp_path / "other.pol"))
    keys = [run_key(run), run_key(other_polar)]

    def touch(name: str) -> None:
        with open(tmp_path / name, "a") as fh:
            comment = {".toml": "\n# edited\n", ".pol": "\n# edited\n", ".bif": "\n// edited\n"}
            fh.write(comment.get(Path(name).suffix, " "))

    (tmp_path / "unrelated.txt").write_text("b")
    assert [run_key(run), run_key(other_polar)] == keys
    for name, changes in (("boat.pol", [True, False]), ("other.pol", [False, True]), ("zone.geojson", [True, True]),
                          ("model.toml", [True, True]), ("dickson2018.bif", [True, True]),  # the model's network
                          ("s.toml", [True, True])):  # fmt: skip
        touch(name)
        now = [run_key(run), run_key(other_polar)]
        assert [a != b for a, b in zip(now, keys, strict=True)] == changes, name
        keys = now


@pytest.mark.slow
def test_departure_planning_from_a_scenario_alone_prints_the_table_and_plots(tmp_path: Path, capsys) -> None:
    """`sweep SCENARIO --departures START,END,STEP_H --plot FILE`: a table row per departure (in order, each with
    its voyage time) and the plot, its top panel drawing those voyage times against departure; nothing else
    written."""
    from matplotlib.image import imread

    (tmp_path / "s.toml").write_text(SCENARIO)
    plot = tmp_path / "plan.png"
    argv = ["sweep", str(tmp_path / "s.toml"), "--departures", "2018-06-01T00:00Z,2018-06-01T12:00Z,6"]
    assert main([*argv, "--plot", str(plot), "--quiet"]) == 0
    lines = capsys.readouterr().out.splitlines()
    rows = [line.split() for line in lines if line.startswith("2018-")]
    assert [r[0] for r in rows] == ["2018-06-01T00:00:00Z", "2018-06-01T06:00:00Z", "2018-06-01T12:00:00Z"]
    assert all(r[1] == "ok" and float(r[2]) > 0 for r in rows)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["plan.png", "s.toml"]
    assert imread(plot).shape[0] > 300
    assert main([*argv, "--json", "--quiet"]) == 0
    runs = json.loads(capsys.readouterr().out)["runs"]
    assert [f"{r['voyage_time_h']:.2f}" for r in runs] == [r[2] for r in rows]
