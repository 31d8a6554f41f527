"""Evaluating a track of a boat whose tacks and gybes cost time (issues 19 and 21): the evaluator charges each
manoeuvre as the router does, so re-timing a routed track gives the route's own figures, in steady and in
time-varying weather; Monte Carlo without noise equals it; every member's sailing equals sailing it alone."""

from __future__ import annotations

import io
import json
from pathlib import Path

import numpy as np
import pytest
from test_evaluate import write_ensemble_scenario

from pyroute_rel import load_scenario
from pyroute_rel.analysis.evaluate import evaluate_track, evaluation_problem, sail_in_members, sail_tracks
from pyroute_rel.analysis.members import member_scenario
from pyroute_rel.analysis.monte_carlo import MonteCarloSettings, monte_carlo
from pyroute_rel.boat.manoeuvre import GYBE, TACK, charge_manoeuvres, track_manoeuvres
from pyroute_rel.cli import main

ROOT = Path(__file__).resolve().parents[1]
# Tagliaferri-style tables [tws_kn, s]; large ones in the time-varying case, so that a missed penalty shows
PENALTIES = "\ntack_penalty_s = [[9.72, {0}], [19.44, {1}]]\ngybe_penalty_s = [[9.72, {0}], [19.44, {1}]]\n"


@pytest.fixture(scope="module")
def beat(tmp_path_factory: pytest.TempPathFactory):
    """The beat example (steady wind from 250 deg, penalties of 20-30 s) on a coarse grid: its route tacks."""
    folder = tmp_path_factory.mktemp("beat")
    text = (ROOT / "examples" / "microtransat_beat.toml").read_text().replace("n_ranks = 160", "n_ranks = 30")
    (folder / "beat.toml").write_text(text)
    sc = load_scenario(folder / "beat.toml")
    return sc, sc.route()


@pytest.fixture(scope="module")
def members(tmp_path_factory: pytest.TempPathFactory):
    """A 3-member time-varying ensemble and a boat losing 1500-2500 s per manoeuvre."""
    folder = tmp_path_factory.mktemp("ens")
    path = write_ensemble_scenario(folder, n_members=3, spread=2.0)
    text = path.read_text().replace("[grid]", "[boat]\npolar = \"maribot_vane\"" + PENALTIES.format(2500.0, 1500.0)
                                    + "[grid]")  # fmt: skip
    path.write_text(text)
    return path


def test_retiming_a_steady_route_charges_its_tacks(beat) -> None:
    sc, route = beat
    assert route.manoeuvres.tacks > 0 and route.manoeuvres.penalty_h.sum() > 0.0
    ev = evaluate_track(sc, np.column_stack([route.lon_deg, route.lat_deg]))
    assert ev.voyage_time_h == route.voyage_time_h
    np.testing.assert_array_equal(ev.elapsed_h, route.elapsed_h)
    np.testing.assert_array_equal(ev.manoeuvres.kind, route.manoeuvres.kind)
    np.testing.assert_array_equal(ev.manoeuvres.penalty_h, route.manoeuvres.penalty_h)
    # closed form: in steady weather a leg's time does not depend on when it is sailed, so the voyage is the legs'
    # sailing times plus one penalty per tack (30 s at 9.72 kn, 20 s at 19.44 kn, linear between: 15 kn -> 24.34 s)
    tack_s = np.interp(15.0, [9.72, 19.44], [30.0, 20.0])
    expected = ev.legs.time_h.sum() + ev.manoeuvres.tacks * tack_s / 3600.0
    assert ev.voyage_time_h == pytest.approx(expected, rel=1e-12)
    man = ev.summary()["manoeuvres"]
    assert (man["tacks"], man["gybes"]) == (route.manoeuvres.tacks, 0)
    assert man["penalty_h"] == pytest.approx(ev.manoeuvres.tacks * tack_s / 3600.0, rel=1e-12)


@pytest.mark.slow
def test_retiming_in_time_varying_weather_charges_each_manoeuvre(members: Path) -> None:
    for k in range(3):
        sc = member_scenario(members, k)
        route = sc.route()
        ev = evaluate_track(sc, np.column_stack([route.lon_deg, route.lat_deg]))
        assert ev.voyage_time_h == route.voyage_time_h, k
        np.testing.assert_array_equal(ev.manoeuvres.kind, route.manoeuvres.kind)
        np.testing.assert_array_equal(ev.manoeuvres.penalty_h, route.manoeuvres.penalty_h)
    assert route.manoeuvres.tacks + route.manoeuvres.gybes > 0  # the case charges something


