"""`pyroute-rel gci` (given values and routed studies) and its CI gate."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from pyroute_rel.cli import main
from pyroute_rel.routing.grid import make_grid
from pyroute_rel.routing.solve import forward_dp
from pyroute_rel.scenario import load_scenario

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "microtransat_control.toml"


def run(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    code = main(args)
    out, err = capsys.readouterr()
    return code, out, err


def csv(values) -> str:
    return ",".join(f"{v:.12g}" for v in values)


@pytest.mark.slow
def test_given_values_recover_a_manufactured_order(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    h = np.array([1.0, 2.0, 4.0, 8.0])
    phi = 700.0 + 0.3 * h**2  # phi0 = 700, p = 2
    code, out, err = run(["gci", "--h", csv(h), "--phi", csv(phi), "--json", "--out", str(tmp_path / "g")], capsys)
    assert code == 0, err
    d = json.loads(out)
    assert d["p"] == pytest.approx(2.0, rel=1e-9) and d["phi_ext"] == pytest.approx(700.0, rel=1e-12)
    assert d["convergence"] == "monotonic" and d["method"] == "celik2008"
    # GCI_fine by hand (Celik eq. 7): Fs e_a / (r^p - 1) with r = 2, e_a = |phi1 - phi2| / phi1
    e_a = abs(phi[0] - phi[1]) / phi[0]
    assert d["gci_fine"] == pytest.approx(1.25 * e_a / (2.0**2 - 1.0), rel=1e-9)
    # GCI_32 / (r^p GCI_21) with errors relative to phi2 and phi1: exactly phi1 / phi2 on power-law data
    assert d["asymptotic_ratio"] == pytest.approx(phi[0] / phi[1], rel=1e-9)
    assert sorted(p.name for p in (tmp_path / "g").iterdir()) == ["gci.csv", "gci.json", "gci.png"]
    assert (tmp_path / "g" / "gci.png").read_bytes()[:4] == b"\x89PNG"


def test_gate_exit_codes(capsys: pytest.CaptureFixture[str]) -> None:
    h = [1.0, 2.0, 4.0]
    phi = [700.0 + 0.3 * x**2 for x in h]
    gci = 1.25 * (0.9 / 700.3) / 3.0
    code, _, err = run(["gci", "--h", csv(h), "--phi", csv(phi), "--max-gci", f"{gci * 0.5:.3g}"], capsys)
    assert code == 1 and err.count("\n") == 1 and "gate failed" in err and "exceeds --max-gci" in err
    code, _, _ = run(["gci", "--h", csv(h), "--phi", csv(phi), "--max-gci", f"{gci * 2:.3g}"], capsys)
    assert code == 0
    osc = [700.0, 701.0, 699.5]  # differences change sign: oscillatory
    code, _, err = run(["gci", "--h", csv(h), "--phi", csv(osc), "--max-gci", "1", "--require-asymptotic"], capsys)
    assert code == 1 and "not in the asymptotic range" in err
    code, _, err = run(["gci", "--h", "1,2", "--phi", "3,4"], capsys)
    assert code == 2 and err.count("\n") == 1


def test_routed_square_study_equals_routing_each_grid(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run(
        [
            "gci",
            "study",
            str(EXAMPLE),
            "--n-nodes",
            "9,13,17",
            "--apf",
            "1",
            "--no-land",
            "--failure-model",
            "none",
            "--json",
        ],
        capsys,
    )
    assert code == 0, err
    d = json.loads(out)
    sc = load_scenario(EXAMPLE).with_options(land=False, failure_model="none")
    assert [g["n_nodes"] for g in d["grids"]] == [9, 13, 17]
    for g in d["grids"]:
        grid = make_grid(sc.start, sc.finish, n_ranks=g["n_nodes"], n_nodes=g["n_nodes"])
        assert g["h_km"] == pytest.approx(grid.spacing_km)
        assert g["voyage_time_h"] == pytest.approx(forward_dp(grid, sc.problem(grid=grid)).finish_h, rel=1e-12)


@pytest.mark.slow
def test_angular_refinement_converges_where_the_square_grid_does_not(capsys: pytest.CaptureFixture[str]) -> None:
    """Issue acceptance: on the example at apf 0.5 the angular path is monotonic with GCI_fine < 1 %, while the
    paper's square grids stay > 5 % above its extrapolated value (they cannot turn by less than 45 deg)."""
    code, out, err = run(
        [
            "gci",
            "study",
            str(EXAMPLE),
            "--refinement",
            "angular",
            "--n-ranks",
            "41,81,161",
            "--aspect0",
            "4",
            "--max-deviation",
            "60",
            "--half-width-km",
            "1000",
            "--apf",
            "0.5",
            "--no-land",
            "--json",
            "--max-gci",
            "0.01",
            "--require-asymptotic",
        ],
        capsys,
    )
    assert code == 0, err
    d = json.loads(out)
    assert d["convergence"] == "monotonic" and d["gci_fine"] < 0.01
    spacing = [g["spacing_km"] / g["rank_spacing_km"] for g in d["grids"]]
    assert spacing[0] > spacing[1] > spacing[2]  # lateral spacing shrinks faster than the rank spacing
    code, out, _ = run(
        ["gci", "study", str(EXAMPLE), "--n-nodes", "41,57,81", "--apf", "0.5", "--no-land", "--json"], capsys
    )
    square = json.loads(out)
    assert all(g["voyage_time_h"] > 1.05 * d["phi_ext"] for g in square["grids"])


