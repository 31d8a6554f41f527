"""Lazy judgement of arcs on the pieces they cross in the forward DP (issue 18, item 5).

The DP costs every arc on its samples and judges on pieces (:mod:`pyroute_rel.reliability.crossings`) only the arcs it
would pick (:func:`pyroute_rel.routing.solve._lazy_pieces`). The reference is the eager judgement of every arc the cost
function can judge (``settings_context(lazy_pieces=False)``, or a ``cost_hook``, which sees every arc's costs): the DP's
arrival times, back-pointers, waits and labels, and the route built from them (voyage time, track, per-leg p_f, largest
and voyage p_f), must be the same to the bit, on random small problems (patches and gridded weather, steady and
time-varying, apf < 1, with waits, with side labels, with pruning) and on the example scenarios at apf 0.2 and 0.02.
"""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import pyroute_rel.routing.cost as cost_module
from pyroute_rel.boat.manoeuvre import ManoeuvrePenalties
from pyroute_rel.boat.polar import get_polar
from pyroute_rel.reliability.failure import load_failure_model
from pyroute_rel.routing import solve
from pyroute_rel.routing.cost import geometry_costs
from pyroute_rel.routing.grid import make_grid
from pyroute_rel.routing.route import build_route
from pyroute_rel.routing.solve import RoutingProblem, forward_dp
from pyroute_rel.scenario import load_scenario, scenario_from_mapping
from pyroute_rel.settings import settings_context
from pyroute_rel.weather import GriddedWeather, Patch, UniformWeather, WeatherField

ROOT = Path(__file__).resolve().parents[1]
DEP = np.datetime64("2018-06-01T00:00:00")
MODELS = {name: load_failure_model(name) for name in ("dickson2018", "wind_wave_multistate")}
POLAR = get_polar("maribot_vane")
#: apf below every p_f of the tables, between them, and just under 1
APFS = (0.0, 0.02, 0.2, 0.5, 0.95)


def props(n: int) -> settings:
    return settings(max_examples=n, derandomize=True, deadline=None, database=None)


def counting(monkeypatch_or_context: pytest.MonkeyPatch) -> list[int]:
    """Count the arcs judged on pieces (passed to :func:`~pyroute_rel.reliability.crossings.arc_extremes` by the cost
    module)."""
    seen = [0]
    real = cost_module.arc_extremes

    def wrapper(a_xyz, *args, **kw):  # type: ignore[no-untyped-def]
        seen[0] += len(a_xyz)
        return real(a_xyz, *args, **kw)

    monkeypatch_or_context.setattr(cost_module, "arc_extremes", wrapper)
    return seen


def eager_and_lazy(grid, problem: RoutingProblem) -> tuple[solve.DPResult, solve.DPResult]:
    with settings_context(lazy_pieces=False):
        eager = forward_dp(grid, problem)
    return eager, forward_dp(grid, problem)


def assert_same_dp(eager: solve.DPResult, lazy: solve.DPResult, *, counts: bool = True) -> None:
    np.testing.assert_array_equal(lazy.arrival_h, eager.arrival_h)
    np.testing.assert_array_equal(lazy.back, eager.back)
    assert (lazy.finish_h, lazy.finish_back, lazy.dead_rank) == (eager.finish_h, eager.finish_back, eager.dead_rank)
    assert (lazy.wait_h is None) == (eager.wait_h is None)
    if eager.wait_h is not None:
        np.testing.assert_array_equal(lazy.wait_h, eager.wait_h)
    assert (lazy.labels is None) == (eager.labels is None)
    if eager.labels is not None:
        for name in ("arrival_h", "back", "from_side"):
            np.testing.assert_array_equal(getattr(lazy.labels, name), getattr(eager.labels, name))
        assert (lazy.labels.finish_side, lazy.labels.finish_from) == (
            eager.labels.finish_side,
            eager.labels.finish_from,
        )
    if not counts:
        return
    assert lazy.arcs_evaluated == eager.arcs_evaluated and lazy.arcs_pruned == eager.arcs_pruned
    # fewer arcs are judged on pieces: the counts of arcs forbidden cover those judged (never more than eagerly)
    assert lazy.arcs_forbidden <= eager.arcs_forbidden
    # with waits an arc counts as forbidden (under all its reasons) only when every departure tried is forbidden: an
    # arc left unjudged at one departure counts as allowed there, so its other reasons may go uncounted too
    waits = eager.wait_h is not None
    for name, n in lazy.forbidden_by_reason.items():
        if name == "failure" or waits:
            assert n <= eager.forbidden_by_reason[name]
        else:
            assert n == eager.forbidden_by_reason[name]


