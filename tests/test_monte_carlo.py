"""Monte Carlo's boat-speed noise (issue 19): an AR(1) process along the legs with Barde's variance kappa V; the runs'
mean voyage time is unbiased against the model's exact expectation, and the noise's correlation is the AR(1)'s."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate, stats

from pyroute_rel import scenario_from_mapping
from pyroute_rel.analysis.evaluate import evaluate_track
from pyroute_rel.analysis.monte_carlo import MonteCarloSettings, expected_speed_factor, monte_carlo, wind_errors
from pyroute_rel.errors import ScenarioError

STEADY = {
    "route": {"start": [-12.0, 45.0], "finish": [-20.0, 40.0], "departure": "2018-06-01T00:00:00Z"},
    "weather": {"kind": "uniform", "tws_kn": 12.0, "twd_deg": 20.0},
    "avoid": {"land": False},
    "failure": {"model": "none"},
}


def _speed_only(**kw: float) -> MonteCarloSettings:
    return MonteCarloSettings(sigma0_ms=0.0, growth_ms_per_h=0.0, sigma_max_ms=0.0, polar_sd=0.0, **kw)


@pytest.mark.slow
def test_expected_speed_factor_matches_direct_integration():
    """E[1 / max(1 + s eta, 0.1)] against scipy's adaptive quadrature of the normal density."""
    for kappa, v in ((0.2, 4.0), (0.2, 1.0), (0.5, 0.7), (0.05, 6.0)):
        s = math.sqrt(kappa / v)
        f = lambda e, s=s: stats.norm.pdf(e) / max(1.0 + s * e, 0.1)  # noqa: E731
        kink = -0.9 / s
        ref = integrate.quad(f, -np.inf, kink)[0] + integrate.quad(f, kink, np.inf, limit=200)[0]
        assert float(expected_speed_factor(kappa, v)) == pytest.approx(ref, rel=1e-10)


@pytest.mark.slow
def test_mean_voyage_time_under_speed_noise_is_the_models_expectation():
    """Steady weather, speed noise alone: each leg's time is t_k V_k / V'_k, so E[T] = sum_k t_k E[1 / max(1 + s_k
    eta, 0.1)] with s_k = sqrt(kappa / V_k) whatever the correlation (linearity of expectation). The mean of 4000 runs
    must be within 4 standard errors of it: a wrong variance (kappa instead of kappa V, or sqrt(kappa V) taken as
    the variance) or a noise whose mean is not zero moves the mean by tens of standard errors."""
    sc = scenario_from_mapping(STEADY)
    track = np.column_stack([np.linspace(-12.0, -20.0, 31), np.linspace(45.0, 40.0, 31)])
    ev = evaluate_track(sc, track)
    t, d = ev.legs.time_h, ev.legs.distance_nm
    expected = float(np.sum(t * expected_speed_factor(0.2, d / t)))
    assert expected > ev.voyage_time_h * 1.02  # the noise's Jensen effect is visible at this tolerance
    for tau in (12.0, 1e-3):  # AR(1) and (almost) independent legs: the same mean
        runs = monte_carlo(sc, track, runs=4000, seed=21, settings=_speed_only(kappa=0.2, tau_speed_h=tau))
        times = runs.voyage_time_h
        se = times.std(ddof=1) / math.sqrt(times.size)
        assert abs(times.mean() - expected) < 4.0 * se, (tau, times.mean(), expected, se)


def _normal_mean(f, s: np.ndarray) -> float:
    """E[f(eta)], eta ~ N(0, 1), by scipy's adaptive quadrature over [-40, 40] (the density is below 1e-340
    beyond) with breaks at the floors' kinks (-0.9 / s)."""
    g = lambda e: stats.norm.pdf(e) * f(e)  # noqa: E731
    return integrate.quad(g, -40.0, 40.0, points=sorted(set((-0.9 / np.atleast_1d(s)).tolist())), limit=800)[0]