# --------------------------------------------------------------------------------------------------
# user mistakes: one line on stderr naming the option, exit 2, no partial output
# --------------------------------------------------------------------------------------------------

SCENARIO = """
[route]
{route}
departure = "2018-06-01T00:00:00Z"

[grid]
n_ranks = 30

[boat]
polar = "maribot_vane"

[weather]
kind = "uniform"
tws_kn = 15.0
twd_deg = 0.0
hs_m = 1.0
wave_dir_deg = 0.0

[failure]
model = "dickson2018"
apf = 1.0
"""
POINTS = "start = [-20.0, 40.0]\nfinish = [-30.0, 35.0]"
LINES = "start_line = [[-20.0, 39.0], [-20.0, 41.0]]\nfinish_line = [[-30.0, 34.0], [-30.0, 36.0]]"


def scenario_file(tmp_path: Path, route: str = POINTS, name: str = "sc.toml") -> str:
    path = tmp_path / name
    path.write_text(SCENARIO.format(route=route), encoding="utf-8")
    return str(path)


def assert_user_error(code: int, err: str, *needles: str) -> None:
    assert code == 2, err
    assert err.count("\n") == 1 and err.startswith("pyroute-rel: error: "), err
    assert "internal error" not in err and "Traceback" not in err
    for needle in needles:
        assert needle in err, (needle, err)


