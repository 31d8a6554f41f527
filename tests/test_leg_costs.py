"""Costing a track's legs in time-varying weather in one vectorised call from guessed departure times (the DP's
arrival times in ``build_route``): the same numbers as costing the legs one after the other.

Reference: the legs costed one at a time here, each with ``RoutingProblem.costs`` leaving when the previous leg
arrived (after its wait), its side of the wind from the weather sampled at its first sample point, its manoeuvre
penalty added when the side changes, and the arrival rounded up on the time lattice: the definition of a track's
timing, written out leg by leg.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pyroute_rel.boat.manoeuvre import ManoeuvrePenalties, manoeuvre_kind, wind_side
from pyroute_rel.reliability.failure import load_failure_model
from pyroute_rel.routing.cost import arc_geometry
from pyroute_rel.routing.grid import make_grid
from pyroute_rel.routing.route import route_on_grid
from pyroute_rel.routing.solve import GUESS_PASSES, RoutingProblem, leg_manoeuvres
from pyroute_rel.times import hours_after
from tests.test_cost import _varying_field
from tests.test_solve import DEP, random_polar

_WEATHER = []


def varying_weather():
    """The time-varying gridded field of test_cost (48 h, 0.5 deg, over lon -40..-20, lat 20..40), built once."""
    if not _WEATHER:
        _WEATHER.append(_varying_field())
    return _WEATHER[0]


def one_leg_at_a_time(problem: RoutingProblem, lon, lat, waits):
    """(elapsed [h] at each point, time [h] and p_f of each leg, penalty [h] of each leg), leg after leg."""
    n = len(lon) - 1
    elapsed, times, p_f, pen = np.zeros(n + 1), np.zeros(n), np.zeros(n), np.zeros(n)
    prev = problem.initial_side
    for i in range(n):
        t0 = elapsed[i] + waits[i]
        c = problem.costs(lon[i], lat[i], lon[i + 1], lat[i + 1], t0)
        times[i], p_f[i] = float(c.time_h), float(c.p_f)
        g = arc_geometry(lon[i], lat[i], lon[i + 1], lat[i + 1], samples=problem.samples)
        w = problem.weather.sample(g.lon_deg[..., 0], g.lat_deg[..., 0], hours_after(DEP, np.asarray(t0)))
        side, twa = wind_side(w.twd_deg, g.course_deg[..., 0])
        side = int(np.ravel(side)[0])
        if problem.sides and prev is not None and side != prev:
            pen[i] = float(problem.manoeuvres.penalty_h(manoeuvre_kind(twa), w.tws_kn).ravel()[0])
        prev = side
        elapsed[i + 1] = problem.arrive((t0 + times[i]) + pen[i])
    return elapsed, times, p_f, pen


def fast_polar(rng: np.random.Generator):
    """A random polar of 4.5-12 kn where it sails: a dozen short legs fit in the field's 48 h."""
    polar = random_polar(rng)
    return replace(polar, speed_kn=np.where(polar.speed_kn > 0, polar.speed_kn + 4.0, 0.0))


def problem_from(data: st.DataObject) -> RoutingProblem:
    rng = np.random.default_rng(data.draw(st.integers(0, 2**32 - 1), label="seed"))
    step = data.draw(st.sampled_from([None, 0.25, 1.0]), label="time_step_h")
    penalties = None
    if data.draw(st.booleans(), label="penalties"):
        penalties = ManoeuvrePenalties(
            tack_s=[[0.0, float(rng.uniform(0, 4e3))], [25.0, float(rng.uniform(0, 4e3))]],
            gybe_s=[[5.0, float(rng.uniform(0, 4e3))], [20.0, float(rng.uniform(0, 4e3))]],
        )
    failure = load_failure_model("dickson2018") if data.draw(st.booleans(), label="failure") else None
    return RoutingProblem(
        departure=DEP,
        weather=varying_weather(),
        polar=fast_polar(rng),
        samples=int(rng.integers(1, 4)),
        failure=failure,
        apf=data.draw(st.sampled_from([1.0, 0.3]), label="apf"),  # 1: legs with p_f 0.9 sail too
        manoeuvres=penalties,
        time_step_h=step,
        max_wait_h=0.0 if step is None else 4.0 * step,
        initial_side=data.draw(st.sampled_from([None, 0, 1]), label="initial_side"),
    )


GUESSES = ["exact", "ulps", "shifted", "random", "none"]


