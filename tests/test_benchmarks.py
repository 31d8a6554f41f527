"""``benchmarks/run.py``: ``--quick`` (advertised in its docstring) runs a few fast cases with fewer repeats."""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

RUN = Path(__file__).resolve().parents[1] / "benchmarks" / "run.py"


def _runner():
    spec = importlib.util.spec_from_file_location("bench_run", RUN)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    module._load_case_files()
    return module


def test_quick_cases_exist() -> None:
    runner = _runner()
    assert set(runner.QUICK_CASES) <= set(runner.CASES) and 0 < len(runner.QUICK_CASES) < len(runner.CASES)


@pytest.mark.slow
def test_quick_runs_a_case_once(tmp_path: Path) -> None:
    env = {**os.environ, "PYTHONPATH": str(RUN.parents[1])}
    run = subprocess.run(
        [sys.executable, str(RUN), "--quick", "--only", "dp_all_to_all_80", "--json"],
        capture_output=True,
        text=True,
        env=env,
        check=False,
    )
    assert run.returncode == 0, run.stderr
    d = json.loads(run.stdout)
    assert [c["name"] for c in d["cases"]] == ["dp_all_to_all_80"] and d["cases"][0]["pass"] is True
    assert d["machine"]["cores"] >= 1
    bad = subprocess.run([sys.executable, str(RUN), "--only", "nope"], capture_output=True, text=True, env=env)
    assert bad.returncode == 2 and bad.stderr.count("\n") == 1 and "unknown case 'nope'" in bad.stderr
