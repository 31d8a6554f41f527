"""Planner and Monte-Carlo settings that cannot apply: refused (one line, exit 2, naming the file or option) or noted,
as the rest of the command line treats them (session 9 clean-up of issues 19 and 22).

How the CLI already treats an option that does not apply, and what these tests hold the planners to:
- a command-line option that would be ignored is refused: ``evaluate --kappa`` without ``--monte-carlo``,
  ``route --departures`` with ``--planner``; so ``route --planner ... --refine/--prune/--no-prune`` and
  ``evaluate --seed`` without ``--monte-carlo``;
- a scenario file's setting for a mode the file does not use is read without complaint (``[grid].n_nodes`` with the
  angular layout): so another planner's table is not looked at, and a setting of the planner's own table that its
  mode leaves unused is named in a note on stderr (as ``route``'s notes), not refused.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from pyroute_rel import scenario_from_mapping
from pyroute_rel.errors import ScenarioError
from pyroute_rel.planners.plan import plan
from pyroute_rel.planners.settings import MODE_SETTINGS, parse_planner, unused_settings
from tests.test_hardening import run

COURSE = """[route]
start = [-12.0, 45.0]
finish = [-13.0, 44.0]
departure = "2018-06-01T00:00:00Z"
[grid]
layout = "square"
n_ranks = 5
n_nodes = 7
[weather]
kind = "uniform"
tws_kn = 15.0
twd_deg = 0.0
[avoid]
land = false
"""


#: Every mode setting's values (the settings module's own lists are what is checked against them).
CHOICES = {
    "engine": ("lattice", "python"),
    "weather": ("auto", "forecast", "members", "perturbed"),
    "space": ("graph", "cells"),
    "time_costing": ("passes", "buckets"),
}


def scenario_file(tmp_path: Path, planner: str = "") -> Path:
    path = tmp_path / "course.toml"
    path.write_text(COURSE + planner)
    return path


def test_members_weather_without_members_names_the_scenario_file(tmp_path, capsys):
    path = scenario_file(tmp_path, '[planner.mcts]\nweather = "members"\niterations = 5\n')
    for engine in ("lattice", "python"):
        code, out, err = run(
            ["route", str(path), "--planner", "mcts", "--quiet", "--out", str(tmp_path / engine)], capsys
        )
        assert code == 2 and out == "" and "Traceback" not in err
        assert len(err.strip().splitlines()) == 1
        assert f"{path}: [planner.mcts].weather = 'members' needs ensemble members (there are none" in err
        assert not (tmp_path / engine).exists()
        path.write_text(path.read_text() + 'engine = "python"\n')
    with pytest.raises(ScenarioError, match=r"^<scenario>: \[planner.mcts\].weather = 'members' needs"):
        plan(course(kind="mcts", mcts={"weather": "members"}))


@pytest.mark.parametrize(("epsilon", "final"), [(0.2, 0.3), (0.0, 0.05), (0.5, 1.0)])
def test_dqn_exploration_may_not_rise(epsilon, final, tmp_path, capsys):
    """epsilon_final above epsilon was accepted (exploration rising over the training); refused naming both."""
    expected = (
        f"[planner.dqn].epsilon_final must be at most epsilon: exploration falls from epsilon to epsilon_final "
        f"(got epsilon_final {final:g} and epsilon {epsilon:g})"
    )
    table = {"epsilon": epsilon} if final == 0.05 else {"epsilon": epsilon, "epsilon_final": final}
    with pytest.raises(ScenarioError) as info:
        parse_planner({"dqn": table})
    assert str(info.value) == expected
    lines = "\n".join(f"{k} = {v}" for k, v in table.items())
    path = scenario_file(tmp_path, f"[planner.dqn]\n{lines}\n")
    code, out, err = run(["route", str(path), "--planner", "dqn", "--quiet"], capsys)
    assert code == 2 and out == "" and err.strip() == f"pyroute-rel: error: {path}: {expected}"


def test_dqn_exploration_may_stay_or_fall_to_zero():
    assert parse_planner({"dqn": {"epsilon": 0.1, "epsilon_final": 0.1}}).dqn.epsilon_final == 0.1
    assert parse_planner({"dqn": {"epsilon": 0.0, "epsilon_final": 0.0}}).dqn.epsilon == 0.0


@pytest.mark.parametrize(
    ("option", "shown"), [(["--refine", "1"], "--refine"), (["--prune"], "--prune"), (["--no-prune"], "--no-prune")]
)
def test_dp_options_with_another_planner_are_refused(option, shown, tmp_path, capsys):
    """--refine and --prune change only the DP's route; with --planner they were silently ignored."""
    path = scenario_file(tmp_path)
    out_dir = tmp_path / "out"
    code, out, err = run(["route", str(path), "--planner", "qlearning", *option, "--out", str(out_dir)], capsys)
    assert code == 2 and out == "" and not out_dir.exists()
    assert err.strip() == (
        f"pyroute-rel: error: {shown} applies to the DP only (leave it out, or use --planner dp; the planner is "
        "qlearning)"
    )