@pytest.mark.slow
@settings(max_examples=40, deadline=None, derandomize=True, database=None)
@given(data=st.data())
def test_legs_from_any_guess_equal_the_legs_one_at_a_time(data: st.DataObject) -> None:
    """Random tracks inside the field's box, waits on the lattice, and guesses that are exact, perturbed by an ulp,
    shifted, or arbitrary: every guess gives the legs costed one after the other (to 1e-9 h)."""
    check_guess(data, problem_from(data), data.draw(st.sampled_from(GUESSES), label="guess"))


@pytest.mark.parametrize("kind", GUESSES)
def test_each_kind_of_guess_on_one_track(kind: str) -> None:
    """The same check on one fixed problem with manoeuvre penalties, a failure model and the time lattice."""

    class Fixed:
        def draw(self, strategy, label=""):
            return {
                "seed": 7,
                "time_step_h": 0.25,
                "penalties": True,
                "failure": True,
                "initial_side": 1,
                "apf": 1.0,
            }.get(label, {"track": 11, "legs": 9}.get(label))

    elapsed = check_guess(Fixed(), problem_from(Fixed()), kind)
    assert np.isfinite(elapsed).all()  # the precondition: every leg sailed (and re-costed when guessed wrong)


def check_guess(data, problem: RoutingProblem, kind: str) -> np.ndarray:
    rng = np.random.default_rng(data.draw(st.integers(0, 2**32 - 1), label="track"))
    n = data.draw(st.integers(1, 12), label="legs")
    lon = np.cumsum(np.concatenate([[rng.uniform(-34.0, -26.0)], rng.uniform(-0.6, 0.6, n)]))  # hops of < 50 nm
    lat = np.cumsum(np.concatenate([[rng.uniform(26.0, 34.0)], rng.uniform(-0.6, 0.6, n)]))
    waits = np.zeros(n)
    if problem.time_step_h is not None:
        waits = problem.time_step_h * rng.integers(0, 3, n).astype(float)
    elapsed, times, p_f, pen = one_leg_at_a_time(problem, lon, lat, waits)
    guess = {
        "exact": elapsed[:-1],
        "ulps": np.nextafter(elapsed[:-1], np.inf),
        "shifted": elapsed[:-1] + rng.uniform(-0.5, 0.5, n),
        "random": rng.uniform(0.0, 30.0, n),
        "none": None,
    }[kind]
    got, costs, man = leg_manoeuvres(problem, lon, lat, waits, elapsed_guess_h=guess)
    ok = np.isfinite(elapsed)
    np.testing.assert_array_equal(np.isfinite(got), ok)
    np.testing.assert_allclose(got[ok], elapsed[ok], rtol=0, atol=1e-9)
    fin = np.isfinite(times)
    np.testing.assert_array_equal(np.isfinite(costs.time_h), fin)
    np.testing.assert_allclose(costs.time_h[fin], times[fin], rtol=0, atol=1e-9)
    np.testing.assert_allclose(costs.p_f, p_f, rtol=0, atol=1e-12)
    np.testing.assert_allclose(man.penalty_h, pen, rtol=0, atol=1e-9)
    return elapsed


@pytest.mark.parametrize("seed", range(4))
def test_route_legs_are_batched_and_equal_the_legs_one_at_a_time(seed: int, monkeypatch: pytest.MonkeyPatch) -> None:
    """A route in time-varying weather: its legs cost in fewer calls than legs (one, when the DP's arrival times are
    the legs' own), and its times equal the legs costed one by one."""
    rng = np.random.default_rng(seed)
    grid = make_grid((-25.0, 30.0), (-28.5, 28.0), n_ranks=12, n_nodes=9, spacing_km=float(rng.uniform(10, 25)))
    problem = RoutingProblem(departure=DEP, weather=varying_weather(), polar=fast_polar(rng), samples=2)
    if seed % 2:
        problem = replace(problem, failure=load_failure_model("dickson2018"), apf=1.0)
    calls = []
    real = RoutingProblem.costs
    monkeypatch.setattr(RoutingProblem, "costs", lambda self, *a: calls.append(1) or real(self, *a))
    route = route_on_grid(grid, problem)
    n_legs = len(route.lon_deg) - 1
    assert 1 <= len(calls) <= GUESS_PASSES < n_legs
    elapsed, times, _, _ = one_leg_at_a_time(problem, route.lon_deg, route.lat_deg, np.zeros(n_legs))
    np.testing.assert_allclose(route.elapsed_h, elapsed, rtol=0, atol=1e-9)
    np.testing.assert_allclose(route.legs.time_h, times, rtol=0, atol=1e-9)
    assert route.voyage_time_h == pytest.approx(route.dp.finish_h, abs=1e-9)