def assert_same_route(grid, problem: RoutingProblem, eager: solve.DPResult, lazy: solve.DPResult) -> None:
    if not np.isfinite(eager.finish_h):
        return
    a, b = build_route(grid, problem, eager), build_route(grid, problem, lazy)
    assert b.voyage_time_h == a.voyage_time_h
    np.testing.assert_array_equal(b.lon_deg, a.lon_deg)
    np.testing.assert_array_equal(b.lat_deg, a.lat_deg)
    np.testing.assert_array_equal(b.legs.p_f, a.legs.p_f)
    assert b.max_failure_probability == a.max_failure_probability
    assert b.voyage_failure_probability == a.voyage_failure_probability


# --- random problems ---------------------------------------------------------------------------------------------


@st.composite
def wave_patches(draw: st.DrawFn) -> Patch:
    """A box of waves about the test course (heights either side of the 4 m criterion, any direction)."""
    lo0, la0 = draw(st.floats(-22.0, -12.0)), draw(st.floats(38.0, 45.0))
    lo1, la1 = lo0 + draw(st.floats(0.3, 4.0)), la0 + draw(st.floats(0.3, 3.0))
    values = {"hs_m": draw(st.sampled_from([1.0, 3.5, 4.0, 6.0]))}
    if draw(st.booleans()):
        values["wave_dir_deg"] = draw(st.floats(0.0, 359.0))
    return Patch(lon=(lo0, lo1), lat=(la0, la1), values=values)


@st.composite
def course(draw: st.DrawFn, *, wide: bool = False):  # type: ignore[no-untyped-def]
    start = (draw(st.floats(-14.0, -11.0)), draw(st.floats(43.0, 46.0)))
    finish = (draw(st.floats(-22.0, -18.0)), draw(st.floats(38.0, 41.0)))
    if wide:  # all-to-all arcs, wider than solve.PRUNE_MIN_WIDTH: the DP prunes
        n_ranks, n_nodes = draw(st.integers(2, 4)), draw(st.integers(33, 40))
        return make_grid(start, finish, n_ranks=n_ranks, n_nodes=n_nodes, spacing_km=draw(st.floats(8.0, 30.0)))
    return make_grid(
        start,
        finish,
        n_ranks=draw(st.integers(2, 9)),
        n_nodes=draw(st.integers(3, 11)),
        spacing_km=draw(st.floats(15.0, 80.0)),
        max_deviation_deg=draw(st.none() | st.floats(30.0, 70.0)),
    )


@st.composite
def patch_weather(draw: st.DrawFn) -> UniformWeather:
    return UniformWeather(
        tws_kn=draw(st.floats(8.0, 25.0)),
        twd_deg=draw(st.floats(0.0, 359.0)),
        hs_m=draw(st.sampled_from([1.0, 2.0, 4.5])),
        wave_dir_deg=draw(st.floats(0.0, 359.0)),
        patches=tuple(draw(st.lists(wave_patches(), min_size=1, max_size=4))),
    )


@st.composite
def gridded_weather(draw: st.DrawFn, *, timed: bool) -> GriddedWeather:
    """Wind, waves and wave direction on a 1 deg grid (every 6 h over 4 days, or steady), from a drawn seed."""
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    lon, lat = np.arange(-26.0, -7.99, 1.0), np.arange(35.0, 49.01, 1.0)
    time = DEP.astype("datetime64[ns]") + np.arange(17) * np.timedelta64(6, "h") if timed else None
    shape = (17 if timed else 1, lat.size, lon.size)
    u = rng.uniform(-9.0, 9.0, shape)
    v = rng.uniform(-9.0, 9.0, shape)
    hs = np.clip(rng.normal(3.5, 1.5, shape), 0.0, None)
    wd = rng.uniform(0.0, 360.0, shape)

    def fld(name: str, values: np.ndarray) -> WeatherField:
        return WeatherField(name, values.astype(np.float32), lon, lat, time, source="test", variable=name)

    return GriddedWeather([fld("wind_u_ms", u), fld("wind_v_ms", v), fld("hs_m", hs), fld("wave_dir_deg", wd)])