def test_unused_settings_of_the_planners_own_table_are_noted(tmp_path, capsys):
    """A setting its table's mode does not use is named on stderr (with the file), the route still planned; another
    planner's table is not looked at (a scenario may hold every planner's settings), nor a setting at its default."""
    planner = (
        '[planner]\nkind = "qlearning"\n[planner.qlearning]\nepisodes = 50\ngamma = 1.0\ncell_nm = 60.0\n'
        "cells_across = 10\n[planner.mcts]\nlattice_h = 3.0\n"
    )
    path = scenario_file(tmp_path, planner)
    code, out, err = run(["route", str(path), "--json", "--quiet"], capsys)
    assert code == 0 and json.loads(out)["planner"] == "qlearning"
    assert err.strip() == (
        f"pyroute-rel: note: {path}: [planner.qlearning].cell_nm = 60.0 is not used: it applies to space = 'cells' "
        "(the table has space = 'graph')"
    )


@pytest.mark.parametrize(("table", "setting", "mode", "modes"), MODE_SETTINGS)
def test_each_mode_setting_is_noted_outside_its_modes_only(table, setting, mode, modes):
    """Every listed setting, changed from its default: no note in the modes that use it, a note naming it in the
    others (and MCTS's lattice settings with graph = true, which searches with the Python engine)."""
    cls = type(getattr(parse_planner({}), table))
    field = cls.__dataclass_fields__[mode]
    choices = CHOICES[mode]
    assert set(modes) <= set(choices) and field.default in choices
    changed = getattr(cls(), setting) * 2 if setting != "cells_across" else 7
    for choice in choices:
        notes = unused_settings(parse_planner({"kind": table, table: {setting: changed, mode: choice}}))
        if choice in modes:
            assert notes == []
        else:
            assert len(notes) == 1 and notes[0].startswith(f"[planner.{table}].{setting} = ")
            assert f"the table has {mode} = {choice!r}" in notes[0]
    assert unused_settings(parse_planner({"kind": "dp", table: {setting: changed, mode: choices[-1]}})) == []
    if mode == "engine":
        notes = unused_settings(parse_planner({"kind": "mcts", "mcts": {setting: changed, "graph": True}}))
        assert len(notes) == 1 and notes[0].endswith("(the table has graph = true)")


def test_seed_without_monte_carlo_is_refused(tmp_path, capsys):
    """--seed (default 0) was silently ignored without --monte-carlo, as --kappa and the others were before."""
    path = scenario_file(tmp_path)
    missing = str(tmp_path / "none.gpx")
    code, out, err = run(["evaluate", str(path), missing, "--seed", "3"], capsys)
    assert (code, out) == (2, "")
    assert err.strip() == (
        "pyroute-rel: error: --seed set the Monte-Carlo runs: add --monte-carlo N (or leave them out)"
    )
    code, out, err = run(["evaluate", str(path), missing, "--kappa", "0.1", "--seed", "3"], capsys)
    assert code == 2 and "--kappa, --seed set the Monte-Carlo runs" in err
    code, out, err = run(["evaluate", str(path), missing, "--monte-carlo", "5", "--seed", "-1"], capsys)
    assert code == 2 and err.strip() == "pyroute-rel: error: --seed must be a whole number >= 0 (got -1)"


def course(**planner: object) -> object:
    return scenario_from_mapping(
        {
            "route": {"start": [-12.0, 45.0], "finish": [-13.0, 44.0]},
            "grid": {"layout": "square", "n_ranks": 5, "n_nodes": 7},
            "weather": {"kind": "uniform", "tws_kn": 15.0, "twd_deg": 0.0},
            "avoid": {"land": False},
            "planner": planner,
        }
    )


@pytest.mark.slow
@pytest.mark.parametrize(("table", "setting", "mode", "modes"), MODE_SETTINGS)
def test_a_setting_noted_as_unused_does_not_change_the_track(table, setting, mode, modes):
    """What the note says is true: in a mode that does not use it, the setting changed gives the same track."""
    other = next(c for c in CHOICES[mode] if c not in modes)
    base = {"mcts": {"iterations": 5, "step_h": 6.0, "rollout_h": 12.0}, "qlearning": {"episodes": 200}}[table]
    default = getattr(parse_planner({}), table).__dataclass_fields__[setting].default
    changed = 7 if setting == "cells_across" else default * 2
    a = course(kind=table, **{table: {**base, mode: other}})
    b = course(kind=table, **{table: {**base, mode: other, setting: changed}})
    assert unused_settings(a.planner) == [] and len(unused_settings(b.planner)) == 1
    ta, tb = plan(a), plan(b)
    for name in ("lon_deg", "lat_deg", "elapsed_h"):
        assert getattr(ta, name).tolist() == getattr(tb, name).tolist()
