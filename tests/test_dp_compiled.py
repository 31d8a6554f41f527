"""The compiled rank step (pyroute_rel.dp_compiled) is bit-identical to the numpy path of the DP (issue 18)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import pyroute_rel.dp_compiled as dp_compiled
import pyroute_rel.solve as solve
from pyroute_rel.grid import make_grid
from pyroute_rel.manoeuvre import ManoeuvrePenalties
from pyroute_rel.polar import Polar
from pyroute_rel.weather import Patch, UniformWeather
from tests.test_properties import NaNBox
from tests.test_solve import DEP, FINISH_PT, START_PT, random_polar, random_weather


def both(grid, problem, monkeypatch: pytest.MonkeyPatch) -> tuple[solve.DPResult, solve.DPResult]:
    compiled = solve.forward_dp(grid, problem)
    monkeypatch.setattr(solve, "COMPILED_RANK_STEP", False)
    numpy_path = solve.forward_dp(grid, problem)
    monkeypatch.setattr(solve, "COMPILED_RANK_STEP", True)
    return compiled, numpy_path


def assert_same(a: solve.DPResult, b: solve.DPResult, *, counts: bool = True) -> None:
    """Equal results, bit for bit; ``counts``: and the same arcs costed and forbidden (not when pruning differs)."""
    np.testing.assert_array_equal(a.arrival_h, b.arrival_h)  # bit for bit (NaN-free: inf where unreachable)
    np.testing.assert_array_equal(a.back, b.back)
    assert (a.labels is None) == (b.labels is None)
    if a.labels is not None and b.labels is not None:
        for name in ("arrival_h", "back", "from_side"):
            np.testing.assert_array_equal(getattr(a.labels, name), getattr(b.labels, name))
        assert (a.labels.finish_side, a.labels.finish_from) == (b.labels.finish_side, b.labels.finish_from)
    assert a.finish_h == b.finish_h or (np.isnan(a.finish_h) and np.isnan(b.finish_h))
    assert a.finish_back == b.finish_back and a.dead_rank == b.dead_rank
    if counts:
        assert a.arcs_evaluated == b.arcs_evaluated
        assert a.arcs_forbidden == b.arcs_forbidden and a.forbidden_by_reason == b.forbidden_by_reason


@settings(max_examples=25, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    n_ranks=st.integers(1, 12),
    n_nodes=st.sampled_from([1, 3, 9, 40, 47]),
    samples=st.integers(1, 4),
    beyond=st.sampled_from(["clamp", "forbid"]),
    prune=st.booleans(),
    hole=st.booleans(),
    sides=st.sampled_from([None, -1, 0, 1]),
)
def test_compiled_rank_step_equals_numpy(
    seed: int, n_ranks: int, n_nodes: int, samples: int, beyond: str, prune: bool, hole: bool, sides: int | None
) -> None:
    """Random polars, winds with patches (calms, wind beyond the table, a NaN hole), square grids with and without
    pruning, with and without manoeuvre penalties (side labels; starting on either side or a given one): arrival
    times, back-pointers, labels and forbidden counts are equal, bit for bit."""
    rng = np.random.default_rng(seed)
    weather = random_weather(rng)
    if hole:  # missing wind in a box: the arcs through it are forbidden for the weather
        weather = NaNBox(
            base=weather, lon=(-40.0, -30.0), lat=(25.0, 40.0), nan_fields=("tws_kn", "twd_deg")[: seed % 2 + 1]
        )
    grid = make_grid(START_PT, FINISH_PT, n_ranks=n_ranks, n_nodes=n_nodes, spacing_km=float(rng.uniform(20, 150)))
    problem = solve.RoutingProblem(
        departure=DEP, weather=weather, polar=random_polar(rng), samples=samples, beyond=beyond, prune=prune
    )
    if sides is not None:
        penalties = ManoeuvrePenalties(tack_s=[[0.0, float(rng.uniform(0, 2e4))], [20.0, float(rng.uniform(0, 2e4))]],
                                       gybe_s=[[8.0, float(rng.uniform(1, 2e4))]])  # fmt: skip
        problem = replace(problem, manoeuvres=penalties, initial_side=None if sides < 0 else sides)
    with pytest.MonkeyPatch.context() as mp:
        compiled, numpy_path = both(grid, problem, mp)
    # the same arcs costed unless pruned (ties may pick others, and side labels are pruned by the compiled step only)
    assert_same(compiled, numpy_path, counts=not prune or n_nodes <= solve.PRUNE_MIN_WIDTH)


def test_compiled_step_serves_only_steady_wind_only_problems(monkeypatch: pytest.MonkeyPatch) -> None:
    """With a current the numpy path runs (the compiled step knows wind only); the results agree anyway."""
    grid = make_grid(START_PT, FINISH_PT, n_ranks=6, n_nodes=9)
    rng = np.random.default_rng(3)
    problem = solve.RoutingProblem(departure=DEP, weather=random_weather(rng), polar=random_polar(rng))
    assert solve._Pricing.of(problem, None, finish_line=False).compiled
    flowing = replace(problem, weather=UniformWeather(tws_kn=12.0, twd_deg=10.0, current_u_ms=0.3))
    assert not solve._Pricing.of(flowing, None, finish_line=False).compiled
    a, b = both(grid, flowing, monkeypatch)
    assert_same(a, b)


@pytest.mark.parametrize("seed", [1, 2])
def test_compiled_step_on_corridors_equals_numpy(seed: int, monkeypatch: pytest.MonkeyPatch) -> None:
    """Refinement's corridor grids (wide enough to prune) have nodes with fewer live arcs than the four pruning
    costs first (a regression: the costs of the next nodes' arcs were then read from the wrong slots; seed 1 found
    it): each level's DP through the compiled step gives the numpy path's result, bit for bit."""
    from pyroute_rel.refine import refine

    rng = np.random.default_rng(seed)
    grid = make_grid(START_PT, FINISH_PT, n_ranks=15, n_nodes=41, spacing_km=25.0, max_deviation_deg=45.0)
    problem = solve.RoutingProblem(departure=DEP, weather=random_weather(rng), polar=random_polar(rng), samples=2)
    corridors = []
    with monkeypatch.context() as mp:
        mp.setattr(solve, "grid_geometry", lambda g, k, n, f=solve.grid_geometry: corridors.append(g) or f(g, k, n))
        refine(grid, problem, solve.forward_dp(grid, problem), levels=3)
    seen = list({id(g): g for g in corridors if g is not grid}.values())
    assert len(seen) >= 2 and seen[0].pattern(1)[1].shape[1] > solve.PRUNE_MIN_WIDTH
    for c in seen:
        compiled, numpy_path = both(c, problem, monkeypatch)
        assert_same(compiled, numpy_path, counts=False)


def _wind_patches(rng: np.random.Generator, n: int) -> tuple[Patch, ...]:
    """``n`` overlapping patches about the course, each setting the wind's speed, its direction, both, or neither
    (waves only)."""
    which = [("tws_kn",), ("twd_deg",), ("tws_kn", "twd_deg"), ("hs_m",)]
    out = []
    for _ in range(n):
        lo, la = float(rng.uniform(-55, -25)), float(rng.uniform(20, 38))
        values = {"tws_kn": float(rng.uniform(0.5, 35)), "twd_deg": float(rng.uniform(0, 360)), "hs_m": 3.0}
        keys = which[int(rng.integers(len(which)))]
        out.append(Patch(lon=(lo, lo + rng.uniform(2, 15)), lat=(la, la + rng.uniform(2, 12)),
                         values={k: values[k] for k in keys}))  # fmt: skip
    return tuple(out)


@settings(max_examples=20, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    samples=st.integers(1, 3),
    beyond=st.sampled_from(["clamp", "forbid"]),
    first_twa=st.sampled_from([0.0, 30.0]),
    first_tws=st.sampled_from([0.0, 6.0]),
)
def test_uniform_wind_in_the_kernel_equals_numpy(
    seed: int, samples: int, beyond: str, first_twa: float, first_tws: float
) -> None:
    """UniformWeather's wind sampled in the kernel (a pruned rank in one compiled call): patches setting the speed
    only, the direction only, both or neither, overlapping; light air below the polar's first column (its speed
    scaled down), a no-go zone below its first row, winds beyond its last column (forbidden or clamped): the numpy
    path's arrivals and back-pointers, bit for bit, and that path was taken."""
    rng = np.random.default_rng(seed)
    twa = np.array([first_twa, 45.0, 60.0, 90.0, 120.0, 150.0, 180.0])
    tws = np.array([first_tws, 10.0, 16.0, 24.0])
    speed = rng.uniform(0.5, 8.0, (twa.size, tws.size))
    polar = Polar(name="random", twa_deg=twa, tws_kn=tws, speed_kn=speed)
    weather = UniformWeather(tws_kn=float(rng.uniform(1, 22)), twd_deg=float(rng.uniform(0, 360)),
                             patches=_wind_patches(rng, int(rng.integers(0, 5))))  # fmt: skip
    grid = make_grid(START_PT, FINISH_PT, n_ranks=6, n_nodes=41, spacing_km=float(rng.uniform(30, 120)))
    problem = solve.RoutingProblem(departure=DEP, weather=weather, polar=polar, samples=samples, beyond=beyond)
    calls = []
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(dp_compiled, "_boxed_rank", lambda *a, f=dp_compiled._boxed_rank: calls.append(1) or f(*a))
        compiled, numpy_path = both(grid, problem, mp)
    # the arcs into ranks 1 to n_ranks (the finish: 41 a node, pruned), or up to the rank none reaches
    assert len(calls) == (grid.n_ranks if compiled.dead_rank is None else compiled.dead_rank)
    assert_same(compiled, numpy_path, counts=False)