@pytest.mark.slow
def test_speed_noise_spread_is_the_ar1s_at_both_ends():
    """The generator's lag-1 correlation is exp(-dt / tau) (within 4 / sqrt(N)); and the voyage time's standard
    deviation matches its exact value at both ends of the correlation time: independent legs (tau -> 0: Var T =
    sum_k t_k**2 Var g_k) and one draw for the whole voyage (tau -> inf: T = sum_k t_k g_k(eta)), g_k(eta) =
    1 / max(1 + s_k eta, 0.1), by scipy's quadrature; within 10 % (about 6 standard errors of a standard deviation
    from 4000 runs). The two differ by a factor of about 6: a noise drawn afresh per leg fails the second."""
    rng = np.random.default_rng(5)
    n, dt, tau = 20_000, 3.0, 12.0
    e = wind_errors(rng, n, np.ones(40), np.full(40, dt), tau)
    r = np.corrcoef(e[:, 10], e[:, 11])[0, 1]
    assert abs(r - math.exp(-dt / tau)) < 4.0 / math.sqrt(n)
    sc = scenario_from_mapping(STEADY)
    track = np.column_stack([np.linspace(-12.0, -20.0, 31), np.linspace(45.0, 40.0, 31)])
    ev = evaluate_track(sc, track)
    t, d = ev.legs.time_h, ev.legs.distance_nm
    s = np.sqrt(0.2 / (d / t))

    def g(eta: float) -> np.ndarray:
        return 1.0 / np.maximum(1.0 + s * eta, 0.1)

    mean_g = np.array([_normal_mean(lambda x, k=k: g(x)[k], s[k]) for k in range(t.size)])
    var_g = np.array([_normal_mean(lambda x, k=k: g(x)[k] ** 2, s[k]) for k in range(t.size)]) - mean_g**2
    sd_independent = math.sqrt(float(np.sum(t**2 * var_g)))
    mean_t = float(np.sum(t * mean_g))
    sd_one_draw = math.sqrt(_normal_mean(lambda x: float(np.sum(t * g(x))) ** 2, s) - mean_t**2)
    assert sd_one_draw > 4.0 * sd_independent
    for tau_h, ref in ((1e-3, sd_independent), (1e7, sd_one_draw)):
        runs = monte_carlo(sc, track, runs=4000, seed=3, settings=_speed_only(kappa=0.2, tau_speed_h=tau_h))
        assert runs.voyage_time_h.std(ddof=1) == pytest.approx(ref, rel=0.1), tau_h


def test_zero_speed_noise_is_the_deterministic_evaluation():
    sc = scenario_from_mapping(STEADY)
    track = np.column_stack([np.linspace(-12.0, -20.0, 11), np.linspace(45.0, 40.0, 11)])
    ev = evaluate_track(sc, track)
    runs = monte_carlo(sc, track, runs=5, seed=1, settings=_speed_only(kappa=0.0, tau_speed_h=12.0))
    assert (runs.voyage_time_h == ev.voyage_time_h).all()


#: Each noise size's plausible range, as its message gives it (issue 34: kappa 1e308 and a wind SD of 1e6 m/s were
#: accepted).
_SCALARS = {
    "sigma0_ms": (50.0, "in [0, 50] [m/s]"),
    "sigma_max_ms": (50.0, "in [0, 50] [m/s]"),
    "growth_ms_per_h": (1.0, "in [0, 1] [m/s per h]"),
    "kappa": (10.0, "in [0, 10] [kn]"),
    "polar_sd": (1.0, "in [0, 1] (a share of the polar's speed)"),
}


@pytest.mark.parametrize("name", sorted(_SCALARS))
@pytest.mark.parametrize("value", [-1.0, -1e-300, math.nan, math.inf, -math.inf, True, "1", None, 1e6, 1e308, "top"])
def test_settings_refuse_a_bad_spread_naming_it(name, value):
    """The noise sizes are numbers in a plausible range; the message names the setting and quotes the value. The
    range's top is accepted."""
    top, rule = _SCALARS[name]
    if value == "top":
        assert getattr(MonteCarloSettings(**{name: top}), name) == top
        value = np.nextafter(top, math.inf)
    with pytest.raises(ScenarioError) as info:
        MonteCarloSettings(**{name: value})
    assert str(info.value) == f"Monte-Carlo {name} must be {rule} (got {value!r})"


@pytest.mark.parametrize("name", ["tau_h", "tau_speed_h"])
@pytest.mark.parametrize("value", [0.0, -0.0, 0, -5.0, math.nan, -math.inf, False, "24", None])
def test_settings_refuse_a_correlation_time_not_above_zero(name, value):
    with pytest.raises(ScenarioError) as info:
        MonteCarloSettings(**{name: value})
    assert str(info.value) == f"Monte-Carlo {name} must be > 0 [h] (got {value!r})"