@pytest.mark.parametrize(
    ("options", "needles"),
    [
        (["--refinement", "angular", "--n-ranks", "0,11,21"], ["--n-ranks", "whole numbers >= 1", "got 0"]),
        (["--refinement", "angular", "--n-ranks", "5,-11,21"], ["--n-ranks", "got -11"]),
        (["--n-nodes", "0,11,21"], ["--n-nodes", "whole numbers >= 1", "got 0"]),
        (["--n-nodes", "5,7,9", "--n-ranks", "5,0,9"], ["--n-ranks", "got 0"]),
    ],
)
def test_study_refuses_counts_below_one(
    options: list[str], needles: list[str], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """QA 1: --n-ranks 0 was a ZeroDivisionError (exit 3); --n-nodes 0 was reported as 'n_ranks'."""
    code, out, err = run(["gci", "study", scenario_file(tmp_path), *options, "--no-land"], capsys)
    assert_user_error(code, err, *needles)
    assert out == ""


@pytest.mark.slow
def test_study_routes_from_the_start_line_to_the_finish_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """QA 2: the study routed point to point, ignoring [route].start_line / finish_line; each of its grids must give
    the voyage time `pyroute-rel route` gives on the same grid."""
    sc = scenario_file(tmp_path, LINES)
    code, out, err = run(["gci", "study", sc, "--n-nodes", "5,7,9", "--no-land", "--json"], capsys)
    assert code == 0, err
    square = json.loads(out)["grids"]
    code, out, err = run(
        ["route", sc, "--layout", "square", "--n-nodes", "9", "--n-ranks", "9", "--no-land", "--json", "--quiet"],
        capsys,
    )
    assert code == 0, err
    assert square[-1]["voyage_time_h"] == pytest.approx(json.loads(out)["voyage_time_h"], rel=1e-12)
    # the lines matter: point to point (the old behaviour) is slower on this course by more than 1 h
    points = load_scenario(sc).with_options(land=False)
    grid = make_grid(points.start, points.finish, n_ranks=9, n_nodes=9)
    assert forward_dp(grid, points.problem(grid=grid)).finish_h > square[-1]["voyage_time_h"] + 1.0
    # the angular path too: its finest grid against `route` with the same ranks, spacing, band and half-width
    code, out, err = run(
        [
            "gci",
            "study",
            sc,
            "--refinement",
            "angular",
            "--n-ranks",
            "5,9,17",
            "--aspect0",
            "2",
            "--half-width-km",
            "200",
            "--max-deviation",
            "60",
            "--no-land",
            "--json",
        ],
        capsys,
    )
    assert code == 0, err
    fin = json.loads(out)["grids"][-1]
    code, out, err = run(
        [
            "route",
            sc,
            "--n-ranks",
            "17",
            "--spacing-km",
            repr(fin["spacing_km"]),
            "--max-deviation",
            "60",
            "--half-width-km",
            "200",
            "--no-land",
            "--json",
            "--quiet",
        ],
        capsys,
    )
    assert code == 0, err
    assert fin["voyage_time_h"] == pytest.approx(json.loads(out)["voyage_time_h"], rel=1e-12)


def test_study_refuses_waypoints_and_a_start_on_land(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """QA 2: waypoints were silently ignored; a start on land gave 'no feasible route'."""
    wp = scenario_file(tmp_path, POINTS + "\nwaypoints = [[-22.0, 36.0], [-27.0, 38.0]]", "wp.toml")
    code, out, err = run(["gci", "study", wp, "--n-nodes", "5,7,9"], capsys)
    assert_user_error(code, err, "[route].waypoints", "gci study does not support", "each leg")
    land = scenario_file(tmp_path, "start = [-8.0, 40.0]\nfinish = [-30.0, 35.0]", "land.toml")  # inland Portugal
    code, out, err = run(["gci", "study", land, "--n-nodes", "5,7,9"], capsys)
    assert_user_error(code, err, "[route].start", "on land")
    assert "no feasible route" not in err


@pytest.mark.parametrize(
    ("options", "needles"),
    [
        (["--aspect0", "-1"], ["--aspect0", "> 0", "got -1.0"]),
        (["--aspect0", "0"], ["--aspect0", "> 0"]),
        (["--half-width-km", "-1"], ["--half-width-km", "> 0", "got -1.0"]),
        (["--half-width-km", "nan"], ["--half-width-km", "> 0"]),
        (["--max-deviation", "95"], ["--max-deviation", "(0, 90)"]),
        (["--n-nodes", "9,11,13"], ["--n-nodes", "only applies to --refinement square"]),
    ],
)
def test_study_validates_the_angular_options(
    options: list[str], needles: list[str], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """QA 3: --aspect0 -1 was reported as 'n_nodes ... (got -25)', --half-width-km -1 was accepted and --n-nodes
    silently ignored."""
    code, _, err = run(
        [
            "gci",
            "study",
            scenario_file(tmp_path),
            "--refinement",
            "angular",
            "--n-ranks",
            "5,9,17",
            *options,
            "--no-land",
        ],
        capsys,
    )
    assert_user_error(code, err, *needles)


@pytest.mark.parametrize("option", [["--aspect0", "4"], ["--half-width-km", "500"], ["--max-deviation", "45"]])
def test_study_refuses_angular_options_on_square_grids(
    option: list[str], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, _, err = run(["gci", "study", scenario_file(tmp_path), "--n-nodes", "5,7,9", *option, "--no-land"], capsys)
    assert_user_error(code, err, option[0], "only apply to --refinement angular")


@pytest.mark.parametrize("h_option", [["--h", "-1,2,4"], ["--h=-1,2,4"], ["--h", "-1e-3,2,4"]])
def test_negative_spacings_reach_the_validation(h_option: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    """QA 4: '--h -1,2,4' was 'argument --h: expected one argument' (argparse read it as an option)."""
    code, _, err = run(["gci", *h_option, "--phi", "1,2,3"], capsys)
    assert_user_error(code, err, "--h (grid spacings) must be finite and > 0", "value 1 of 3")


@pytest.mark.parametrize(
    ("option", "needle"),
    [
        (["--max-gci", "-1"], "--max-gci must be a fraction in (0, 1]"),
        (["--max-gci", "-1e-3"], "--max-gci must be a fraction in (0, 1]"),
        (["--max-gci", "inf"], "--max-gci must be a fraction in (0, 1]"),
        (["--max-gci", "0"], "--max-gci must be a fraction in (0, 1]"),
        (["--max-gci", "-1%"], "--max-gci must be a fraction in (0, 1]"),
        (["--max-gci", "150%"], "or a percent in (0, 100]"),
        (["--max-gci", "1%%"], "--max-gci must be a fraction such as 0.015 or a percent such as 1.5%"),
        (["--max-gci", "1.5"], "--max-gci 1.5 is above 1 (a bare number is a fraction): write 0.015 or 1.5%"),
        (["--max-gci", "2"], "--max-gci 2 is above 1 (a bare number is a fraction): write 0.02 or 2%"),
        (["--asymptotic-tol", "-1"], "--asymptotic-tol must be a finite number >= 0"),
        (["--safety-factor", "0"], "--safety-factor must be a finite number > 0"),
    ],
)
def test_gate_thresholds_are_validated(
    option: list[str], needle: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """QA 5: a negative --max-gci or --asymptotic-tol was accepted and the gate then always failed (exit 1)."""
    code, _, err = run(["gci", "--h", "1,2,4", "--phi", "700.3,701.2,704.8", *option], capsys)
    assert_user_error(code, err, needle)
    # the study refuses them before routing anything
    code, _, err = run(["gci", "study", scenario_file(tmp_path), "--n-nodes", "5,7,9", *option], capsys)
    assert_user_error(code, err, needle)


def test_require_asymptotic_is_a_gate_on_its_own(capsys: pytest.CaptureFixture[str]) -> None:
    """QA 5: --require-asymptotic without --max-gci must still gate."""
    h = [1.0, 2.0, 4.0]
    mono = [700.0 + 0.3 * x**2 for x in h]  # monotonic, asymptotic ratio phi1/phi2 = 0.9987
    code, out, err = run(["gci", "--h", csv(h), "--phi", csv(mono), "--require-asymptotic", "--json"], capsys)
    assert code == 0, err
    assert json.loads(out)["gate"] == {
        "max_gci": None,
        "require_asymptotic": True,
        "asymptotic_tol": 0.1,
        "passed": True,
        "reason": None,
    }
    osc = [700.0, 701.0, 699.5]
    code, out, err = run(["gci", "--h", csv(h), "--phi", csv(osc), "--require-asymptotic", "--json"], capsys)
    assert code == 1 and err.count("\n") == 1 and "not in the asymptotic range" in err
    assert json.loads(out)["gate"]["passed"] is False
    # a tolerance of 0 lets only an exact ratio of 1 through
    code, _, err = run(
        ["gci", "--h", csv(h), "--phi", csv(mono), "--require-asymptotic", "--asymptotic-tol", "0"], capsys
    )
    assert code == 1 and "|ratio - 1| <= 0" in err


def test_gate_options_before_study_are_not_dropped(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """'gci --max-gci F study ...' used to lose F (the subparser's default overwrote it) and pass."""
    sc = scenario_file(tmp_path)
    code, _, err = run(["gci", "--max-gci", "1e-9", "study", sc, "--n-nodes", "5,7,9", "--no-land"], capsys)
    # p = 2.5e-7 on these tiny grids: indeterminate, so the gate names itself with its F
    assert code == 1 and "--max-gci 1e-09" in err
    code, _, err = run(["gci", "--h", "1,2,4", "study", sc, "--n-nodes", "5,7,9", "--no-land"], capsys)
    assert_user_error(code, err, "--h and --phi")


@pytest.mark.parametrize(
    ("h", "phi", "needles"),
    [
        ("1,2", "1,2", ["--h and --phi need at least 3 values each", "got 2"]),
        ("1,2,4", "1,2", ["--h and --phi must have the same length", "got 3 and 2"]),
        ("1,0,4", "1,2,3", ["--h (grid spacings) must be finite and > 0", "got 0.0 at value 2 of 3"]),
        ("1,2,2", "1,2,3", ["--h values must be distinct"]),
        ("1,2,4", "1,nan,3", ["--phi must be finite", "got nan at value 2 of 3"]),
        ("1,2,4", "1e308,-1e308,1", ["--phi differences overflow"]),
    ],
)
def test_given_value_errors_name_the_options(
    h: str, phi: str, needles: list[str], capsys: pytest.CaptureFixture[str]
) -> None:
    """QA 6: messages were prefixed 'convergence_study:' / 'grid_convergence:' instead of naming --h / --phi."""
    code, _, err = run(["gci", "--h", h, "--phi", phi], capsys)
    assert_user_error(code, err, *needles)
    assert "convergence_study" not in err and "grid_convergence" not in err and "'h'" not in err


def test_out_that_is_a_file_fails_before_any_work(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """QA 7: --out naming a file (or a folder under a file) was FileExistsError / NotADirectoryError, exit 3, and
    the study found out only after routing every grid."""
    import pyroute_rel.gci.study

    a_file = tmp_path / "a_file"
    a_file.write_text("keep me", encoding="utf-8")
    code, out, err = run(["gci", "--h", "1,2,4", "--phi", "700.3,701.2,704.8", "--out", str(a_file)], capsys)
    assert_user_error(code, err, "--out", "is a file, not a folder")
    assert out == "" and a_file.read_text(encoding="utf-8") == "keep me"

    def no_routing(*args: object, **kwargs: object) -> None:
        raise AssertionError("routed before checking --out")

    monkeypatch.setattr(pyroute_rel.gci.study, "forward_dp", no_routing)
    code, out, err = run(
        ["gci", "study", scenario_file(tmp_path), "--n-nodes", "5,7,9", "--no-land", "--out", str(a_file / "sub")],
        capsys,
    )
    assert_user_error(code, err, "--out", "is a file, not a folder")
    assert out == "" and a_file.read_text(encoding="utf-8") == "keep me"


def test_a_failed_write_is_an_output_error_and_leaves_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """QA 7: an OSError while writing the outputs is a one-line OutputError (exit 2), with no partial file set."""
    import errno

    import pyroute_rel.viz.convergence

    real_plot = pyroute_rel.viz.convergence.plot_convergence

    def full_disk(*args: object, **kwargs: object) -> None:
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(pyroute_rel.viz.convergence, "plot_convergence", full_disk)
    args = ["gci", "--h", "1,2,4", "--phi", "700.3,701.2,704.8"]
    code, _, err = run([*args, "--out", str(tmp_path / "new")], capsys)
    assert_user_error(code, err, "--out", "No space left on device")
    assert not (tmp_path / "new").exists()  # the folder it created is removed again
    (tmp_path / "old").mkdir()
    code, _, err = run([*args, "--out", str(tmp_path / "old")], capsys)
    assert_user_error(code, err, "--out")
    assert list((tmp_path / "old").iterdir()) == []  # no gci.csv / gci.json without gci.png, no staging folder
    monkeypatch.setattr(pyroute_rel.viz.convergence, "plot_convergence", real_plot)
    code, _, err = run([*args, "--out", str(tmp_path / "old")], capsys)
    assert code == 0, err
    assert sorted(p.name for p in (tmp_path / "old").iterdir()) == ["gci.csv", "gci.json", "gci.png"]


def test_study_says_it_does_not_refine(tmp_path, capsys) -> None:
    from pyroute_rel.cli import main

    src = Path(__file__).resolve().parents[1] / "examples" / "microtransat_control.toml"
    path = tmp_path / "r.toml"
    path.write_text(src.read_text().replace("[grid]", "[grid]\nrefine = 2", 1))
    assert main(["gci", "study", str(path), "--n-nodes", "11,15,21", "--no-land", "--json"]) == 0
    assert "[grid].refine = 2 is not applied" in capsys.readouterr().err


def test_max_gci_takes_a_fraction_or_a_percent(capsys: pytest.CaptureFixture[str]) -> None:
    """Issue 15: '--max-gci 1.5' was read as 150 % and passed silently; '1.5%' and '0.015' are the same gate."""
    h = [1.0, 2.0, 4.0]
    phi = [700.0 + 0.3 * x**2 for x in h]
    gci = 1.25 * (0.9 / 700.3) / 3.0  # 5.4e-4
    for fraction, percent in [(gci * 0.5, gci * 50.0), (gci * 2.0, gci * 200.0)]:
        results = []
        for value in (f"{fraction:.6g}", f"{percent:.6g}%"):
            code, out, _ = run(["gci", "--h", csv(h), "--phi", csv(phi), "--max-gci", value, "--json"], capsys)
            results.append((code, json.loads(out)["gate"]["max_gci"]))
        assert results[0][0] == results[1][0] == (1 if fraction < gci else 0)
        assert results[1][1] == pytest.approx(results[0][1], rel=1e-12)
    code, _, err = run(["gci", "--h", csv(h), "--phi", csv(phi), "--max-gci", f"{gci * 50:.3g}%"], capsys)
    assert code == 1 and f"exceeds --max-gci {gci * 0.5:.3g} ({gci * 50:.3g} %)" in err


@pytest.mark.slow
@pytest.mark.parametrize("study", [False, True])
def test_gci_json_in_out_holds_the_gate_as_printed(
    study: bool, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Issue 15: 'gci --out' wrote gci.json without the 'gate' object that --json prints; now the two agree."""
    if study:
        args = ["gci", "study", scenario_file(tmp_path), "--n-nodes", "5,7,9", "--no-land"]
    else:
        args = ["gci", "--h", "1,2,4", "--phi", "700.3,701.2,704.8"]
    out = tmp_path / "g"
    gate = ["--max-gci", "1e-9", "--require-asymptotic", "--asymptotic-tol", "0.2"]
    code, printed, err = run([*args, *gate, "--json", "--out", str(out)], capsys)
    assert code == 1 and "gate failed" in err
    written = json.loads((out / "gci.json").read_text())
    assert written == json.loads(printed)
    assert written["gate"]["max_gci"] == 1e-9 and written["gate"]["asymptotic_tol"] == 0.2
    assert written["gate"]["require_asymptotic"] is True and written["gate"]["passed"] is False
    # the 5,7,9 study is indeterminate (p = 2.5e-7): the gate fails naming itself; the given values converge
    expected = "the gate (--max-gci 1e-09, --require-asymptotic)" if study else "exceeds --max-gci 1e-09"
    assert expected in written["gate"]["reason"]
    assert written["verdict"] == ("indeterminate" if study else "converging")


def test_bad_max_gci_leaves_nothing_in_out(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "g"
    code, _, err = run(
        ["gci", "--h", "1,2,4", "--phi", "700.3,701.2,704.8", "--max-gci", "1.5", "--out", str(out)], capsys
    )
    assert_user_error(code, err, "write 0.015 or 1.5%")
    assert not out.exists()
