"""Sweeps (pyroute_rel.batch.sweep, ``pyroute-rel sweep``): each row is the single route of the same settings, a killed
sweep resumes to the same table, a real dask cluster gives the same table and loses no run when a worker dies,
bad specifications are one-line errors."""

from __future__ import annotations

import importlib.util
import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
from dask_processes import dask_processes, free_port

from pyroute_rel.batch.sweep import Run, departure_range, load_sweep, read_runs, run_key, run_sweep
from pyroute_rel.cli.main import main
from pyroute_rel.weather import cache

ROOT = Path(__file__).resolve().parents[1]
#: Columns that differ between two runs of the same sweep: the time it took.
TIMING = ("runtime_s",)


def _make_ensemble():
    spec = importlib.util.spec_from_file_location("make_ensemble", ROOT / "benchmarks" / "make_ensemble.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def ensemble(tmp_path_factory) -> Path:
    """A 3-member ensemble (2 deg, 12-hourly, 40 days) and its scenario on 12 ranks."""
    folder = tmp_path_factory.mktemp("ensemble")
    return _make_ensemble().write_ensemble(folder, n_ranks=12, members=3, step_deg=2.0, step_h=12, days=40)


@pytest.fixture(scope="module")
def uninterrupted(ensemble, tmp_path_factory):
    """The sweep of :data:`BODY`, run inline without interruption: (its spec file, its output folder, its table)."""
    folder = tmp_path_factory.mktemp("uninterrupted")
    spec_path = _spec(folder, ensemble, BODY)
    return spec_path, folder / "out", run_sweep(load_sweep(spec_path).runs, out=folder / "out")


def _spec(folder: Path, scenario: Path, body: str, name: str = "spec.toml") -> Path:
    path = folder / name
    path.write_text(f'[sweep]\nscenario = "{scenario}"\n{body}\n', encoding="utf-8")
    return path


#: 2 departures x 3 members x 2 apf: the strict apf leaves some runs without a route (the storm).
BODY = """departures = ["2018-06-02T00:00:00Z", "2018-06-03T00:00:00Z"]
members = "all"
apf = [1.0, 0.02]"""


def _edited(scenario: Path, row: dict) -> Path:
    """The scenario file with the row's departure and member written in by text (independently of the sweep)."""
    text = scenario.read_text(encoding="utf-8")
    text = text.replace('departure = "2018-06-01T00:00:00Z"', f'departure = "{row["departure"]}"')
    text = text.replace("member = 0", f"member = {row['member']}")
    path = scenario.parent / f"edited_{row['key']}.toml"  # beside it: its weather file is named relative to it
    path.write_text(text, encoding="utf-8")
    return path


def _comparable(table) -> list[dict]:
    return sorted(({k: v for k, v in r.items() if k not in TIMING} for r in table.to_pylist()), key=lambda r: r["key"])


@pytest.mark.slow
def test_each_row_equals_the_same_single_route(ensemble, uninterrupted, capsys) -> None:
    spec_path, out, table = uninterrupted
    spec = load_sweep(spec_path)
    assert len(spec.runs) == 12 and {r.member for r in spec.runs} == {0, 1, 2}
    rows = table.to_pylist()
    assert [r["key"] for r in rows] == [run_key(r) for r in spec.runs]
    statuses = {r["status"] for r in rows}
    assert statuses == {"ok", "no_route"}, statuses  # the storm blocks some runs at apf 0.02
    for row in rows:
        code = main(["route", str(_edited(ensemble, row)), "--apf", str(row["apf"]), "--json", "--quiet"])
        printed, err = capsys.readouterr()
        if row["status"] == "no_route":
            # the same line, but for the grid twice as wide that a single route tries and a sweep run does not
            wider = r"it routes on a wider grid, [^;]*?\(\d+\.\d+ h\); |; a grid twice as wide does not route it either"
            alone = re.sub(wider, "", err.strip())
            assert code == 2 and alone == f"pyroute-rel: error: {row['message']}"
            assert row["track"] is None and row["voyage_time_h"] is None
            continue
        assert code == 0, err
        single = json.loads(printed)
        assert row["departure"] == single["departure"] and row["arrival"] == single["arrival"]
        assert abs(row["voyage_time_h"] - single["voyage_time_h"]) <= 1e-9
        assert row["distance_nm"] == pytest.approx(single["distance_nm"], rel=1e-12)
        assert row["max_failure_probability"] == pytest.approx(single["max_failure_probability"], abs=1e-12)
        assert row["voyage_failure_probability"] == pytest.approx(single["voyage_failure_probability"], abs=1e-12)
        assert row["arcs"] == single["arcs"]["evaluated"]
        track = json.loads((out / row["track"]).read_text())
        assert track["geometry"]["coordinates"] == [[p["lon"], p["lat"]] for p in single["track"]]
        assert track["properties"]["time"] == [p["time"] for p in single["track"]]
    on_disk = pq.read_table(out / "runs.parquet")  # the dataset folder, read as one table
    assert _comparable(on_disk) == _comparable(table)


@pytest.mark.slow
def test_weather_is_opened_once_per_member_and_keys_follow_the_files(ensemble, tmp_path) -> None:
    runs = [Run(str(ensemble), departure=d, member=m) for m in (0, 1) for d in departure_range(
        "2018-06-02T00:00Z", "2018-06-02T12:00Z", 6)]  # fmt: skip
    assert len(runs) == 6
    cache.clear()
    table = run_sweep(runs)
    assert set(table.column("status").to_pylist()) == {"ok"}
    assert cache.stats() == {"hits": 4, "misses": 2, "entries": 2}  # one read per member, then reused
    cache.clear()
    copy = tmp_path / "ensemble.toml"
    copy.write_text(ensemble.read_text())
    (tmp_path / "ensemble.nc").write_bytes((ensemble.parent / "ensemble.nc").read_bytes())
    moved = Run(str(copy), departure=runs[0].departure, member=0)
    assert run_key(moved) == run_key(runs[0])  # the same content elsewhere: the same run
    with open(tmp_path / "ensemble.nc", "ab") as fh:
        fh.write(b"\0")  # the weather changed: a new key
    assert run_key(moved) != run_key(runs[0])


def _parts(out: Path) -> list[Path]:
    return sorted((out / "runs.parquet").glob("part-*.parquet"))


@pytest.mark.slow
def test_a_killed_sweep_resumes_to_the_uninterrupted_table(ensemble, uninterrupted, tmp_path, monkeypatch, capsys):
    spec_path = _spec(tmp_path, ensemble, BODY)
    out = tmp_path / "killed"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    cmd = [sys.executable, "-m", "pyroute_rel.cli", "sweep", str(spec_path), "--out", str(out), "--batch", "1"]
    with subprocess.Popen([*cmd, "--quiet"], env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE) as proc:
        deadline = time.monotonic() + 60
        while len(_parts(out)) < 3 and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        assert proc.returncode == -signal.SIGKILL, proc.stderr.read()
    kept = read_runs(out).to_pylist()
    assert 3 <= len(kept) < 12
    computed: list[str] = []
    import pyroute_rel.batch.sweep as sweep

    real = sweep.run_one
    monkeypatch.setattr(sweep, "run_one", lambda run, key: computed.append(key) or real(run, key))
    assert main(["sweep", str(spec_path), "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert f"{len(kept)} done, {12 - len(kept)} to run" in err
    assert sorted(computed) == sorted({run_key(r) for r in load_sweep(spec_path).runs} - {r["key"] for r in kept})
    assert _comparable(read_runs(out)) == _comparable(uninterrupted[2])
    assert main(["sweep", str(spec_path), "--out", str(out), "--json"]) == 0  # all done: nothing to route
    captured = capsys.readouterr()
    assert "12 done, 0 to run" in captured.err and len(json.loads(captured.out)["runs"]) == 12


def _midway_on_dask(cmd: list[str], address: str, env: dict, out: Path) -> subprocess.Popen:
    """The sweep ``cmd`` started on the scheduler at ``address``, returned once it has written two of its twelve
    runs' parts (mid-sweep)."""
    sweep = subprocess.Popen(
        [*cmd, "--scheduler", address, "--connect-timeout", "60", "--quiet"],
        env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    deadline = time.monotonic() + 90
    while len(_parts(out)) < 2 and sweep.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    assert sweep.poll() is None and len(_parts(out)) < 12  # mid-sweep
    return sweep


@pytest.mark.slow
def test_a_dask_cluster_gives_the_inline_table_and_a_killed_worker_loses_no_run(ensemble, uninterrupted, tmp_path):
    env = {**os.environ, "PYTHONPATH": str(ROOT), "PYROUTE_REL_THREADS": "1"}
    with dask_processes(env) as (address, procs):
        spec_path = _spec(tmp_path, ensemble, BODY)
        out = tmp_path / "dask"
        cmd = [sys.executable, "-m", "pyroute_rel.cli", "sweep", str(spec_path), "--out", str(out), "--batch", "1"]
        sweep = _midway_on_dask([*cmd, "--json"], address, env, out)
        procs[1].send_signal(signal.SIGKILL)  # a worker dies mid-sweep: its runs go to the other one
        stdout, stderr = sweep.communicate(timeout=120)
        assert sweep.returncode == 0, stderr
    rows = json.loads(stdout)["runs"]
    assert len(rows) == 12 and not any(r["message"].startswith("internal error") for r in rows)
    assert _comparable(read_runs(out)) == _comparable(uninterrupted[2])


@pytest.mark.slow
def test_a_dying_scheduler_is_one_line_and_the_resume_completes(ensemble, uninterrupted, tmp_path) -> None:
    """Issue 34: the dask scheduler killed mid-sweep was an internal error (exit 3) after distributed's logged
    traceback. Now: exit 2 and one line naming the scheduler, every finished run kept (none an internal error), and
    the same command on a new scheduler routes only the rest, to the uninterrupted table."""
    env = {**os.environ, "PYTHONPATH": str(ROOT), "PYROUTE_REL_THREADS": "1"}
    spec_path = _spec(tmp_path, ensemble, BODY)
    out = tmp_path / "dask"
    cmd = [sys.executable, "-m", "pyroute_rel.cli", "sweep", str(spec_path), "--out", str(out), "--batch", "1"]
    with dask_processes(env) as (address, procs):
        sweep = _midway_on_dask(cmd, address, env, out)
        procs[0].send_signal(signal.SIGKILL)
        _, stderr = sweep.communicate(timeout=120)
    assert sweep.returncode == 2, stderr
    assert stderr.count("\n") == 1 and stderr.startswith(f"pyroute-rel: error: the dask scheduler {address} went away")
    assert "the runs finished so far are kept" in stderr
    kept = read_runs(out).to_pylist()
    assert 2 <= len(kept) < 12 and {r["status"] for r in kept} <= {"ok", "no_route"}
    with dask_processes(env) as (address, _):
        again = subprocess.run([*cmd, "--scheduler", address, "--connect-timeout", "60"], env=env,
                               capture_output=True, text=True, timeout=300)  # fmt: skip
    assert again.returncode == 0, again.stderr
    assert f"{len(kept)} done, {12 - len(kept)} to run" in again.stderr
    assert _comparable(read_runs(out)) == _comparable(uninterrupted[2])


@pytest.mark.slow
def test_a_killed_pool_worker_loses_no_run(ensemble, uninterrupted, tmp_path) -> None:
    """SIGKILL one process of the local pool mid-sweep: the pool is restarted, the unfinished batches run again, and
    the table equals the uninterrupted inline one, without an internal error."""
    import psutil

    spec_path = _spec(tmp_path, ensemble, BODY)
    out = tmp_path / "pool"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    cmd = [sys.executable, "-m", "pyroute_rel.cli", "sweep", str(spec_path), "--engine", "processes"]
    sweep = subprocess.Popen(
        [*cmd, "--workers", "2", "--out", str(out), "--batch", "1", "--quiet", "--json"],
        env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        deadline = time.monotonic() + 120
        while len(_parts(out)) < 1 and sweep.poll() is None and time.monotonic() < deadline:
            time.sleep(0.02)
        me = psutil.Process(sweep.pid)
        workers = [p for p in me.children(recursive=True) if p.ppid() != sweep.pid]  # the forkserver's children
        assert sweep.poll() is None and len(_parts(out)) < 12 and workers  # mid-sweep
        workers[0].send_signal(signal.SIGKILL)
        stdout, stderr = sweep.communicate(timeout=180)
    finally:
        sweep.kill()
        sweep.wait()
    assert sweep.returncode == 0, stderr
    rows = json.loads(stdout)["runs"]
    assert len(rows) == 12 and not any(r["message"].startswith("internal error") for r in rows)
    assert _comparable(read_runs(out)) == _comparable(uninterrupted[2])


def test_a_run_that_keeps_failing_is_retried_a_bounded_number_of_times(ensemble, monkeypatch) -> None:
    """An internal error is tried ``retries`` more times in its worker, then is an internal-error row; a user
    error is a row at once, never retried."""
    import pyroute_rel.batch.sweep as sweep_module

    calls = []

    def flaky(run, key=""):
        calls.append(key)
        if run.member == 0:
            raise RuntimeError("a bug")
        return {"key": key, "status": "error", "message": "user error"}

    monkeypatch.setattr(sweep_module, "run_one", flaky)
    monkeypatch.setattr(sweep_module, "_limit_pools", lambda: None)  # this test process keeps its threads
    runs = [("a", Run(str(ensemble), member=0)), ("b", Run(str(ensemble), member=1))]
    rows = sweep_module.run_batch(runs, retries=2)
    assert calls == ["a", "a", "a", "b"]
    assert rows[0]["message"] == "internal error: RuntimeError: a bug" and rows[0]["_internal"]
    assert {k: v for k, v in rows[1].items() if not k.startswith("_")} == {
        "key": "b",
        "status": "error",
        "message": "user error",
    }
    assert all(r["_worker"].endswith(f":{os.getpid()}") and r["_reads"] == 0 for r in rows)  # routed here, read nothing


def test_auto_engine_uses_the_cores_for_large_sweeps_only() -> None:
    from pyroute_rel.batch.sweep import AUTO_MIN_RUNS, auto_engine

    assert auto_engine(AUTO_MIN_RUNS - 1, 8) == ("inline", None)
    assert auto_engine(AUTO_MIN_RUNS, 8) == ("processes", 8)
    assert auto_engine(10 * AUTO_MIN_RUNS, 1) == ("inline", None)


def test_task_batches_group_members_and_cover_every_run_once() -> None:
    from pyroute_rel.batch.sweep import MAX_BATCH_RUNS, task_batches

    todo = [(f"k{i}", Run("s.toml", member=i % 5, apf=float(i))) for i in range(103)]
    for workers in (1, 2, 7, 200):
        batches = task_batches(todo, workers)
        flat = [k for b in batches for k, _ in b]
        assert sorted(flat) == sorted(k for k, _ in todo)
        assert max(len(b) for b in batches) <= MAX_BATCH_RUNS
        assert len(batches) >= min(len(todo), 4 * workers) // MAX_BATCH_RUNS
        members = [r.member for b in batches for _, r in b]
        assert members == sorted(members)  # a member's runs are consecutive: batches share their weather
        assert all(len({r.member for _, r in b}) == 1 for b in batches)  # a batch is one member's (one worker's)


@pytest.mark.parametrize(
    ("body", "expected"),
    [
        ('departures = {start = "2018-06-02T00:00Z", end = "2018-06-01T00:00Z", step_h = 6}', "must not be before"),
        ('departures = {start = "2018-06-02T00:00Z", end = "2018-06-03T00:00Z"}', "missing step_h"),
        ("apf = [1.0, 2.0]", r"\[sweep\]\.apf\[1\] must be a probability"),
        ("members = [0, -1]", r"\[sweep\]\.members\[1\] must be a whole number"),
        ("grids = [{n_rank = 3}]", r"\[sweep\]\.grids\[0\]: unknown \[grid\] key n_rank"),
        ("grids = [{n_ranks = 0}]", r"\[sweep\]\.grids\[0\]\.n_ranks must be >= 1"),
        ("polar = ['x']", r"\[sweep\]: unknown key polar"),
        # a polar or failure model that does not load is the spec's error, not an error row in each of its runs
        ("polars = ['maribot_vane', 'missing.pol']", r"\[sweep\]\.polars: polar file 'missing.pol'.*not found"),
        ("failure_models = ['none', 'nosuch']", r"\[sweep\]\.failure_models: failure model 'nosuch' not found"),
    ],
)
def test_bad_specifications_are_one_line_errors(ensemble, tmp_path, capsys, body, expected) -> None:
    assert main(["sweep", str(_spec(tmp_path, ensemble, body)), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and err.startswith("pyroute-rel: error: ") and "spec.toml" in err
    assert re.search(expected, err), err
    assert not any(tmp_path.glob("*.png"))


def test_bad_options_and_files_are_one_line_errors(ensemble, tmp_path, capsys) -> None:
    control = ROOT / "examples" / "microtransat_control.toml"
    cases = [
        (["sweep", str(control), "--members", "all"], '--members = "all" needs a scenario whose [weather]'),
        (["sweep", str(control), "--departures", "2018-06-01T00:00Z,June"], "--departures[1]"),
        (["sweep", str(_spec(tmp_path, tmp_path / "nope.toml", ""))], "no such file"),
        (["sweep", str(tmp_path / "missing.toml")], "missing.toml"),
    ]
    for argv, expected in cases:
        assert main([*argv, "--quiet"]) == 2, argv
        err = capsys.readouterr().err.strip()
        assert err.count("\n") == 0 and expected in err, err


@pytest.mark.slow
def test_an_unreachable_scheduler_is_a_one_line_error(ensemble, tmp_path, capsys) -> None:
    argv = ["sweep", str(ensemble), "--scheduler", f"tcp://127.0.0.1:{free_port()}", "--connect-timeout", "1"]
    assert main([*argv, "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "cannot reach the dask scheduler" in err


@pytest.mark.slow
def test_runs_without_a_route_exit_0_and_are_recorded_and_plotted(ensemble, tmp_path, capsys) -> None:
    from pyroute_rel.viz.sweep import sweep_figure

    deps = "2018-06-02T00:00:00Z,2018-06-03T00:00:00Z"
    out = tmp_path / "out"
    argv = ["sweep", str(ensemble), "--departures", deps, "--members", "1", "--apf", "0.02", "--out", str(out)]
    assert main([*argv, "--quiet"]) == 0
    printed = capsys.readouterr().out
    rows = read_runs(out).to_pylist()
    by_dep = {r["departure"]: r for r in rows}
    assert by_dep["2018-06-02T00:00:00Z"]["status"] == "ok"
    bad = by_dep["2018-06-03T00:00:00Z"]
    assert bad["status"] == "no_route" and bad["message"].startswith("no feasible route")
    assert "2 runs: 1 routed, 1 without a route" in printed and (out / "sweep.png").is_file()
    fig = sweep_figure(rows)
    top, bottom = fig.axes[:2]
    ok = by_dep["2018-06-02T00:00:00Z"]
    line = top.lines[0]
    assert list(line.get_ydata()) == [ok["voyage_time_h"]]
    assert list(bottom.lines[0].get_ydata()) == [ok["voyage_failure_probability"]]
    crosses = [ln for ln in top.lines if ln.get_marker() == "x"]
    assert len(crosses) == 1 and list(crosses[0].get_xdata()) == [np.datetime64("2018-06-03T00:00:00")]


def test_a_departure_range_spans_its_ends() -> None:
    got = departure_range("2018-06-01T00:00Z", "2018-06-01T10:00Z", 2.5)
    hours = [(np.datetime64(t.rstrip("Z")) - np.datetime64("2018-06-01T00:00")) / np.timedelta64(1, "h") for t in got]
    assert hours == [0.0, 2.5, 5.0, 7.5, 10.0]
    assert departure_range("2018-06-01T00:00Z", "2018-06-01T01:00Z", 2.0) == ["2018-06-01T00:00:00Z"]


@pytest.mark.slow
def test_a_process_pool_gives_the_inline_rows(ensemble) -> None:
    runs = [Run(str(ensemble), departure="2018-06-02T00:00:00Z", member=m, grid=(("n_ranks", 8),)) for m in (0, 2)]
    inline = run_sweep(runs)
    pooled = run_sweep(runs, engine="processes", workers=2)
    assert _comparable(pooled) == _comparable(inline)
    assert inline.column("status").to_pylist() == ["ok", "ok"]


def test_many_series_are_drawn_as_the_members_medians() -> None:
    """With more series than lines, each apf's line holds each departure's median over the members."""
    from pyroute_rel.viz.sweep import MAX_LINES, sweep_figure

    rng = np.random.default_rng(3)
    rows = [
        {"departure": f"2018-06-0{d + 1}T00:00:00Z", "status": "ok", "member": m, "apf": apf, "failure_model": None,
         "polar": None, "grid": "{}", "options": "{}", "voyage_time_h": float(rng.uniform(700, 800)),
         "voyage_failure_probability": float(rng.uniform(0, 1))}
        for m in range(5) for apf in (1.0, 0.5) for d in range(3)
    ]  # fmt: skip
    assert 10 > MAX_LINES
    top = sweep_figure(rows).axes[0]
    medians = [ln for ln in top.lines if ln.get_linestyle() == "-"]
    assert [ln.get_label() for ln in medians] == ["apf 1.0: median per departure", "apf 0.5: median per departure"]
    for ln, apf in zip(medians, (1.0, 0.5), strict=True):
        expected = [
            np.median(
                [r["voyage_time_h"] for r in rows if r["apf"] == apf and r["departure"].startswith(f"2018-06-0{d}")]
            )
            for d in (1, 2, 3)
        ]
        assert list(ln.get_ydata()) == expected


def test_a_second_sweep_into_a_folder_in_use_refuses_and_rows_are_never_doubled(ensemble, tmp_path, capsys) -> None:
    """Issue 34: two sweeps writing to one folder at once both recorded every run (48 rows for 24 runs). The folder is
    held by the sweep writing it (another process here): a second one refuses with one line (exit 2 from the
    command), writes nothing, and once the first is done it runs and records each run once."""
    spec_path = _spec(tmp_path, ensemble, 'departures = ["2018-06-02T00:00:00Z"]\nmembers = [0]')
    out = tmp_path / "out"
    holder = subprocess.Popen(
        [sys.executable, "-c", "import fcntl, os, sys, time\n"
         f"os.makedirs({str(out)!r}, exist_ok=True); fd = os.open({str(out)!r}, os.O_RDONLY)\n"
         "fcntl.flock(fd, fcntl.LOCK_EX); print('held', flush=True); sys.stdin.read()"],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        assert holder.stdout.readline().strip() == "held"
        assert main(["sweep", str(spec_path), "--out", str(out), "--quiet"]) == 2
        err = capsys.readouterr().err.strip()
        assert (
            err
            == f"pyroute-rel: error: another sweep is writing to '{out}': wait for it to finish, or give another --out"
        )
        assert list(out.iterdir()) == []
    finally:
        holder.communicate("", timeout=30)
    assert main(["sweep", str(spec_path), "--out", str(out), "--quiet"]) == 0
    assert main(["sweep", str(spec_path), "--out", str(out), "--quiet"]) == 0  # resumed: nothing to run
    capsys.readouterr()
    keys = [r["key"] for r in read_runs(out).to_pylist()]
    assert len(keys) == 1 == len(set(keys))


def test_a_folder_made_only_to_hold_a_sweep_is_removed_when_nothing_is_written(tmp_path) -> None:
    with pytest.raises(Exception, match="runs"):
        run_sweep([object()], out=tmp_path / "never")  # refused before the folder is made
    assert not (tmp_path / "never").exists()
    assert run_sweep([], out=tmp_path / "empty").num_rows == 0
    assert not (tmp_path / "empty").exists()


def test_a_scenario_planned_by_another_planner_is_refused_not_routed_by_the_dp(tmp_path, capsys) -> None:
    """Issue 34: a sweep of a scenario with ``[planner] kind = "mcts"`` was routed by the DP without a word."""
    text = (ROOT / "examples" / "microtransat_control.toml").read_text(encoding="utf-8")
    (tmp_path / "s.toml").write_text(text + '\n[planner]\nkind = "mcts"\n', encoding="utf-8")
    for argv in (
        ["sweep", str(_spec(tmp_path, tmp_path / "s.toml", ""))],
        ["sweep", str(tmp_path / "s.toml"), "--departures", "2018-06-01T00:00Z,2018-06-01T12:00Z,12"],
    ):
        assert main([*argv, "--quiet", "--out", str(tmp_path / "out")]) == 2
        err = capsys.readouterr().err.strip()
        assert (
            err.count("\n") == 0
            and "plans with [planner] kind = 'mcts', but a sweep routes every run with the DP" in err
        )
        assert not (tmp_path / "out").exists()


def test_a_resume_sets_aside_unreadable_parts_and_routes_only_their_runs_again(ensemble, tmp_path) -> None:
    """Issue 34: a truncated or corrupt part in runs.parquet ended a resume as an internal error (ArrowInvalid); a
    part of another schema, a directory or an empty file were read or refused as badly. Now each is set aside with a
    warning naming it, only its runs are routed again, and the table is the uninterrupted one."""
    import pyarrow as pa

    from pyroute_rel.errors import PyrouteWarning

    spec_path = _spec(
        tmp_path, ensemble, 'departures = ["2018-06-02T00:00:00Z", "2018-06-03T00:00:00Z"]\nmembers = [0]'
    )
    runs = load_sweep(spec_path).runs
    out = tmp_path / "out"
    first = run_sweep(runs, out=out, batch=1)
    parts = sorted((out / "runs.parquet").glob("part-*.parquet"))
    assert len(parts) == 2
    lost_key = pq.read_table(parts[0]).column("key")[0].as_py()
    parts[0].write_bytes(parts[0].read_bytes()[:40])  # truncated
    folder = out / "runs.parquet"
    (folder / "part-empty.parquet").write_bytes(b"")
    (folder / "part-garbage.parquet").write_bytes(b"PAR1 not parquet at all")
    (folder / "part-dir.parquet").mkdir()
    pq.write_table(pa.table({"key": [lost_key], "other": [1]}), folder / "part-other.parquet")
    with pytest.warns(PyrouteWarning, match="not a readable part of the runs") as seen:
        assert read_runs(out).num_rows == 1  # a reader skips them, moving nothing
    assert len(seen) == 5 and (folder / "part-empty.parquet").exists()
    routed: list[str] = []
    with pytest.warns(PyrouteWarning, match="set aside in"):
        again = run_sweep(runs, out=out, batch=1, log=routed.append)
    assert routed == ["1 done, 1 to run"]
    assert _comparable(again) == _comparable(first)
    assert sorted(p.name for p in (folder / "set-aside").iterdir()) == sorted(
        [parts[0].name, "part-dir.parquet", "part-empty.parquet", "part-garbage.parquet", "part-other.parquet"]
    )
    assert _comparable(read_runs(out)) == _comparable(first)  # read cleanly now, each run once


def test_a_full_disk_is_one_line_keeps_the_runs_recorded_and_the_sweep_resumes(
    ensemble, tmp_path, monkeypatch, capsys
) -> None:
    """Issue 34: 'No space left on device' during a sweep ended as an internal error (exit 3). Now: exit 2 and one
    line; the part written before stays, and the sweep run again routes only the run that was not recorded."""
    import errno

    from pyroute_rel.batch import sweep as sweep_module

    spec_path = _spec(
        tmp_path, ensemble, 'departures = ["2018-06-02T00:00:00Z", "2018-06-03T00:00:00Z"]\nmembers = [0]'
    )
    out = tmp_path / "out"
    real = sweep_module.atomic_write
    calls = []

    def full_after_one(path, writer):
        calls.append(path)
        if len(calls) > 1:
            raise OSError(errno.ENOSPC, "No space left on device", str(path))
        return real(path, writer)

    monkeypatch.setattr(sweep_module, "atomic_write", full_after_one)
    argv = ["sweep", str(spec_path), "--out", str(out), "--quiet", "--batch", "1"]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "No space left on device; the runs recorded before are kept" in err, err
    assert read_runs(out).num_rows == 1
    monkeypatch.setattr(sweep_module, "atomic_write", real)
    assert main([*argv[:-2], "--batch", "1"]) == 0
    capsys.readouterr()
    assert read_runs(out).num_rows == 2


@pytest.mark.parametrize(
    ("departures", "expected"),
    [
        ("2018-06-01T00:00Z,2018-06-02T00:00Z,5e-324", "step_h must be at least one second, 1/3600 h"),
        ("2018-06-01T00:00Z,2030-06-02T00:00Z,0.001", "departures (at most 100000): use a larger step_h"),
    ],
)
def test_a_tiny_step_or_too_many_departures_is_refused_at_once(tmp_path, capsys, departures, expected) -> None:
    """Issue 34: a denormal step ended in an OverflowError (exit 3); 10^6 departures started to be built."""
    t0 = time.perf_counter()
    argv = ["sweep", str(ROOT / "examples" / "microtransat_control.toml"), "--departures", departures, "--quiet"]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and expected in err, err
    assert time.perf_counter() - t0 < 5.0


@pytest.mark.parametrize("case", ["plot is a folder", "runs is a file", "tracks is a file", "tracks is a link"])
def test_an_out_folder_whose_parts_are_of_the_wrong_kind_is_refused_before_routing(tmp_path, capsys, case) -> None:
    """Issue 34: ``--out`` whose sweep.png was a folder ended as an internal error after routing, runs.parquet or
    tracks as a file likewise, and a tracks link sent the track files elsewhere. Each is one line, nothing written."""
    out, elsewhere = tmp_path / "out", tmp_path / "elsewhere"
    out.mkdir()
    elsewhere.mkdir()
    {
        "plot is a folder": lambda: (out / "sweep.png").mkdir(),
        "runs is a file": lambda: (out / "runs.parquet").write_text("x"),
        "tracks is a file": lambda: (out / "tracks").write_text("x"),
        "tracks is a link": lambda: (out / "tracks").symlink_to(elsewhere),
    }[case]()
    before = sorted(p.name for p in out.iterdir())
    argv = ["sweep", str(ROOT / "examples" / "microtransat_control.toml"), "--departures",
            "2018-06-01T00:00Z,2018-06-01T06:00Z,6", "--out", str(out), "--quiet"]  # fmt: skip
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and err.endswith("(nothing was written)"), err
    assert sorted(p.name for p in out.iterdir()) == before and not list(elsewhere.iterdir())


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGTERM])
def test_a_killed_sweep_leaves_no_worker_holding_its_output(ensemble, tmp_path, sig) -> None:
    """Issue 34: after SIGKILL or SIGTERM of a ``--engine processes`` sweep, its workers (and multiprocessing's
    helpers) lived on holding stdout, so ``pyroute-rel sweep ... | cat`` never ended. Here the pipe reaches its end
    within seconds of the kill: every process that held it is gone."""
    import threading

    spec_path = _spec(tmp_path, ensemble, BODY)
    out = tmp_path / "killed"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    cmd = [sys.executable, "-m", "pyroute_rel.cli", "sweep", str(spec_path), "--out", str(out), "--batch", "1",
           "--engine", "processes", "--workers", "2", "--quiet"]  # fmt: skip
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    deadline = time.monotonic() + 90
    while not _parts(out) and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    assert proc.poll() is None and _parts(out), "the sweep should be running its pool"
    proc.send_signal(sig)
    ended = threading.Event()
    threading.Thread(target=lambda: (proc.stdout.read(), ended.set()), daemon=True).start()
    proc.wait(10)
    assert ended.wait(30), "a process still holds the sweep's output 30 s after the kill"
    proc.stdout.close()  # (only once read to its end: a reader blocked in it holds its lock)
