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


def test_every_case_names_modules_and_functions_that_exist() -> None:
    """Each case's ``from pyroute_rel... import ...`` lines resolve: a module moved by a restructure (issue 33) broke
    ``monte_carlo_1000_runs_160_legs`` once, unseen because CI does not run the benchmarks."""
    import ast
    import importlib

    runner = _runner()
    checked = 0
    for name, (code, _target, _what) in runner.CASES.items():
        for node in ast.walk(ast.parse(code)):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("pyroute_rel"):
                module = importlib.import_module(node.module)
                for alias in node.names:
                    assert hasattr(module, alias.name), f"{name}: {node.module}.{alias.name}"
                    checked += 1
            elif isinstance(node, ast.Import):
                for alias in node.names:
                    if alias.name.startswith("pyroute_rel"):
                        importlib.import_module(alias.name)
                        checked += 1
    assert checked > len(runner.CASES)
