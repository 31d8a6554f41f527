"""``pyroute-rel ensemble`` on a dask cluster (issue 19, item 2: members routed through the sweep's engine): a real
``dask scheduler`` with two ``dask worker`` processes on the loopback interface, and a LocalCluster, give the local
engine's result exactly; an unreachable scheduler is a one-line error, exit 2."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from dask_processes import dask_processes, free_port
from test_evaluate import write_ensemble_scenario

from pyroute_rel.analysis.ensemble import route_ensemble
from pyroute_rel.cli import main
from pyroute_rel.errors import ScenarioError

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def local(tmp_path_factory: pytest.TempPathFactory):
    """A 4-member ensemble and its result in this process (the reference)."""
    path = write_ensemble_scenario(tmp_path_factory.mktemp("ens"), n_members=4)
    return path, route_ensemble(path, engine="inline", risk="cvar:0.75").summary()


@pytest.mark.slow
def test_a_dask_cluster_gives_the_local_result(local) -> None:
    path, expected = local
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    with dask_processes(env) as (address, _):
        cmd = [sys.executable, "-m", "pyroute_rel.cli", "ensemble", str(path), "--risk", "cvar:0.75", "--json"]
        run = subprocess.run(
            [*cmd, "--scheduler", address, "--connect-timeout", "60", "--quiet"],
            env=env, capture_output=True, text=True, timeout=300,
        )  # fmt: skip
        assert run.returncode == 0, run.stderr
        assert json.loads(run.stdout) == json.loads(json.dumps(expected))
        # a second call on the same workers (which dropped the first call's weather) gives it again
        again = subprocess.run([*cmd, "--scheduler", address, "--quiet"], env=env, capture_output=True, text=True)
        assert again.returncode == 0 and json.loads(again.stdout) == json.loads(run.stdout), again.stderr


@pytest.mark.slow
def test_a_dying_scheduler_is_one_line(local, tmp_path) -> None:
    """Issue 34: the scheduler killed while the members are routed: exit 2 and one line naming it, not distributed's
    traceback and an internal error; nothing written."""
    path, _ = local
    env = {**os.environ, "PYTHONPATH": str(ROOT), "PYROUTE_REL_THREADS": "1"}
    out = tmp_path / "out"
    with dask_processes(env, workers=1) as (address, procs):
        cmd = [sys.executable, "-m", "pyroute_rel.cli", "ensemble", str(path), "--out", str(out)]
        run = subprocess.Popen([*cmd, "--scheduler", address, "--connect-timeout", "60", "--quiet"], env=env,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)  # fmt: skip
        deadline = time.monotonic() + 60
        while not _running_a_task(address) and run.poll() is None and time.monotonic() < deadline:
            time.sleep(0.1)
        assert run.poll() is None, run.communicate()
        procs[0].send_signal(signal.SIGKILL)
        _, stderr = run.communicate(timeout=120)
    assert run.returncode == 2, stderr
    assert stderr.count("\n") == 1 and stderr.startswith(f"pyroute-rel: error: the dask scheduler {address} went away")
    assert not out.exists() or not any(out.iterdir())


def _running_a_task(address: str) -> bool:
    """Whether the scheduler at ``address`` has a task processing on a worker (asked from another client)."""
    from distributed import Client

    with Client(address, timeout="10s", set_as_default=False) as c:
        return any(c.processing().values())


@pytest.mark.slow
def test_a_local_dask_cluster_gives_the_local_result(local) -> None:
    """``--engine dask --workers 2``: a LocalCluster of two processes (in a child process: distributed's own
    ResourceWarnings are errors in pytest)."""
    path, expected = local
    cmd = [sys.executable, "-m", "pyroute_rel.cli", "ensemble", str(path), "--risk", "cvar:0.75", "--json"]
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    run = subprocess.run([*cmd, "--engine", "dask", "--workers", "2", "--quiet"], env=env, capture_output=True,
                         text=True, timeout=300)  # fmt: skip
    assert run.returncode == 0, run.stderr
    assert json.loads(run.stdout) == json.loads(json.dumps(expected))


@pytest.mark.slow
def test_an_unreachable_scheduler_is_a_one_line_error(local, capsys: pytest.CaptureFixture[str]) -> None:
    path, _ = local
    argv = ["ensemble", str(path), "--scheduler", f"tcp://127.0.0.1:{free_port()}", "--connect-timeout", "1"]
    assert main([*argv, "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "cannot reach the dask scheduler" in err, err


@pytest.mark.parametrize(
    ("kwargs", "expected"),
    [
        ({"engine": "threads"}, "engine must be one of auto, inline, processes, dask"),
        ({"engine": "processes", "scheduler": "tcp://127.0.0.1:1"}, "--scheduler needs the dask engine"),
        ({"engine": "inline", "workers": 2}, "--workers 2 needs the processes or dask engine"),
        ({"scheduler": "tcp://127.0.0.1:1", "workers": 2}, "give it or --scheduler, not both"),
        ({"engine": "dask", "connect_timeout_s": 0.0}, "connect_timeout_s"),
    ],
)
def test_engine_options_are_checked_before_any_work(tmp_path: Path, kwargs, expected) -> None:
    path = tmp_path / "missing_weather.toml"
    path.write_text('[route]\nstart = [-14.0, 31.0]\nfinish = [-22.0, 25.0]\n[weather]\nkind = "file"\n'
                    'paths = ["nope.nc"]\n')  # fmt: skip
    with pytest.raises(ScenarioError, match=expected):
        route_ensemble(path, **kwargs)