def problem_of(draw: st.DrawFn, weather, **kw) -> RoutingProblem:  # type: ignore[no-untyped-def]
    return RoutingProblem(
        departure=DEP,
        weather=weather,
        polar=POLAR,
        failure=MODELS[draw(st.sampled_from(sorted(MODELS)))],
        apf=draw(st.sampled_from(APFS)),
        samples=draw(st.integers(1, 4)),
        **kw,
    )


@pytest.mark.slow
@props(15)
@given(data=st.data())
def test_lazy_equals_eager_with_patches(data: st.DataObject) -> None:
    grid = data.draw(course())
    problem = problem_of(data.draw, data.draw(patch_weather()))
    eager, lazy = eager_and_lazy(grid, problem)
    assert_same_dp(eager, lazy)
    assert_same_route(grid, problem, eager, lazy)


@pytest.mark.slow
@props(30)
@given(data=st.data())
def test_lazy_equals_eager_on_gridded_weather(data: st.DataObject) -> None:
    grid = data.draw(course())
    problem = problem_of(data.draw, data.draw(gridded_weather(timed=data.draw(st.booleans()))))
    eager, lazy = eager_and_lazy(grid, problem)
    assert_same_dp(eager, lazy)
    assert_same_route(grid, problem, eager, lazy)


@pytest.mark.slow
@props(15)
@given(data=st.data())
def test_lazy_equals_eager_with_waits(data: st.DataObject) -> None:
    """Each wait tried costs the arcs at another departure: the best arc of each wait is judged."""
    grid = data.draw(course())
    step = data.draw(st.sampled_from([1.0, 3.0, 6.0]))
    weather = data.draw(gridded_weather(timed=True))
    problem = problem_of(data.draw, weather, time_step_h=step, max_wait_h=step * data.draw(st.integers(1, 3)))
    eager, lazy = eager_and_lazy(grid, problem)
    assert_same_dp(eager, lazy)
    assert_same_route(grid, problem, eager, lazy)


@pytest.mark.slow
@props(25)
@given(data=st.data())
def test_lazy_equals_eager_with_side_labels(data: st.DataObject) -> None:
    """Manoeuvre penalties: the best arc into each label is judged; steady weather shares the costs (and what is
    judged) between the two source labels."""
    grid = data.draw(course())
    timed = data.draw(st.sampled_from([None, False, True]))
    weather = data.draw(patch_weather()) if timed is None else data.draw(gridded_weather(timed=timed))
    penalties = ManoeuvrePenalties(
        tack_s=[[0.0, data.draw(st.floats(60.0, 4e4))], [25.0, data.draw(st.floats(60.0, 4e4))]],
        gybe_s=[[5.0, data.draw(st.floats(60.0, 4e4))], [20.0, data.draw(st.floats(60.0, 4e4))]],
    )
    problem = problem_of(
        data.draw, weather, manoeuvres=penalties, initial_side=data.draw(st.sampled_from([None, 0, 1]))
    )
    eager, lazy = eager_and_lazy(grid, problem)
    assert lazy.labels is not None
    assert_same_dp(eager, lazy)
    assert_same_route(grid, problem, eager, lazy)


@pytest.mark.slow
@props(12)
@given(data=st.data())
def test_lazy_equals_eager_when_the_dp_prunes(data: st.DataObject) -> None:
    """All-to-all arcs: the four most promising arcs of each node are costed and the best of them judged before
    the others are bounded by it."""
    grid = data.draw(course(wide=True))
    problem = problem_of(data.draw, data.draw(patch_weather()))
    eager, lazy = eager_and_lazy(grid, problem)
    assert_same_dp(eager, lazy)
    assert_same_route(grid, problem, eager, lazy)


@pytest.mark.slow
@pytest.mark.parametrize("apf", [0.2, 0.02])
def test_lazy_equals_eager_with_land_tested_lazily(apf: float) -> None:
    """The control course with land (the obstacle mask is tested lazily too): each node's best arc must be free of
    land and allowed on its pieces, whichever is found first."""
    sc = load_scenario(ROOT / "examples" / "microtransat_control.toml").with_options(apf=apf, n_ranks=20)
    grid = sc.make_grid()
    problem = sc.problem(grid=grid)
    assert problem.blocked is not None
    eager, lazy = eager_and_lazy(grid, problem)
    assert eager.forbidden_by_reason["obstacle"] > 0 and eager.forbidden_by_reason["failure"] > 0
    assert_same_dp(eager, lazy)
    assert_same_route(grid, problem, eager, lazy)


