"""The example scripts write only to their output folder: ``examples/output/`` (git ignores it) or ``--out``; the
README's committed figures in ``examples/figures/`` only with ``--figures``."""

from __future__ import annotations

import argparse
import importlib.util
import os
import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
SCRIPTS = ["paper_reproduction", "convergence_study", "real_course", "era5_figure", "planners_comparison"]


def _load(name: str):
    if str(EXAMPLES) not in sys.path:  # as `python examples/<name>.py` does: the scripts import output_options
        sys.path.insert(0, str(EXAMPLES))
    spec = importlib.util.spec_from_file_location(f"example_{name}", EXAMPLES / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.parametrize("name", SCRIPTS)
def test_examples_write_to_their_output_folder(name: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    module = _load(name)
    ap = argparse.ArgumentParser()
    assert module.output_folder(ap, argparse.Namespace(out=None, figures=False)) == EXAMPLES / "output"
    assert module.output_folder(ap, argparse.Namespace(out=str(tmp_path / "o"), figures=False)) == tmp_path / "o"
    assert (tmp_path / "o").is_dir()
    assert module.output_folder(ap, argparse.Namespace(out=None, figures=True)) == EXAMPLES / "figures"
    with pytest.raises(SystemExit) as exc:
        module.output_folder(ap, argparse.Namespace(out=str(tmp_path / "p"), figures=True))
    assert exc.value.code == 2 and not (tmp_path / "p").exists()
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "give --out or --figures, not both" in err
    assert "/examples/output/" in (EXAMPLES.parent / ".gitignore").read_text().splitlines()


@pytest.mark.slow
def test_paper_reproduction_leaves_the_committed_figures_alone(tmp_path: Path) -> None:
    """Issue 15: the script overwrote examples/figures/paper_routes_angular.png on every run."""
    committed = {p: p.stat().st_mtime_ns for p in (EXAMPLES / "figures").iterdir()}
    env = {**os.environ, "MPLBACKEND": "Agg", "PYTHONPATH": str(EXAMPLES.parent)}
    run = subprocess.run(
        [sys.executable, str(EXAMPLES / "paper_reproduction.py"), "--out", str(tmp_path)],
        capture_output=True,
        text=True,
        env=env,
        check=False,
    )
    assert run.returncode == 0, run.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["paper_routes_angular.json", "paper_routes_angular.png"]
    assert {p: p.stat().st_mtime_ns for p in (EXAMPLES / "figures").iterdir()} == committed


def test_the_scripts_share_one_output_folder_helper() -> None:
    # The --out/--figures handling was written four times; each script now uses examples/output_options.py.
    for name in SCRIPTS:
        module = _load(name)
        shared = sys.modules["output_options"]  # what the script imported
        assert module.output_folder is shared.output_folder
        assert module.add_output_options is shared.add_output_options
        ap = argparse.ArgumentParser()
        module.add_output_options(ap)
        assert ap.parse_args(["--out", "x"]) == argparse.Namespace(out="x", figures=False)
