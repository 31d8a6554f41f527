"""Results that do not arrive never look like success (issue 35, item 3), and advice that works (item 5).

Every command that plans, sails or sweeps exits with the no-route code (2) and one line saying why when its result
does not reach the finish; its figures and files are still printed and written, the finish is marked where it is and
no other point is named ``finish``. References: the great-circle distance written out in the test (haversine), the
files read back with the standard library.
"""

from __future__ import annotations

import csv
import json
import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from pyroute_rel.cli import main
from pyroute_rel.units import EARTH_RADIUS_KM, KM_PER_NM

CONTROL = Path(__file__).resolve().parents[1] / "examples" / "microtransat_control.toml"
FINISH = (-60.0, 17.5)  # the control course's [route].finish


def haversine_nm(lon1: float, lat1: float, lon2: float, lat2: float) -> float:
    """Great-circle distance [nm] on the sphere of the project's radius (written out, not the project's code)."""
    p1, p2, dl = math.radians(lat1), math.radians(lat2), math.radians(lon2 - lon1)
    h = math.sin((p2 - p1) / 2) ** 2 + math.cos(p1) * math.cos(p2) * math.sin(dl / 2) ** 2
    return 2.0 * EARTH_RADIUS_KM * math.asin(math.sqrt(h)) / KM_PER_NM


def _errors(err: str) -> list[str]:
    return [line for line in err.splitlines() if line.startswith("pyroute-rel: error:")]