def test_box_wind_is_uniform_weathers() -> None:
    """The wind the kernels sample from UniformWeather.wind_boxes is what UniformWeather.sample gives, at random
    points, on the patches' edges and corners (closed boxes) and at NaN points."""
    rng = np.random.default_rng(5)
    weather = UniformWeather(tws_kn=12.0, twd_deg=80.0, patches=_wind_patches(rng, 6))
    edges = np.array([v for p in weather.patches for v in (*p.lon, *p.lat)])
    lon = np.concatenate([rng.uniform(-60, -10, 4000), rng.choice(edges, 500), [np.nan, 0.0]])
    lat = np.concatenate([rng.uniform(15, 55, 4000), rng.choice(edges, 500), [0.0, np.nan]])
    want = weather.sample(lon, lat, DEP)
    tws0, twd0, boxes, values = weather.wind_boxes()
    tws, twd = np.empty(lon.size), np.empty(lon.size)
    dp_compiled._box_wind_all(lon, lat, tws0, twd0, boxes, values, tws, twd)
    np.testing.assert_array_equal(tws, want.tws_kn)
    np.testing.assert_array_equal(twd, want.twd_deg)
    assert boxes.shape[0] == sum("tws_kn" in p.values or "twd_deg" in p.values for p in weather.patches)