def test_settings_take_zero_noise_and_any_positive_correlation_time():
    """0 is no noise, an infinite correlation time a constant error (phi = 1), whole numbers are numbers."""
    s = MonteCarloSettings(sigma0_ms=0, growth_ms_per_h=0.0, sigma_max_ms=50, kappa=0, polar_sd=0.0, tau_h=math.inf,
                           tau_speed_h=1e-300)  # fmt: skip
    assert s.describe_values() == {
        "sigma0_ms": 0.0, "growth_ms_per_h": 0.0, "sigma_max_ms": 50.0, "tau_h": math.inf, "kappa": 0.0,
        "polar_sd": 0.0, "tau_speed_h": 1e-300,
    }  # fmt: skip
    assert float(wind_errors(np.random.default_rng(1), 3, [1.0, 1.0], [0.0, 5.0], s.tau_h).std(axis=1).max()) == 0.0


def test_more_runs_than_the_memory_budget_allows_are_refused_before_any_is_sailed(monkeypatch):
    """Issue 34: ``--monte-carlo 10000000`` ignored the memory budget (about 1.2 GB a million runs) and ended in a
    MemoryError. The estimate counts the arrays of :func:`run_estimate`; over the budget, one line names both."""
    from pyroute_rel import resources
    from pyroute_rel.analysis.monte_carlo import RUN_LEG_ARRAYS, run_estimate
    from pyroute_rel.errors import MemoryBudgetError

    est = run_estimate(1000, 4, 16)
    assert est.total_bytes == 6 * 8 * 1000 * 4 + 8 * RUN_LEG_ARRAYS * 1000 * 16
    sc = scenario_from_mapping(STEADY)
    track = np.column_stack([np.linspace(-12.0, -20.0, 5), np.linspace(45.0, 40.0, 5)])
    from pyroute_rel.analysis.evaluate import evaluation_problem

    problem = evaluation_problem(sc)  # (made first: a route's own check counts what this process already holds)
    monkeypatch.setenv(resources.MEMORY_ENV, "200M")
    sailed = []
    import pyroute_rel.analysis.monte_carlo as mc

    real = mc.sail_tracks
    monkeypatch.setattr(mc, "sail_tracks", lambda *a, **k: sailed.append(1) or real(*a, **k))
    with pytest.raises(MemoryBudgetError, match=r"this Monte-Carlo evaluation needs about .* \(1000000 runs x 4 legs"):
        monte_carlo(sc, track, runs=1_000_000, seed=1, problem=problem)
    assert not sailed
    assert monte_carlo(sc, track, runs=100, seed=1, problem=problem).voyage_time_h.size == 100  # within it


def test_the_runs_that_arrive_are_summarised_apart_from_those_that_never_do():
    """A wind of 3 kn from dead ahead on some runs stalls them (the polar gives nothing head to wind): those never
    arrive; ``arrived_h`` is the distribution of the others, checked against numpy on the runs' own times (the
    quantile definition written out: the sorted time at index ceil(q n) - 1)."""
    sc = scenario_from_mapping({**STEADY, "weather": {"kind": "uniform", "tws_kn": 4.0, "twd_deg": 232.0}})
    track = np.column_stack([np.linspace(-12.0, -20.0, 11), np.linspace(45.0, 40.0, 11)])
    mc = monte_carlo(sc, track, runs=60, seed=3, settings=MonteCarloSettings(sigma0_ms=1.0, growth_ms_per_h=0.0))
    t = mc.voyage_time_h
    done = np.sort(t[np.isfinite(t)])
    assert 2 <= done.size < t.size  # the case: some runs stall, most arrive
    got = mc.summary()
    a = got["arrived_h"]
    assert a["runs"] == done.size and got["completed"] == done.size / t.size
    assert a["mean"] == pytest.approx(done.mean(), rel=1e-12) and a["sd"] == pytest.approx(done.std(ddof=1), rel=1e-12)
    for q, key in ((0.05, "p5"), (0.5, "p50"), (0.95, "p95")):
        assert a[key] == done[math.ceil(q * done.size) - 1]
    assert a["worst"] == done[-1] and got["arrival_h"]["worst"] is None  # over all runs: infinite