def test_a_planner_that_stops_short_exits_with_the_no_route_code(tmp_path, capsys):
    """Q-learning with one episode stops short of the finish: exit 2 and one line saying how far short and what
    searches more; summary.json has no arrival and the distance left; the GPX's last point is ``end``, never
    ``finish``; the map marks the real finish and the track's end."""
    scenario = tmp_path / "s.toml"
    scenario.write_text(
        CONTROL.read_text() + '\n[planner]\nkind = "qlearning"\n[planner.qlearning]\nepisodes = 1\n', encoding="utf-8"
    )
    out = tmp_path / "o"
    assert main(["route", str(scenario), "--n-ranks", "12", "--quiet", "--out", str(out)]) == 2
    captured = capsys.readouterr()
    errors = _errors(captured.err)
    assert len(errors) == 1 and "the qlearning planner did not reach the finish" in errors[0]
    assert "[planner.qlearning] episodes (it ran 1)" in errors[0]
    assert "did NOT reach the finish" in captured.out and "short of the finish" in captured.out

    with open(out / "route.csv", encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    end = float(rows[-1]["lon_deg"]), float(rows[-1]["lat_deg"])
    short = haversine_nm(*end, *FINISH)
    assert short > 100.0  # the case: far from the finish
    summary = json.loads((out / "summary.json").read_text())
    assert summary["arrival"] is None and not summary["reached"] and not summary["feasible"]
    assert summary["distance_to_finish_nm"] == pytest.approx(short, abs=1e-4)  # the CSV's 6 decimals of a degree
    assert f"{short:.0f} nm short" in errors[0]

    names = [el.text for el in ET.parse(out / "route.gpx").iter() if el.tag.endswith("}name")]
    assert "finish" not in names and "end" in names
    geo = json.loads((out / "route.geojson").read_text())
    line = geo["features"][0]["properties"]
    assert line["arrived"] is False and line["arrival"] is None and line["track_end"] == rows[-1]["time_utc"]

    from dataclasses import replace

    from pyroute_rel.cli.planners import _planner_summary
    from pyroute_rel.scenario import load_scenario
    from pyroute_rel.viz.maps import plot_route

    sc = load_scenario(scenario).with_options(n_ranks=12)
    sc = replace(sc, planner=replace(sc.planner, kind="qlearning"))
    route = _planner_summary(sc, "qlearning", progress=False)[2]
    assert route is not None and not route.arrived
    ax = plot_route(route).axes[0]
    marks = {ln.get_gid(): ln.get_xydata()[0] for ln in ax.get_lines() if ln.get_gid() in ("finish", "track end")}
    assert np.allclose(marks["finish"], FINISH) and np.allclose(marks["track end"], end, atol=1e-6)


def _small(tmp_path: Path, hs_m: float = 1.0, patch: bool = True) -> Path:
    """A short course in steady wind; with ``patch`` 4.5 m waves across the great circle, which apf 0.5 forbids."""
    text = (
        '[route]\nstart = [-12.0, 45.0]\nfinish = [-14.0, 43.0]\ndeparture = "2018-06-01T00:00:00Z"\n'
        '[grid]\nlayout = "square"\nn_ranks = 5\nn_nodes = 7\nsamples_per_arc = 4\n'
        f'[weather]\nkind = "uniform"\ntws_kn = 15.0\ntwd_deg = 0.0\nhs_m = {hs_m}\n'
        + ("[[weather.patch]]\nlon = [-13.4, -12.6]\nlat = [43.6, 44.4]\nhs_m = 4.5\n" if patch else "")
        + '[failure]\nmodel = "dickson2018"\napf = 0.5\n[avoid]\nland = false\n'
    )
    path = tmp_path / "small.toml"
    path.write_text(text, encoding="utf-8")
    return path


def test_evaluate_exits_with_the_no_route_code_for_a_track_that_is_not_a_route(tmp_path, capsys):
    """The straight line through the 4.5 m waves at apf 0.5: the figures are printed (JSON) and the exit code is 2
    with one line naming the blocked leg, its p_f and the conditions on it; a track that stops halfway: 2, saying
    how far short (the distance written out); the DP's own route: 0."""
    scenario = _small(tmp_path)
    straight = tmp_path / "straight.csv"
    straight.write_text("lon,lat\n-12,45\n-14,43\n", encoding="utf-8")  # one leg: its exposure is the voyage's
    assert main(["evaluate", str(scenario), str(straight), "--json"]) == 2
    captured = capsys.readouterr()
    printed = json.loads(captured.out)
    assert printed["feasible"] is False and printed["reason"] == "p_f"
    (error,) = _errors(captured.err)
    leg = printed["blocked_leg"]
    p_f = printed["track"][leg + 1]["p_f"]
    assert f"leg {leg} (from track point {leg}" in error and f"p_f {p_f:.3f} > apf 0.5" in error
    hours = printed["exposure_by_criterion_h"]["WH: hs_m >= 4 m"]
    assert hours > 0.0 and f"meeting WH: hs_m >= 4 m for {hours:.2f} h" in error  # the criterion met on the leg

    half = tmp_path / "half.csv"
    half.write_text("lon,lat\n-12,45\n-12.5,44.8\n", encoding="utf-8")
    assert main(["evaluate", str(scenario), str(half), "--json"]) == 2
    captured = capsys.readouterr()
    printed = json.loads(captured.out)
    short = haversine_nm(-12.5, 44.8, -14.0, 43.0)
    assert printed["feasible"] and not printed["arrived"] and printed["arrival"] is None
    assert printed["distance_to_finish_nm"] == pytest.approx(short, rel=1e-9)
    (error,) = _errors(captured.err)
    assert f"ends {short:.1f} nm from the scenario's finish" in error

    out = tmp_path / "dp"
    assert main(["route", str(scenario), "--quiet", "--out", str(out)]) == 0
    capsys.readouterr()
    assert main(["evaluate", str(scenario), str(out / "route.gpx"), "--json"]) == 0
    printed = json.loads(capsys.readouterr().out)
    assert printed["arrived"] and printed["feasible"] and printed["distance_to_finish_nm"] < 1e-3


def test_a_sweep_in_which_no_run_routes_exits_with_the_no_route_code(tmp_path, capsys):
    """4.5 m waves everywhere at apf 0.2 and 0.3: both runs have no route; the table is printed, then exit 2."""
    scenario = _small(tmp_path, hs_m=4.5, patch=False)
    code = main(["sweep", str(scenario), "--apf", "0.2,0.3", "--engine", "inline", "--quiet"])
    captured = capsys.readouterr()
    assert code == 2
    assert "2 runs: 0 routed, 2 without a route" in captured.out
    (error,) = _errors(captured.err)
    assert error.startswith("pyroute-rel: error: no run has a route") and "no feasible route" in error
    code = main(["sweep", str(_small(tmp_path)), "--apf", "0.5", "--engine", "inline", "--quiet"])
    assert code == 0 and "1 runs: 1 routed" in capsys.readouterr().out


def test_the_ensemble_says_how_it_chose_with_the_sign_right():
    """``beats_mean_field_by_h`` is the mean-field route's risk minus the chosen one's: positive, the chosen route is
    better; negative, the mean-field route has the smaller risk but is infeasible in more members."""
    from pyroute_rel.cli.ensemble import _text

    def summary(chosen_h: float, mean_h: float, mean_infeasible: float) -> dict:
        cand = {"arrival_h": dict.fromkeys(("mean", "p5", "p50", "p95", "cvar", "worst"), 1.0), "risk_h": 1.0,
                "p_fail_conditions": 0.0, "infeasible_members": 0.0}  # fmt: skip
        return {
            "members": [{"feasible": True}],
            "candidates": [
                {**cand, "name": "member 0"},
                {**cand, "name": "mean", "arrival_h": {**cand["arrival_h"], "mean": None}},  # type: ignore[dict-item]
            ],
            "chosen": {
                "name": "member 0",
                "risk": "p90",
                "value_h": chosen_h,
                "infeasible_members": 0.0,
                "mean_field_value_h": mean_h,
                "mean_field_infeasible_members": mean_infeasible,
                "beats_mean_field_by_h": mean_h - chosen_h,
            },  # fmt: skip
        }

    better = _text(summary(225.4, 231.5, 0.0))
    assert "feasibility first" in better and "the chosen route's p90 is 6.1 h less" in better
    worse = _text(summary(231.5, 225.4, 0.2))
    assert "its p90 is 6.1 h less, but it is infeasible in more members" in worse
    assert "faster" not in worse and "beaten" not in worse
    assert "-: infinite" in worse  # the mean candidate's "-" entries are explained


@pytest.mark.parametrize("layout", ["angular", "square"])
def test_the_grid_edge_advice_names_the_option_and_following_it_routes_faster(layout, tmp_path, capsys):
    """Dead upwind on a grid too narrow to tack: the route uses the outermost nodes; the warning names the option
    that widens the grid in use, with a value; routing again with it gives a faster route."""
    path = tmp_path / "beat.toml"
    grid = "half_width_km = 15.0\naspect = 1.0" if layout == "angular" else "n_nodes = 5\nspacing_km = 8.0"
    path.write_text(
        '[route]\nstart = [-12.0, 45.0]\nfinish = [-15.0, 45.0]\ndeparture = "2018-06-01T00:00:00Z"\n'
        f'[grid]\nlayout = "{layout}"\nn_ranks = 8\n{grid}\n'
        '[weather]\nkind = "uniform"\ntws_kn = 15.0\ntwd_deg = 270.0\n[avoid]\nland = false\n',
        encoding="utf-8",
    )
    assert main(["route", str(path), "--quiet", "--json"]) == 0
    captured = capsys.readouterr()
    before = json.loads(captured.out)["voyage_time_h"]
    (warning,) = [ln for ln in captured.err.splitlines() if "outermost nodes" in ln]
    option, value = warning.split("e.g. ")[1].split()
    assert option == ("--half-width-km" if layout == "angular" else "--n-nodes")
    assert main(["route", str(path), "--quiet", "--json", option, value]) == 0
    after = json.loads(capsys.readouterr().out)["voyage_time_h"]
    assert after < before


def test_a_track_that_crosses_the_finish_line_arrives(tmp_path, capsys):
    """A GPS log that keeps recording after crossing the finish line ends beyond it: it arrived (exit 0); one that
    stops before the line does not (a review found the first called "short")."""
    path = tmp_path / "line.toml"
    path.write_text(
        "[route]\nstart = [-12.0, 45.0]\nfinish_line = [[-14.0, 42.0], [-14.0, 44.0]]\n"
        'departure = "2018-06-01T00:00:00Z"\n[grid]\nn_ranks = 5\n'
        '[weather]\nkind = "uniform"\ntws_kn = 15.0\ntwd_deg = 0.0\n[avoid]\nland = false\n',
        encoding="utf-8",
    )
    beyond, before = tmp_path / "beyond.csv", tmp_path / "before.csv"
    beyond.write_text("lon,lat\n-12,45\n-13,44.2\n-14.5,43\n", encoding="utf-8")
    before.write_text("lon,lat\n-12,45\n-13,44.2\n-13.5,43.6\n", encoding="utf-8")
    assert main(["evaluate", str(path), str(beyond), "--json"]) == 0
    printed = json.loads(capsys.readouterr().out)
    assert printed["arrived"] and printed["distance_to_finish_nm"] == 0.0
    assert main(["evaluate", str(path), str(before), "--json"]) == 2
    assert not json.loads(capsys.readouterr().out)["arrived"]
