"""Ensemble inputs and figures (the parts tests/test_evaluate.py, test_ensemble.py and test_ensemble_members.py do not
reach; issue 19): GPX routes and tracks and bare GeoJSON LineStrings written by hand (not by our writer); the member
dimension named ``realization`` or ``member``; a list of files as the members; ``--risk p90`` on the sorted times;
what the figures draw (the chosen route highlighted, each candidate's empirical CDF, the regret matrix with its
infeasible cells masked, the Monte-Carlo histogram); the example script's synthetic 20-member ensemble."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from test_evaluate import load_example, write_ensemble_scenario

from pyroute_rel import load_scenario
from pyroute_rel.analysis.ensemble import EnsembleResult, MemberRoute, parse_risk, route_ensemble
from pyroute_rel.analysis.evaluate import evaluate_track
from pyroute_rel.cli import main

ROOT = Path(__file__).resolve().parents[1]
POINTS = [(-12.0, 45.0), (-14.5, 43.75), (-16.0, 42.5), (-18.25, 41.0), (-20.0, 40.0)]
TIMES = ["2018-06-02T00:00:00Z", "2018-06-02T20:00:00Z", "2018-06-03T08:00:00Z", "2018-06-04T01:00:00Z",
         "2018-06-04T15:00:00Z"]  # fmt: skip


def _scenario_file(folder: Path) -> Path:
    path = folder / "s.toml"
    path.write_text(
        '[route]\nstart = [-12.0, 45.0]\nfinish = [-20.0, 40.0]\ndeparture = "2018-06-01T00:00:00Z"\n'
        '[grid]\nn_ranks = 20\n[avoid]\nland = false\n[weather]\nkind = "uniform"\ntws_kn = 15.0\ntwd_deg = 0.0\n'
        "hs_m = 1.0\n[[weather.patch]]\nlon = [-17.0, -15.0]\nlat = [41.0, 44.0]\nhs_m = 4.5\n"
        '[failure]\nmodel = "dickson2018"\napf = 0.95\n'
    )
    return path


def _gpx(body: str) -> str:
    return (
        '<?xml version="1.0" encoding="UTF-8"?>\n'
        '<gpx version="1.1" creator="by hand" xmlns="http://www.topografix.com/GPX/1/1">\n' + body + "\n</gpx>\n"
    )


TRACK_FILES = {
    "route.gpx": _gpx("<rte><name>r</name>" + "".join(f'<rtept lat="{la}" lon="{lo}"/>' for lo, la in POINTS)
                      + "</rte>"),
    "track.gpx": _gpx("<trk><trkseg>" + "".join(f'<trkpt lat="{la}" lon="{lo}"/>' for lo, la in POINTS[:3])
                      + "</trkseg><trkseg>" + "".join(f'<trkpt lat="{la}" lon="{lo}"/>' for lo, la in POINTS[3:])
                      + "</trkseg></trk>"),
    "timed.gpx": _gpx("<trk><trkseg>" + "".join(f'<trkpt lat="{la}" lon="{lo}"><time>{t}</time></trkpt>'
                                                 for (lo, la), t in zip(POINTS, TIMES, strict=True))
                      + "</trkseg></trk>"),
    "line.geojson": json.dumps({"type": "LineString", "coordinates": [list(p) for p in POINTS]}),
    "collection.geojson": json.dumps({"type": "FeatureCollection", "features": [
        {"type": "Feature", "geometry": {"type": "Point", "coordinates": [-12.0, 45.0]}, "properties": {}},
        {"type": "Feature", "geometry": {"type": "LineString", "coordinates": [list(p) for p in POINTS]},
         "properties": {"name": "by hand"}}]}),
    "plain.csv": "lon,lat\n" + "".join(f"{lo},{la}\n" for lo, la in POINTS),
    "latlon.csv": "lat,lon\n" + "".join(f"{la},{lo}\n" for lo, la in POINTS),
    "timed.csv": "lon,lat,time\n" + "".join(f"{lo},{la},{t}\n" for (lo, la), t in zip(POINTS, TIMES, strict=True)),
}  # fmt: skip


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(TRACK_FILES))
def test_hand_written_track_files_evaluate_as_their_points(tmp_path: Path, name: str, capsys) -> None:
    """`pyroute-rel evaluate` of each file (GPX route, GPX track in two segments, GPX with times, a bare GeoJSON
    LineString, a FeatureCollection with a point and a line, CSV lon/lat, lat/lon, lon/lat/time) gives the evaluation
    of the points written, departing at the file's first time where it has times."""
    (tmp_path / name).write_text(TRACK_FILES[name])
    scenario = _scenario_file(tmp_path)
    assert main(["evaluate", str(scenario), str(tmp_path / name), "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    timed = name.startswith("timed")
    ref = evaluate_track(load_scenario(scenario), np.array(POINTS), departure=TIMES[0] if timed else None)
    assert [(p["lon"], p["lat"]) for p in got["track"]] == POINTS
    assert got["departure"] == (TIMES[0] if timed else "2018-06-01T00:00:00Z")
    assert got["voyage_time_h"] == ref.voyage_time_h and got["max_failure_probability"] == ref.max_failure_probability
    assert got["feasible"] is True and got["max_failure_probability"] == 0.9  # the line crosses the patch


def _renamed(folder: Path, dim: str) -> Path:
    import xarray as xr

    path = write_ensemble_scenario(folder, n_members=3)
    with xr.open_dataset(folder / "ens.nc") as ds:
        renamed = ds.load().rename({"number": dim})
    (folder / "ens.nc").unlink()
    renamed.to_netcdf(folder / "ens.nc")
    return path


@pytest.mark.slow
@pytest.mark.parametrize("dim", ["realization", "member"])
def test_member_dimension_named_realization_or_member(tmp_path: Path, dim: str) -> None:
    """The same file with its member dimension renamed: `[weather] member = k` routes as on the ``number`` file, and
    the ensemble's member routes and times are the same."""
    (tmp_path / "number").mkdir()
    (tmp_path / dim).mkdir()
    ref_path = write_ensemble_scenario(tmp_path / "number", n_members=3)
    path = _renamed(tmp_path / dim, dim)
    import xarray as xr

    with xr.open_dataset(tmp_path / dim / "ens.nc") as ds:
        assert dim in ds.dims and "number" not in ds.dims
    for k in (0, 2):
        a = load_scenario(_with_member(path, k)).route()
        b = load_scenario(_with_member(ref_path, k)).route()
        assert a.voyage_time_h == b.voyage_time_h and np.array_equal(a.lon_deg, b.lon_deg)
    res = route_ensemble(path, workers=1, mean_field=False, risk="mean")
    ref = route_ensemble(ref_path, workers=1, mean_field=False, risk="mean")
    assert res.members == ref.members == (0, 1, 2)
    assert np.array_equal(res.time_h, ref.time_h) and res.chosen == ref.chosen


def _with_member(path: Path, k: int) -> Path:
    out = path.with_name(f"member{k}.toml")
    out.write_text(path.read_text().replace('kind = "file"\n', f'kind = "file"\nmember = {k}\n'))
    return out


@pytest.mark.slow
def test_a_list_of_files_as_members(tmp_path: Path, capsys) -> None:
    """`--member-files`: member k's route is `route` on a scenario whose weather is file k alone; the regret entries
    recompute with `evaluate` in that scenario; the diagonal is zero."""
    make = load_example("make_ensemble_example")
    ds = make.make_ensemble(3, resolution_deg=2.0, step_h=12.0)
    files = []
    for k in range(3):
        files.append(tmp_path / f"m{k}.nc")
        ds.isel(number=k).drop_vars("number").to_netcdf(files[-1])
    text = write_ensemble_scenario(tmp_path, n_members=1).read_text()
    scenario = tmp_path / "files.toml"
    scenario.write_text(text.replace('paths = ["ens.nc"]', 'paths = ["m0.nc"]'))
    res = route_ensemble(scenario, member_files=files, workers=1, mean_field=False, risk="worst")
    assert res.members == (0, 1, 2)
    singles = []
    for k in range(3):
        own = tmp_path / f"own{k}.toml"
        own.write_text(text.replace('paths = ["ens.nc"]', f'paths = ["m{k}.nc"]'))
        singles.append(load_scenario(own))
        ref = singles[-1].route()
        assert res.routes[k].voyage_time_h == ref.voyage_time_h
        assert np.array_equal(res.routes[k].lon_deg, ref.lon_deg) and np.array_equal(res.routes[k].lat_deg, ref.lat_deg)
    assert len({r.voyage_time_h for r in res.routes}) == 3  # the files differ
    for i in range(3):
        for j in range(3):
            ev = evaluate_track(singles[j], res.tracks[i])
            assert res.time_h[i, j] == pytest.approx(ev.voyage_time_h, rel=1e-12)
            if ev.feasible:
                assert res.regret_h[i, j] == pytest.approx(ev.voyage_time_h - res.routes[j].voyage_time_h, abs=1e-9)
        assert res.regret_h[i, i] == pytest.approx(0.0, abs=1e-9)
    argv = ["ensemble", str(scenario), "--member-files", *map(str, files), "--no-mean", "--workers", "1"]
    assert main([*argv, "--risk", "worst", "--json", "--quiet"]) == 0
    cli = json.loads(capsys.readouterr().out)
    assert cli["time_h"] == res.time_h.tolist() and cli["chosen"]["name"] == res.names[res.chosen]


@settings(max_examples=100, deadline=None)
@given(st.lists(st.floats(0.0, 1e4, allow_nan=False), min_size=1, max_size=60), st.integers(1, 99))
def test_percentile_risk_is_the_sorted_time_at_its_rank(times, pct) -> None:
    """`--risk pXX`: the smallest sorted time with at least XX % of the members at or below it (counted here with
    whole numbers, no floating-point quantile)."""
    t = np.array(times)
    s = np.sort(t)
    n = t.size
    k = next(k for k in range(1, n + 1) if 100 * k >= pct * n)
    assert parse_risk(f"p{pct}").of(t) == s[k - 1]


# ------------------------------------------------------------------------------------------------ the figures


def _result(risk: str = "cvar:0.5") -> EnsembleResult:
    """A hand-made result: 3 members, 3 member routes and the mean; candidates 1 and 2 are infeasible in member 2,
    candidate 1 cannot be completed in member 0 (an infinite time); member 2 has no route of its own."""
    tracks = tuple(np.column_stack([np.linspace(-14.0, -22.0, 5), np.linspace(31.0, 25.0, 5) + d]) for d in (0.0,
                   0.5, -0.5, 0.2))  # fmt: skip
    routes = (
        MemberRoute(0, tracks[0][:, 0], tracks[0][:, 1], 100.0),
        MemberRoute(1, tracks[1][:, 0], tracks[1][:, 1], 104.0),
        MemberRoute(2, np.empty(0), np.empty(0), math.inf, error="no feasible route"),
    )
    time_h = np.array([[100.0, 110.0, 120.0], [math.inf, 104.0, 108.0], [101.0, 105.0, 130.0], [102.0, 106.0, 111.0]])
    feasible = np.ones((4, 3), dtype=bool)
    feasible[1, 2] = feasible[2, 2] = False
    return EnsembleResult(
        members=(0, 1, 2), routes=routes, mean_route=None, names=("member 0", "member 1", "member 2", "mean"),
        sources=(0, 1, 2, "mean"), tracks=tracks, time_h=time_h, max_p_f=np.zeros((4, 3)),
        p_fail=~feasible, feasible=feasible, risk=parse_risk(risk),
    )  # fmt: skip


def test_spaghetti_map_highlights_the_chosen_route() -> None:
    from matplotlib.colors import to_rgba

    from pyroute_rel.viz.ensemble import spaghetti_map

    res = _result()
    assert res.chosen == 3  # 0 and 3 feasible everywhere; CVaR 0.5 116.7 h against 109.3 h
    ax = spaghetti_map(res).axes[0]
    red = [ln for ln in ax.lines if to_rgba(ln.get_color()) == to_rgba("tab:red")]
    assert len(red) == 1 and red[0].get_label().startswith("chosen: mean (cvar:0.5)")
    np.testing.assert_array_equal(np.column_stack([red[0].get_xdata(), red[0].get_ydata()]), res.tracks[3])
    assert red[0].get_linewidth() > max(ln.get_linewidth() for ln in ax.lines if ln is not red[0])
    labels = ax.get_legend_handles_labels()[1]
    assert "member routes" in labels and "start" in labels and "finish" in labels
    assert ax.get_xlabel() == "longitude [deg]" and ax.get_ylabel() == "latitude [deg]"


def test_arrival_cdf_draws_each_candidates_empirical_distribution() -> None:
    """Each candidate's curve holds its finite times, sorted, at heights k / n (a curve that cannot be completed in
    a member stops short of 1); infeasible arrivals are crosses at their place on the curve."""
    from pyroute_rel.viz.ensemble import arrival_cdf

    res = _result()
    ax = arrival_cdf(res).axes[0]
    steps = [ln for ln in ax.lines if ln.get_drawstyle() == "steps-post"]
    assert len(steps) == 4
    for i, ln in enumerate(steps):
        t = res.time_h[i]
        finite = np.sort(t[np.isfinite(t)])
        heights = [sum(t <= x) / 3 for x in finite]  # the fraction of members arrived by then
        assert list(ln.get_xdata()) == list(finite) and list(ln.get_ydata()) == heights
    crosses = [ln for ln in ax.lines if ln.get_marker() == "x" and len(ln.get_xdata())]
    marked = sorted(x for ln in crosses for x in ln.get_xdata())
    expected = sorted(res.time_h[i, j] for i in range(4) for j in range(3)
                      if not res.feasible[i, j] and np.isfinite(res.time_h[i, j]))  # fmt: skip
    assert marked == expected
    assert ax.get_xlabel() == "voyage time [h]" and ax.get_ylabel() == "fraction of members arrived"


def test_regret_heatmap_draws_the_matrix_with_infeasible_cells_masked() -> None:
    from pyroute_rel.viz.ensemble import regret_heatmap

    res = _result()
    fig = regret_heatmap(res)
    ax = fig.axes[0]
    data = ax.images[0].get_array()
    # time minus the member's own optimum, by hand; masked where infeasible or the member has no route
    expected = [[0.0, 6.0, None], [None, 0.0, None], [1.0, 1.0, None], [2.0, 2.0, None]]
    assert [[None if m else float(v) for v, m in zip(row, mrow, strict=True)]
            for row, mrow in zip(data.data, np.ma.getmaskarray(data), strict=True)] == expected  # fmt: skip
    bar = fig.axes[1]
    assert bar.get_ylabel() == "regret [h]"
    lo, hi = ax.images[0].get_clim()
    assert (lo, hi) == (0.0, 6.0)
    assert [t.get_text() for t in ax.get_yticklabels()] == list(res.names)
    assert [t.get_text() for t in ax.get_xticklabels()] == ["0", "1", "2"]
    chosen = ax.get_yticklabels()[res.chosen]
    assert chosen.get_color() == "tab:red" and all(
        t.get_color() != "tab:red" for k, t in enumerate(ax.get_yticklabels()) if k != res.chosen
    )


def test_monte_carlo_histogram_counts_the_runs_that_arrive() -> None:
    from pyroute_rel.analysis.monte_carlo import MonteCarloResult
    from pyroute_rel.viz.ensemble import monte_carlo_histogram

    rng = np.random.default_rng(0)
    t = rng.normal(200.0, 10.0, 300)
    t[:7] = np.inf
    p_fail = np.zeros(300, dtype=bool)
    p_fail[7:40] = True
    mc = MonteCarloResult(voyage_time_h=t, max_p_f=np.where(p_fail, 0.9, 0.1), p_fail=p_fail, deterministic_h=198.0,
                          apf=0.5, seed=0)  # fmt: skip
    ax = monte_carlo_histogram(mc).axes[0]
    bars = ax.containers
    assert sum(b.get_height() for b in bars[0]) == 293  # every run that arrives, once
    assert sum(b.get_height() for b in bars[1]) == 33  # those meeting p_f > apf
    assert [ln.get_xdata()[0] for ln in ax.lines] == [198.0]
    assert "293 of 300 runs arrived" in ax.get_legend_handles_labels()[1]  # the 7 that did not are said
    assert ax.get_xlabel() == "voyage time [h]"


# ------------------------------------------------------------------------------------------------ the example


@pytest.mark.slow
def test_the_example_script_makes_a_20_member_ensemble_and_its_figures(tmp_path: Path) -> None:
    """`python examples/make_ensemble_example.py` writes 20 members in ERA5's ensemble layout, and `python
    examples/ensemble_example.py --out DIR` routes them and the mean, writes the three figures and ensemble.json,
    whose choice follows the documented rule (fewest infeasible members, then the least CVaR 0.9)."""
    import xarray as xr

    env = {"PYTHONPATH": str(ROOT), "MPLBACKEND": "Agg", "PATH": "/usr/bin:/bin"}
    data = tmp_path / "ens.nc"
    subprocess.run([sys.executable, str(ROOT / "examples" / "make_ensemble_example.py"), "--out", str(data)],
                   check=True, env=env, capture_output=True, timeout=600)  # fmt: skip
    with xr.open_dataset(data) as ds:
        assert ds.sizes["number"] == 20 and {"valid_time", "latitude", "longitude"} <= set(ds.dims)
    out = tmp_path / "out"
    run = subprocess.run([sys.executable, str(ROOT / "examples" / "ensemble_example.py"), "--out", str(out)],
                         env=env, capture_output=True, text=True, timeout=1200)  # fmt: skip
    assert run.returncode == 0, run.stderr
    names = sorted(p.name for p in out.iterdir())
    assert names == ["ensemble.json", "ensemble_arrival_cdf.png", "ensemble_regret.png", "ensemble_spaghetti.png"]
    s = json.loads((out / "ensemble.json").read_text())
    assert len(s["members"]) == 20 and s["candidates"][-1]["name"] == "mean"
    assert len(s["candidates"]) == 1 + sum(m["feasible"] for m in s["members"])
    frac = np.array([c["infeasible_members"] for c in s["candidates"]])
    risk = np.array([math.inf if c["risk_h"] is None else c["risk_h"] for c in s["candidates"]])
    best = np.flatnonzero(np.isclose(frac, frac.min(), rtol=0.0, atol=1e-12))
    assert s["chosen"]["name"] == s["candidates"][best[np.argmin(risk[best])]]["name"]
    assert s["chosen"]["risk"] == "cvar:0.9" and f"chosen: {s['chosen']['name']}" in run.stdout


@pytest.mark.slow
def test_evaluate_in_a_member_the_mean_and_monte_carlo_from_the_members_spread(tmp_path: Path, capsys) -> None:
    """`evaluate --member K` sails member K's weather, `--member mean` the ensemble mean (as the library does on
    the member's scenario); Monte Carlo with --member takes the wind error from the members' spread: identical
    members and no boat noise give every run the deterministic time; members that differ give a spread."""
    from pyroute_rel.analysis.members import mean_scenario, member_scenario

    track = tmp_path / "t.csv"
    lon, lat = np.linspace(-14.0, -22.0, 9), np.linspace(31.0, 25.0, 9)
    track.write_text("lon,lat\n" + "".join(f"{a},{b}\n" for a, b in zip(lon, lat, strict=True)))
    points = np.loadtxt(track, delimiter=",", skiprows=1)
    (tmp_path / "same").mkdir()
    (tmp_path / "wide").mkdir()
    same = write_ensemble_scenario(tmp_path / "same", n_members=3, spread=0.0)
    wide = write_ensemble_scenario(tmp_path / "wide", n_members=4, spread=1.0)
    for member, scenario in ((2, member_scenario(wide, 2)), ("mean", mean_scenario(wide))):
        code = main(["evaluate", str(wide), str(track), "--member", str(member), "--json"])
        got = json.loads(capsys.readouterr().out)
        ref = evaluate_track(scenario, points)
        assert code == (0 if ref.feasible and ref.arrived else 2)  # printed either way; 2: not a route
        assert got["voyage_time_h"] == ref.voyage_time_h and got["arrival"] == str(ref.arrival)[:19] + "Z"
    mc_args = ["--member", "1", "--monte-carlo", "40", "--seed", "2", "--kappa", "0", "--json"]
    code = main(["evaluate", str(same), str(track), *mc_args])
    got = json.loads(capsys.readouterr().out)
    assert code == (0 if got["feasible"] and got["arrived"] else 2)
    mc = got["monte_carlo"]
    assert mc["settings"]["wind_spread"] == "ensemble members"
    # identical members: the wind errors drawn from their spread are ~1e-15 m/s (rounding in the spread), not 0, so the
    # runs agree with the deterministic time to rounding (the march's steps may round differently), not to the bit
    assert mc["deterministic_h"] == got["voyage_time_h"]
    for q in ("p5", "p50", "worst"):
        assert mc["arrival_h"][q] == pytest.approx(got["voyage_time_h"], rel=1e-13)
    code = main(["evaluate", str(wide), str(track), *mc_args])
    got = json.loads(capsys.readouterr().out)
    assert code == (0 if got["feasible"] and got["arrived"] else 2)
    mc = got["monte_carlo"]
    spread = mc["arrival_h"]
    assert mc["settings"]["wind_spread"] == "ensemble members" and spread["p50"] is not None
    assert spread["p5"] < spread["p50"]


def test_polar_scaling_divides_each_runs_time_by_its_factor() -> None:
    """Polar scaling alone, in steady weather: run i sails every leg at s_i times the polar speed, so its time is the
    deterministic time / s_i; the factors det / T_i must then be N(1, polar_sd): their mean within 4 standard errors
    of 1 and their standard deviation within 5 % (4.5 standard errors for 4000 runs) of polar_sd."""
    from pyroute_rel import scenario_from_mapping
    from pyroute_rel.analysis.monte_carlo import MonteCarloSettings, monte_carlo

    sc = scenario_from_mapping({
        "route": {"start": [-12.0, 45.0], "finish": [-20.0, 40.0], "departure": "2018-06-01T00:00:00Z"},
        "weather": {"kind": "uniform", "tws_kn": 12.0, "twd_deg": 20.0},
        "avoid": {"land": False}, "failure": {"model": "none"},
    })  # fmt: skip
    track = np.column_stack([np.linspace(-12.0, -20.0, 11), np.linspace(45.0, 40.0, 11)])
    det = evaluate_track(sc, track).voyage_time_h
    only_polar = MonteCarloSettings(sigma0_ms=0.0, growth_ms_per_h=0.0, sigma_max_ms=0.0, kappa=0.0, polar_sd=0.05)
    runs = monte_carlo(sc, track, runs=4000, seed=8, settings=only_polar).voyage_time_h
    s = det / runs
    assert abs(s.mean() - 1.0) < 4.0 * 0.05 / math.sqrt(s.size)
    assert s.std(ddof=1) == pytest.approx(0.05, rel=0.05)


@pytest.mark.slow
def test_the_spread_of_the_monte_carlo_mean_shrinks_as_one_over_root_n() -> None:
    """The rate itself: over 40 seeds, the variance of the N-run mean is sigma^2 / N, so its ratio between N = 25
    and N = 400 is 16. The ratio of two sample variances of 40 values each has a log standard deviation of about
    sqrt(2 * 2 / 39) = 0.32: the test allows 16 within a factor exp(3 * 0.32) = 2.6 (6.1 to 42, a 3-sigma band).
    Draws shared between runs (a mean that does not converge) give a ratio near 1; draws shared between seeds give
    variances near 0."""
    from pyroute_rel import scenario_from_mapping
    from pyroute_rel.analysis.monte_carlo import MonteCarloSettings, monte_carlo

    sc = scenario_from_mapping({
        "route": {"start": [-12.0, 45.0], "finish": [-20.0, 40.0], "departure": "2018-06-01T00:00:00Z"},
        "weather": {"kind": "uniform", "tws_kn": 15.0, "twd_deg": 0.0},
        "avoid": {"land": False}, "failure": {"model": "none"},
    })  # fmt: skip
    track = np.column_stack([np.linspace(-12.0, -20.0, 21), np.linspace(45.0, 40.0, 21)])
    noisy = MonteCarloSettings(sigma0_ms=2.0, growth_ms_per_h=0.0, kappa=0.2, polar_sd=0.025)
    means = {n: [monte_carlo(sc, track, runs=n, seed=1000 * n + s, settings=noisy).voyage_time_h.mean()
                 for s in range(40)] for n in (25, 400)}  # fmt: skip
    assert all(np.isfinite(m).all() for m in means.values())
    ratio = np.var(means[25], ddof=1) / np.var(means[400], ddof=1)
    assert 16.0 / 2.6 < ratio < 16.0 * 2.6, ratio


def test_retiming_a_route_with_manoeuvre_penalties_gives_its_figures(tmp_path: Path) -> None:
    """Issue 19: re-timing a routed track gives the route's own figures, also for a boat whose tacks cost time (the
    beat example, on a coarser grid: its route tacks)."""
    text = (ROOT / "examples" / "microtransat_beat.toml").read_text().replace("n_ranks = 160", "n_ranks = 30")
    (tmp_path / "beat.toml").write_text(text)
    route = load_scenario(tmp_path / "beat.toml").route()
    assert route.manoeuvres.tacks > 0 and route.manoeuvres.penalty_h.sum() > 0.0
    ev = evaluate_track(load_scenario(tmp_path / "beat.toml"), np.column_stack([route.lon_deg, route.lat_deg]))
    assert ev.voyage_time_h == pytest.approx(route.voyage_time_h, rel=1e-12)