# --- how many arcs are judged --------------------------------------------------------------------------------------


@pytest.mark.slow
def test_far_fewer_arcs_are_judged_on_pieces() -> None:
    """The ERA5 example (gridded, time-varying) at apf 0.2 on 30 ranks: a hook sees every arc's costs, so the DP
    then judges on pieces every arc that may need it (the eager reference); without one, at most a tenth of them."""
    sc = load_scenario(ROOT / "examples" / "microtransat_era5.toml").with_options(apf=0.2, n_ranks=30)
    grid = sc.make_grid()
    problem = sc.problem(grid=grid)
    with pytest.MonkeyPatch.context() as mp:
        seen = counting(mp)
        eager = forward_dp(grid, problem, cost_hook=lambda k, c: None)
        n_eager = seen[0]
        seen[0] = 0
        lazy = forward_dp(grid, problem)
        n_lazy = seen[0]
    assert n_eager > 1000
    assert 0 < n_lazy * 10 <= n_eager, (n_lazy, n_eager)
    assert_same_dp(eager, lazy, counts=False)  # the hook also turns pruning off


def test_a_cost_hook_sees_every_arc_judged_on_pieces() -> None:
    """With a hook the costs it sees are the eager ones: every arc's time (inf where forbidden, on its pieces
    included) and p_f equal the cost function's on the same geometry."""
    sc = load_scenario(ROOT / "examples" / "microtransat_control.toml").with_options(apf=0.2, n_ranks=12, land=False)
    grid = sc.make_grid()
    problem = sc.problem(grid=grid)
    seen: dict[int, Any] = {}
    result = forward_dp(grid, problem, cost_hook=lambda k, c: seen.setdefault(k, c))
    judged = 0
    for k in range(1, grid.n_ranks):
        src, valid = grid.pattern(k)
        t0 = result.arrival_h[k - 1][src]
        live = valid & np.isfinite(t0)
        ref = geometry_costs(
            solve.grid_geometry(grid, k, problem.samples), np.where(live, t0, 0.0), **problem._cost_options()
        )
        got = seen[k]
        np.testing.assert_array_equal(got.time_h[live], ref.time_h[live])
        np.testing.assert_array_equal(got.p_f[live], ref.p_f[live])
        judged += int(np.count_nonzero(live & (ref.reason != 0)))
    assert judged > 0


# --- the examples --------------------------------------------------------------------------------------------------

EXAMPLES = ["microtransat_control", "microtransat_beat", "microtransat_run", "microtransat_era5"]


@pytest.mark.slow
@pytest.mark.parametrize(("name", "apf"), [*((n, 0.2) for n in EXAMPLES), ("microtransat_control", 0.02)])
def test_examples_route_the_same(name: str, apf: float) -> None:
    sc = load_scenario(ROOT / "examples" / f"{name}.toml").with_options(apf=apf)
    grid = sc.make_grid()
    problem = sc.problem(grid=grid)
    eager, lazy = eager_and_lazy(grid, problem)
    assert_same_dp(eager, lazy)
    assert_same_route(grid, problem, eager, lazy)


@pytest.mark.slow
@pytest.mark.parametrize("apf", [0.2, 0.02])
def test_ensemble_member_routes_the_same(apf: float) -> None:
    pytest.importorskip("xarray")
    if not (ROOT / "examples" / "data" / "ensemble_synthetic.nc").exists():
        pytest.skip("examples/data/ensemble_synthetic.nc: run examples/make_ensemble_example.py")
    path = ROOT / "examples" / "ensemble.toml"
    table = tomllib.loads(path.read_text())
    table["weather"]["member"] = 3
    sc = scenario_from_mapping(table, base_dir=path.parent, source=str(path)).with_options(apf=apf)
    grid = sc.make_grid()
    problem = sc.problem(grid=grid)
    eager, lazy = eager_and_lazy(grid, problem)
    assert_same_dp(eager, lazy)
    assert_same_route(grid, problem, eager, lazy)
