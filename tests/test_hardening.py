"""Hardening, round 2 (issue 17): GCI gates that cannot pass by accident, all-or-nothing outputs, coordinates and
zones that look wrong, and exit 2 with one line for user mistakes that used to be internal errors (exit 3)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from pyroute_rel.cli import main
from pyroute_rel.gci.numbers import P_PLAUSIBLE, ROUNDOFF_REL, convergence_study, grid_convergence

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "microtransat_control.toml"
SMALL = ["--layout", "square", "--n-nodes", "7", "--n-ranks", "7", "--no-land", "--quiet"]
ENV = {**os.environ, "PYTHONPATH": str(ROOT)}


def run(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    code = main(args)
    out, err = capsys.readouterr()
    return code, out, err


def cli(*args: str, **kw) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "pyroute_rel.cli", *args], capture_output=True, text=True, env=ENV, timeout=120, **kw
    )


# --------------------------------------------------------------------------------------------------
# item 6: GCI gates
# --------------------------------------------------------------------------------------------------


def test_roundoff_differences_make_the_triplet_indeterminate() -> None:
    # eps21 = 1e-300, max|phi| = 1: far below 1e-10 * 1, so no order (it used to be p = 996.6)
    res = grid_convergence([1.0, 2.0, 4.0], [0.0, 1e-300, 1.0])
    assert res.convergence == "indeterminate" and res.p is None and res.gci_fine is None
    assert "round-off" in res.note
    # 700 vs 700.000000000001: eps21 = 1.02e-12 <= 1e-10 * 703 = 7.03e-8
    res = grid_convergence([1.0, 2.0, 4.0], [700.0, 700.000000000001, 703.0])
    assert res.convergence == "indeterminate" and res.p is None
    # just above the threshold the triplet is judged as before: eps21 = 2e-10 * 703 > tol
    eps = 2 * ROUNDOFF_REL * 703.0
    res = grid_convergence([1.0, 2.0, 4.0], [700.0, 700.0 + eps, 703.0])
    assert res.convergence == "monotonic" and res.p is not None


@pytest.mark.parametrize(
    ("phi", "verdict"),
    [
        ([12.0, 18.0, 42.0], "converging"),  # 10 + 2 h^2: p = 2
        ([10.0 + 2.0 * h**0.45 for h in (1.0, 2.0, 4.0)], "indeterminate"),  # p = 0.45 < 0.5
        ([10.0 + 2.0 * h**0.55 for h in (1.0, 2.0, 4.0)], "converging"),  # p = 0.55
        ([10.0 + 1e-3 * h**7.9 for h in (1.0, 2.0, 4.0)], "converging"),  # p = 7.9
        ([10.0 + 1e-3 * h**8.1 for h in (1.0, 2.0, 4.0)], "indeterminate"),  # p = 8.1 > 8
        ([5.0, 5.0, 5.0], "converged"),
        ([1.0, 3.0, 4.0], "indeterminate"),  # divergent
    ],
)
def test_study_verdict_on_the_plausible_order_range(phi: list[float], verdict: str) -> None:
    assert P_PLAUSIBLE == (0.5, 8.0)
    study = convergence_study([1.0, 2.0, 4.0], phi)
    assert study.verdict()[0] == verdict
    assert study.to_dict()["verdict"] == verdict


def test_issue_case_gate_fails_with_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    args = ["gci", "--h", "1,2,4", "--phi", "700,700.000000000001,703", "--max-gci", "0.01", "--require-asymptotic"]
    code, _, err = run(args, capsys)
    assert code == 1 and err.count("\n") == 1
    assert "indeterminate" in err and "round-off" in err
    # an implausible order (p = 9.97 from 10, 10.001, 11: |eps32/eps21| = 1000 = 2^9.97) fails --max-gci
    code, _, err = run(["gci", "--h", "1,2,4", "--phi", "10,10.001,11", "--max-gci", "0.5"], capsys)
    assert code == 1 and "outside the plausible 0.5 to 8" in err
    # without a gate the study is reported, exit 0
    code, out, _ = run(["gci", "--h", "1,2,4", "--phi", "10,10.001,11", "--json"], capsys)
    assert code == 0 and json.loads(out)["verdict"] == "indeterminate"


@pytest.mark.parametrize("json_flag", [["--json"], []])
def test_gate_failure_survives_a_closed_pipe(json_flag: list[str]) -> None:
    cmd = [sys.executable, "-m", "pyroute_rel.cli", "gci", "--h", "1,2,4", "--phi", "700.3,701.2,704.8"]
    cmd += ["--max-gci", "0.0001", *json_flag]
    alone = subprocess.run(cmd, capture_output=True, text=True, env=ENV, timeout=60)
    assert alone.returncode == 1
    # the reader closes the pipe at once; the gate's verdict must still be the exit code
    code, err = _closed_pipe(cmd)
    assert code == 1
    assert "gate failed" in err and "Traceback" not in err and "Exception ignored" not in err
    # a passing gate with a closed pipe is still 0
    ok = [*cmd[: -2 - len(json_flag)], "--max-gci", "0.5", *json_flag]
    assert _closed_pipe(ok) == (0, "")


def _closed_pipe(cmd: list[str]) -> tuple[int, str]:
    """Run ``cmd`` with its stdout read by no one (closed at once): exit code, stderr."""
    with subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=ENV) as proc:
        proc.stdout.close()
        err = proc.stderr.read().decode()
        return proc.wait(timeout=60), err
