"""Ensemble routing and Monte Carlo (issue 19): member routes are `route` with `[weather] member = k`, the regret
matrix recomputes with `evaluate`, risk measures match their definitions, Monte Carlo reduces to the deterministic
evaluation without noise and converges at the 1/sqrt(N) rate."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.stats import binomtest
from test_evaluate import TABLE, write_ensemble_scenario

from pyroute_rel import load_scenario, scenario_from_mapping
from pyroute_rel.analysis.ensemble import arrival_stats, cvar, empirical_quantile, parse_risk, route_ensemble
from pyroute_rel.analysis.evaluate import evaluate_track
from pyroute_rel.analysis.monte_carlo import MonteCarloSettings, monte_carlo, wilson_interval
from pyroute_rel.cli import main
from pyroute_rel.errors import ScenarioError


@pytest.fixture(scope="module")
def ensemble(tmp_path_factory: pytest.TempPathFactory):
    folder = tmp_path_factory.mktemp("ens")
    path = write_ensemble_scenario(folder, n_members=4)
    return path, route_ensemble(path, workers=1, risk="cvar:0.75")


def _member_toml(path: Path, k: int) -> Path:
    text = path.read_text().replace('kind = "file"\n', f'kind = "file"\nmember = {k}\n')
    out = path.with_name(f"member{k}.toml")
    out.write_text(text)
    return out


@pytest.mark.slow
def test_each_member_route_is_route_with_that_member(ensemble):
    path, res = ensemble
    assert res.members == (0, 1, 2, 3) and all(r.ok for r in res.routes)
    for k, r in zip(res.members, res.routes, strict=True):
        ref = load_scenario(_member_toml(path, k)).route()
        assert r.voyage_time_h == ref.voyage_time_h
        assert np.array_equal(r.lon_deg, ref.lon_deg) and np.array_equal(r.lat_deg, ref.lat_deg)
    assert len({round(r.voyage_time_h, 6) for r in res.routes}) > 1  # the members differ


@pytest.mark.slow
def test_regret_diagonal_is_zero_and_entries_recompute_with_evaluate(ensemble):
    path, res = ensemble
    regret = res.regret_h
    for i, src in enumerate(res.sources):
        for j, m in enumerate(res.members):
            ev = evaluate_track(path, res.tracks[i], member=m)
            assert res.time_h[i, j] == pytest.approx(ev.voyage_time_h, rel=1e-12)
            assert bool(res.feasible[i, j]) == ev.feasible
            expect = ev.voyage_time_h - res.routes[j].voyage_time_h if ev.feasible else math.nan
            assert regret[i, j] == pytest.approx(expect, abs=1e-9, nan_ok=True)
            if src == m:
                assert abs(regret[i, j]) < 1e-9
    s = res.summary()
    assert s["regret_h"] == [[None if math.isnan(v) else v for v in row] for row in regret.tolist()]


@pytest.mark.slow
def test_json_contract_and_the_choice(ensemble):
    path, res = ensemble
    s = json.loads(json.dumps(res.summary()))
    assert [m["member"] for m in s["members"]] == [0, 1, 2, 3]
    assert {"member", "voyage_time_h", "feasible"} <= set(s["members"][0])
    names = [c["name"] for c in s["candidates"]]
    assert names == ["member 0", "member 1", "member 2", "member 3", "mean"]
    for c, times, feasible, over in zip(s["candidates"], res.time_h, res.feasible, res.p_fail, strict=True):
        assert set(c["arrival_h"]) == {"mean", "p5", "p50", "p95", "cvar", "worst"}
        assert c["p_fail_conditions"] == pytest.approx(over.mean())
        assert c["infeasible_members"] == pytest.approx(1.0 - feasible.mean())
        t = np.sort(times)
        assert c["arrival_h"]["worst"] == (t[-1] if np.isfinite(t[-1]) else None)
    ch = s["chosen"]
    assert ch["risk"] == "cvar:0.75" and ch["name"] in names
    frac = np.array([c["infeasible_members"] for c in s["candidates"]])
    risk = np.array([np.inf if c["risk_h"] is None else c["risk_h"] for c in s["candidates"]])
    ok = np.flatnonzero(frac == frac.min())
    assert names.index(ch["name"]) == ok[np.argmin(risk[ok])]
    mean = s["candidates"][-1]["risk_h"]
    if mean is not None and ch["value_h"] is not None:
        assert ch["beats_mean_field_by_h"] == pytest.approx(mean - ch["value_h"])


@pytest.mark.slow
def test_identical_members_have_no_spread_and_choose_the_deterministic_route(tmp_path: Path):
    path = write_ensemble_scenario(tmp_path, n_members=3, spread=0.0)
    res = route_ensemble(path, workers=1, risk="worst")
    for times in res.time_h:
        assert np.ptp(times) == 0.0
    det = load_scenario(_member_toml(path, 0)).route()
    chosen = res.tracks[res.chosen]
    np.testing.assert_allclose(chosen[:, 0], det.lon_deg, atol=1e-9)
    np.testing.assert_allclose(chosen[:, 1], det.lat_deg, atol=1e-9)
    assert res.risk_values[res.chosen] == pytest.approx(det.voyage_time_h, rel=1e-12)


@pytest.mark.slow
def test_member_selection_and_bad_options(ensemble):
    path, _ = ensemble
    with pytest.raises(ScenarioError, match=r"in \[0, 3\]"):
        route_ensemble(path, members=[0, 7], workers=1)
    with pytest.raises(ScenarioError, match="--risk must be"):
        parse_risk("p100")
    with pytest.raises(ScenarioError, match="ensemble needs"):
        route_ensemble(_uniform_file(path.parent), workers=1)


def _uniform_file(folder: Path) -> Path:
    p = folder / "uniform.toml"
    p.write_text('[route]\nstart = [-12.0, 45.0]\nfinish = [-20.0, 40.0]\n[weather]\nkind = "uniform"\ntws_kn = 15.0\n'
                 "twd_deg = 0.0\n")  # fmt: skip
    return p


@pytest.mark.slow
def test_members_in_processes_are_the_same(ensemble):
    path, res = ensemble
    two = route_ensemble(path, members=[1, 3], workers=2, mean_field=False)
    assert [r.voyage_time_h for r in two.routes] == [res.routes[1].voyage_time_h, res.routes[3].voyage_time_h]
    assert np.array_equal(two.time_h, res.time_h[[1, 3]][:, [1, 3]])


@pytest.mark.slow
def test_cli_ensemble_json_and_figures(ensemble, tmp_path: Path, capsys: pytest.CaptureFixture[str]):
    path, res = ensemble
    out = tmp_path / "out"
    code = main(["ensemble", str(path), "--members", "0,2", "--workers", "1", "--risk", "p50", "--json", "--out",
                 str(out), "--quiet"])  # fmt: skip
    stdout, err = capsys.readouterr()
    assert code == 0, err
    s = json.loads(stdout)
    assert [m["member"] for m in s["members"]] == [0, 2] and s["chosen"]["risk"] == "p50"
    assert sorted(p.name for p in out.iterdir()) == ["arrival_cdf.png", "ensemble.json", "regret.png", "spaghetti.png"]
    code = main(["ensemble", str(path), "--risk", "median"])
    _, err = capsys.readouterr()
    assert code == 2 and err.count("\n") == 1 and "--risk must be" in err


# --------------------------------------------------------------------------------------------- risk measures


def _ru_cvar(t: np.ndarray, alpha: float) -> float:
    """CVaR by Rockafellar and Uryasev's minimisation, min over c of c + E[(T - c)+] / (1 - alpha): the minimum of a
    convex piecewise-linear function of c, attained at one of the sample values."""
    return min(c + np.mean(np.maximum(t - c, 0.0)) / (1.0 - alpha) for c in t)


@settings(max_examples=100, deadline=None)
@given(
    st.lists(st.floats(0.0, 1e4, allow_nan=False), min_size=1, max_size=40),
    st.floats(0.0, 0.99),
)
def test_risk_measures_match_their_definitions_on_the_sorted_times(times, alpha):
    t = np.array(times)
    s = np.sort(t)
    n = t.size
    assert cvar(t, alpha) == pytest.approx(_ru_cvar(t, alpha), rel=1e-9, abs=1e-9)
    for q in (0.05, 0.5, 0.95, alpha if alpha > 0 else 0.5):
        k = max(math.ceil(q * n - 1e-12), 1)  # the smallest k with k / n >= q
        assert empirical_quantile(t, q) == s[k - 1]
    stats = arrival_stats(t, alpha)
    assert stats["worst"] == s[-1] and stats["mean"] == pytest.approx(s.mean())
    assert stats["p50"] == s[max(math.ceil(0.5 * n - 1e-12), 1) - 1]
    assert parse_risk(f"cvar:{alpha}").of(t) == cvar(t, alpha)
    assert parse_risk("worst").of(t) == s[-1] and parse_risk("mean").of(t) == pytest.approx(s.mean())


def test_cvar_reaches_an_infinite_time_only_in_its_tail():
    t = np.array([1.0, 2.0, 3.0, np.inf])
    assert cvar(t, 0.5) == np.inf and cvar(np.array([1.0, 2.0, 3.0, 4.0]), 0.75) == 4.0
    assert empirical_quantile(t, 0.75) == 3.0 and arrival_stats(t)["mean"] == np.inf


def test_wilson_interval_matches_scipy():
    for k, n in [(0, 10), (3, 10), (50, 100), (999, 1000), (1000, 1000)]:
        ci = binomtest(k, n).proportion_ci(confidence_level=0.95, method="wilson")
        assert wilson_interval(k, n) == pytest.approx((ci.low, ci.high), abs=1e-12)


# --------------------------------------------------------------------------------------------- Monte Carlo


@pytest.mark.slow
def test_monte_carlo_without_noise_is_the_deterministic_evaluation(ensemble):
    path, res = ensemble
    from pyroute_rel.analysis.members import member_scenario

    sc = member_scenario(path, 1)
    track = res.tracks[2]
    ev = evaluate_track(sc, track)
    mc = monte_carlo(sc, track, runs=7, seed=3, settings=MonteCarloSettings.zero())
    assert (mc.voyage_time_h == ev.voyage_time_h).all()
    assert (mc.max_p_f == ev.max_failure_probability).all()
    assert (mc.p_fail == (ev.max_failure_probability > 0.5)).all()


@pytest.mark.slow
def test_monte_carlo_mean_converges_at_the_root_n_rate():
    """The mean voyage time over N runs (seed 11) is within 3.5 standard errors of the mean of 20 000 runs (another
    seed) for N = 100, 400, 1600: each check fails with probability about 5e-4 for an honest 1/sqrt(N) estimator,
    and would fail for an estimator whose error does not shrink (a bias or a shared draw)."""
    sc = scenario_from_mapping({**TABLE, "failure": {"model": "dickson2018", "apf": 1.0}})
    track = np.column_stack([np.linspace(-12.0, -20.0, 21), np.linspace(45.0, 40.0, 21)])
    noisy = MonteCarloSettings(sigma0_ms=2.0, growth_ms_per_h=0.0, kappa=0.2, polar_sd=0.025)
    ref = monte_carlo(sc, track, runs=20_000, seed=99, settings=noisy).voyage_time_h
    mu, sd = ref.mean(), ref.std(ddof=1)
    assert sd > 0.5  # the noise matters
    errors = []
    for n in (100, 400, 1600):
        t = monte_carlo(sc, track, runs=n, seed=11, settings=noisy).voyage_time_h
        errors.append(abs(t.mean() - mu))
        assert errors[-1] < 3.5 * sd / math.sqrt(n) + 3.5 * sd / math.sqrt(ref.size)
    runs = monte_carlo(sc, track, runs=50, seed=5, settings=noisy).voyage_time_h
    assert np.array_equal(runs, monte_carlo(sc, track, runs=50, seed=5, settings=noisy).voyage_time_h)


@pytest.mark.slow
def test_cli_evaluate_monte_carlo(tmp_path: Path, capsys: pytest.CaptureFixture[str]):
    scenario = tmp_path / "s.toml"
    scenario.write_text(
        '[route]\nstart = [-12.0, 45.0]\nfinish = [-20.0, 40.0]\ndeparture = "2018-06-01T00:00:00Z"\n'
        '[avoid]\nland = false\n[weather]\nkind = "uniform"\ntws_kn = 15.0\ntwd_deg = 0.0\n'
    )
    (tmp_path / "t.csv").write_text("lon,lat\n-12,45\n-16,42.5\n-20,40\n")
    args = ["evaluate", str(scenario), str(tmp_path / "t.csv"), "--monte-carlo", "200", "--seed", "4", "--json"]
    code = main([*args, "--out", str(tmp_path / "o")])
    out, err = capsys.readouterr()
    assert code == 0, err
    mc = json.loads(out)["monte_carlo"]
    assert mc["runs"] == 200 and mc["seed"] == 4 and mc["settings"]["kappa"] == 0.2
    assert mc["p_fail_conditions"] == 0.0 and mc["p_fail_conditions_ci95"] == pytest.approx(wilson_interval(0, 200))
    assert (tmp_path / "o" / "monte_carlo.png").is_file()
    code = main(args)
    again, _ = capsys.readouterr()
    assert json.loads(again)["monte_carlo"] == mc  # the seed reproduces the runs


@pytest.mark.slow
def test_ensemble_spread_is_zero_for_identical_members_and_positive_otherwise(tmp_path: Path):
    from pyroute_rel.analysis.monte_carlo import spread_from_members

    track = np.column_stack([np.linspace(-14.0, -22.0, 9), np.linspace(31.0, 25.0, 9)])
    (tmp_path / "a").mkdir()
    flat = write_ensemble_scenario(tmp_path / "a", n_members=3, spread=0.0)
    np.testing.assert_allclose(spread_from_members(flat, track), 0.0, atol=1e-12)  # std of equal values: rounding
    (tmp_path / "b").mkdir()
    wide = write_ensemble_scenario(tmp_path / "b", n_members=6, spread=1.0)
    s = spread_from_members(wide, track)
    assert (s > 0).all() and s.max() > 0.5  # [m/s]: the members' lows are displaced by degrees


@pytest.mark.slow
def test_sailed_flags_equal_the_leg_reasons(ensemble):
    """The ensemble's p_f and feasibility flags of a sailed track
    (:func:`~pyroute_rel.analysis.evaluate.member_figures`, as the ensemble's sailing phase gets them) equal
    ``Sailed.leg_reasons`` / ``feasible``, on tracks that meet p_f > apf, cross land and leave the weather."""
    from dataclasses import replace

    from pyroute_rel.analysis.evaluate import evaluation_problem, member_figures, sail_in_members
    from pyroute_rel.analysis.members import member_scenario

    path, res = ensemble
    scs = [member_scenario(path, m).with_options(apf=a) for m, a in ((0, 0.5), (1, 0.02), (2, 1e-6))]
    tracks = [
        *res.tracks,
        np.array([[-14.0, 31.0], [-9.0, 31.5], [-6.0, 32.0]]),  # into Morocco
        np.array([[-5.0, 40.0], [-2.0, 45.0], [3.0, 46.0]]),  # through Spain, off the file's east edge (0 E)
    ]
    avoid = replace(scs[0].avoid, land=True)
    problems = [evaluation_problem(sc) for sc in scs]
    sailed = sail_in_members(problems, tracks, avoid=avoid)
    fig = member_figures(problems, tracks, avoid=avoid)
    seen = {"p_f": 0, "land": 0, "stop": 0, "ok": 0}
    for j, per_member in enumerate(sailed):
        for i, s in enumerate(per_member):
            reasons = s.leg_reasons()
            over = any("p_f" in r for r in reasons)
            assert bool(fig.over_apf[i, j]) == over
            assert bool(fig.feasible[i, j]) == s.feasible
            assert bool(fig.on_land[i, j]) == bool(s.land.any())
            seen["p_f"] += over
            seen["land"] += any("land" in r for r in reasons)
            seen["stop"] += not np.isfinite(s.voyage_time_h)
            seen["ok"] += s.feasible
    assert all(seen.values()), seen  # every case met


@pytest.mark.slow
def test_ensemble_spread_of_a_track_leaving_the_members_data_is_a_clear_error(tmp_path: Path):
    """A track whose legs leave the members' data: one line naming the first such leg, where it is and the wind's
    extent (it said "Monte-Carlo spread_ms must be ... finite (got nan at index k)")."""
    from pyroute_rel.analysis.monte_carlo import spread_from_members
    from pyroute_rel.errors import ScenarioError

    path = write_ensemble_scenario(tmp_path, n_members=3, spread=1.0)
    inside = np.column_stack([np.linspace(-14.0, -22.0, 5), np.linspace(31.0, 25.0, 5)])
    assert np.isfinite(spread_from_members(path, inside)).all()
    out = np.vstack([inside, [[-60.0, 25.0], [-70.0, 25.0]]])  # two legs out of the data to the west
    with pytest.raises(ScenarioError, match=r"^the ensemble's members have no wind at the midpoint of leg 5 of 6 "):
        spread_from_members(path, out)
    with pytest.raises(
        ScenarioError, match=r"the track leaves the members' data \(wind: lon \[-40, 0\], lat .*\); 2 legs in all$"
    ):
        spread_from_members(path, out)


@pytest.mark.slow
def test_route_member_reads_an_edited_scenario_or_weather_file_again(tmp_path: Path):
    """``route_member`` keeps a member's scenario and grids in the process: only while the scenario file, and the
    weather file it names, are unchanged. The finish moved in the file, then the ensemble file replaced by another:
    each call gives the route a fresh read gives."""
    import os

    from pyroute_rel.analysis.ensemble import route_member

    def touched(p: Path) -> None:  # a later modification time, whatever the file system's clock resolution
        st = p.stat()
        os.utime(p, ns=(st.st_atime_ns, st.st_mtime_ns + 2_000_000_000))

    path = write_ensemble_scenario(tmp_path, n_members=2)
    first = route_member(path, 0)
    assert first.lon_deg[-1] == pytest.approx(-22.0)
    path.write_text(path.read_text().replace("finish = [-22.0, 25.0]", "finish = [-18.0, 25.0]"))
    touched(path)
    moved = route_member(path, 0)
    ref = load_scenario(_member_toml(path, 0)).route()
    assert moved.lon_deg[-1] == pytest.approx(-18.0)
    assert moved.voyage_time_h == ref.voyage_time_h
    write_ensemble_scenario(tmp_path, n_members=2, spread=4.0)  # another ensemble file (and the finish back)
    touched(tmp_path / "ens.nc")
    again = route_member(path, 0)
    ref = load_scenario(_member_toml(path, 0)).route()
    assert again.voyage_time_h == ref.voyage_time_h and again.voyage_time_h != first.voyage_time_h
    np.testing.assert_array_equal(again.lon_deg, ref.lon_deg)