@pytest.mark.slow
def test_the_side_of_each_leg_is_the_wind_at_its_departure(members: Path) -> None:
    """Independent of the evaluator's bookkeeping: the side of each leg from the wind sampled at the leg's first
    point at the time the evaluator says the craft leaves it; a manoeuvre wherever it changes."""
    sc = member_scenario(members, 1)
    route = sc.route()
    ev = evaluate_track(sc, np.column_stack([route.lon_deg, route.lat_deg]))
    problem = evaluation_problem(sc)
    from pyroute_rel.boat.manoeuvre import wind_side
    from pyroute_rel.routing.cost import arc_geometry

    g = arc_geometry(
        route.lon_deg[:-1], route.lat_deg[:-1], route.lon_deg[1:], route.lat_deg[1:], samples=problem.samples
    )
    cond = problem.weather_at(g.lon_deg[:, 0], g.lat_deg[:, 0], ev.elapsed_h[:-1])
    side, twa = wind_side(cond.twd_deg, g.course_deg[:, 0])
    np.testing.assert_array_equal(ev.manoeuvres.side, side)
    changes = np.flatnonzero(side[1:] != side[:-1]) + 1
    np.testing.assert_array_equal(np.flatnonzero(ev.manoeuvres.kind), changes)
    np.testing.assert_array_equal(ev.manoeuvres.kind[changes], np.where(twa[changes] < 90.0, TACK, GYBE))


@pytest.mark.slow
def test_monte_carlo_without_noise_charges_the_same(members: Path, beat) -> None:
    quiet = MonteCarloSettings(sigma0_ms=0.0, growth_ms_per_h=0.0, sigma_max_ms=0.0, kappa=0.0)
    for sc in (member_scenario(members, 2), beat[0]):
        route = sc.route()
        track = np.column_stack([route.lon_deg, route.lat_deg])
        mc = monte_carlo(sc, track, runs=4, seed=1, settings=quiet)
        np.testing.assert_array_equal(mc.voyage_time_h, np.full(4, evaluate_track(sc, track).voyage_time_h))


@pytest.mark.slow
def test_sailing_in_every_member_equals_sailing_in_each(members: Path) -> None:
    scs = [member_scenario(members, k) for k in range(3)]
    tracks = [np.column_stack([r.lon_deg, r.lat_deg]) for r in (sc.route() for sc in scs)]
    problems = [evaluation_problem(sc) for sc in scs]
    together = sail_in_members(problems, tracks)
    for j, p in enumerate(problems):
        alone = sail_tracks(p, tracks)
        for i in range(3):
            np.testing.assert_array_equal(together[j][i].elapsed_h, alone[i].elapsed_h)
            np.testing.assert_array_equal(together[j][i].manoeuvres.penalty_h, alone[i].manoeuvres.penalty_h)
        assert together[j][j].voyage_time_h == scs[j].route().voyage_time_h  # the diagonal of the regret matrix


def test_charge_manoeuvres_is_track_manoeuvres_leg_by_leg() -> None:
    rng = np.random.default_rng(3)
    side = rng.integers(0, 2, 50).astype(np.int8)
    twa, tws = rng.uniform(0, 180, 50), rng.uniform(5, 25, 50)
    from pyroute_rel.boat.manoeuvre import ManoeuvrePenalties

    pen = ManoeuvrePenalties(tack_s=((9.72, 30.0), (19.44, 20.0)), gybe_s=((9.72, 60.0), (19.44, 40.0)))
    whole = track_manoeuvres(side, twa, tws, pen, initial_side=0)
    prev = np.concatenate([[0], side[:-1]])
    kind, p = charge_manoeuvres(side, twa, tws, prev, pen)
    np.testing.assert_array_equal(kind, whole.kind)
    np.testing.assert_array_equal(p, whole.penalty_h)


def test_evaluate_json_reports_the_manoeuvres(beat, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    sc, route = beat
    track = tmp_path / "r.csv"
    track.write_text(
        "lon,lat\n" + "".join(f"{float(a)!r},{float(b)!r}\n" for a, b in zip(route.lon_deg, route.lat_deg, strict=True))
    )
    assert main(["evaluate", str(sc.source), str(track), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["manoeuvres"]["tacks"] == route.manoeuvres.tacks
    assert out["voyage_time_h"] == route.voyage_time_h


def test_evaluation_csv_has_the_route_csv_manoeuvre_columns(beat, tmp_path: Path) -> None:
    """``evaluate --out`` writes the same side / manoeuvre / penalty columns as the route's ``route.csv``."""
    import csv

    from pyroute_rel.outputs import to_csv

    sc, route = beat
    track = tmp_path / "r.csv"
    track.write_text(to_csv(route))
    assert main(["evaluate", str(sc.source), str(track), "--out", str(tmp_path / "e"), "--quiet"]) == 0
    got = list(csv.DictReader(io.StringIO((tmp_path / "e" / "evaluation.csv").read_text())))
    want = list(csv.DictReader(io.StringIO(to_csv(route))))
    assert len(got) == len(want)
    for name in ("leg_side", "leg_manoeuvre", "leg_manoeuvre_h"):
        assert [r[name] for r in got] == [r[name] for r in want], name
    assert sum(r["leg_manoeuvre"] == "tack" for r in got) == route.manoeuvres.tacks > 0
