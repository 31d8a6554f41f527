"""The compiled rank step (pyroute_rel._kernels.dp) is bit-identical to the numpy path of the DP (issue 18)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import pyroute_rel._kernels.dp as dp_compiled
import pyroute_rel.routing.solve as solve
from pyroute_rel.boat.manoeuvre import ManoeuvrePenalties, wind_side
from pyroute_rel.boat.polar import Polar
from pyroute_rel.routing.grid import make_grid
from pyroute_rel.settings import settings_context
from pyroute_rel.weather import Patch, UniformWeather
from tests.test_properties import NaNBox
from tests.test_solve import DEP, FINISH_PT, START_PT, random_polar, random_weather


def both(grid, problem, monkeypatch: pytest.MonkeyPatch) -> tuple[solve.DPResult, solve.DPResult]:
    compiled = solve.forward_dp(grid, problem)
    with settings_context(compiled_rank_step=False):
        numpy_path = solve.forward_dp(grid, problem)
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


@pytest.mark.slow
@settings(max_examples=12, deadline=None)
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
    from pyroute_rel.routing.refine import refine

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


@pytest.mark.slow
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


def _random_penalties(rng: np.random.Generator) -> ManoeuvrePenalties:
    """Tack and gybe tables of one to three rows, with zero penalties in part of the wind range (so that changing
    side or not, or leaving from either label, often ties)."""

    def table() -> list[list[float]]:
        tws = np.sort(rng.choice(np.arange(0.0, 30.0, 2.5), int(rng.integers(1, 4)), replace=False))
        return [[float(w), float(rng.choice([0.0, rng.uniform(1, 2e4)]))] for w in tws]

    p = ManoeuvrePenalties(tack_s=table(), gybe_s=table())
    return p if p.active else ManoeuvrePenalties(tack_s=[[0.0, 60.0]], gybe_s=table())


@pytest.mark.slow
@settings(max_examples=12, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    samples=st.integers(1, 3),
    beyond=st.sampled_from(["clamp", "forbid"]),
    prune=st.booleans(),
    n_nodes=st.sampled_from([9, 41]),
    initial=st.sampled_from([None, 0, 1]),
    first_tws=st.sampled_from([0.0, 6.0]),
)
def test_side_labels_with_uniform_wind_in_the_kernel_equal_numpy_and_the_sampled_kernel(
    seed: int, samples: int, beyond: str, prune: bool, n_nodes: int, initial: int | None, first_tws: float
) -> None:
    """Side labels on UniformWeather in one compiled call a rank (_boxed_sides_rank): random polars (light air below
    the first column, a no-go zone, winds beyond the last column), random tack and gybe tables, overlapping patches
    setting the speed, the direction, both or neither, with and without pruning, starting on either side or a given
    one: the numpy path's labels, arrivals and back-pointers, bit for bit, and the kernel that samples the wind at
    every arc first (_rank_kernel, the compiled path before it) arc for arc: the same arcs costed, pruned and
    forbidden. And that path was taken for every rank."""
    rng = np.random.default_rng(seed)
    twa = np.array([30.0, 45.0, 60.0, 90.0, 120.0, 150.0, 180.0])
    tws = np.array([first_tws, 10.0, 16.0, 24.0])
    polar = Polar(name="random", twa_deg=twa, tws_kn=tws, speed_kn=rng.uniform(0.5, 8.0, (twa.size, tws.size)))
    weather = UniformWeather(tws_kn=float(rng.uniform(1, 22)), twd_deg=float(rng.uniform(0, 360)),
                             patches=_wind_patches(rng, int(rng.integers(0, 5))))  # fmt: skip
    grid = make_grid(START_PT, FINISH_PT, n_ranks=6, n_nodes=n_nodes, spacing_km=float(rng.uniform(30, 120)))
    problem = solve.RoutingProblem(departure=DEP, weather=weather, polar=polar, samples=samples, beyond=beyond,
                                   prune=prune, manoeuvres=_random_penalties(rng), initial_side=initial)  # fmt: skip
    assert problem.sides
    calls = []
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(
            dp_compiled, "_boxed_sides_rank", lambda *a, f=dp_compiled._boxed_sides_rank: calls.append(1) or f(*a)
        )
        compiled, numpy_path = both(grid, problem, mp)
        n_calls = len(calls)
        of = solve._Pricing.of  # the wind sampled at every arc by the weather, then _rank_kernel
        mp.setattr(solve._Pricing, "of", lambda *a, **k: replace(of(*a, **k), wind_boxes=None))
        sampled = solve.forward_dp(grid, problem)
    assert n_calls == (grid.n_ranks if compiled.dead_rank is None else compiled.dead_rank) + 1  # the finish too
    assert len(calls) == n_calls  # the sampled path did not call it
    assert_same(compiled, numpy_path, counts=not prune or n_nodes <= solve.PRUNE_MIN_WIDTH)
    assert_same(compiled, sampled)


@pytest.mark.slow
@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10_000), n_patches=st.integers(0, 4), twd=st.sampled_from([0.0, 90.0, 250.0, 359.5, -30.0]))
def test_box_sides_are_wind_side(seed: int, n_patches: int, twd: float) -> None:
    """The side each arc is sailed on, from the kernel's wind at the first sample (_box_sides), is
    manoeuvre.wind_side of the wind UniformWeather.sample gives there: at node 0 courses within a turn of the wind
    (its quick path: random, dead up- and downwind, a hair either side), at node 1 any (a turn away, beyond, NaN,
    infinite: the exact path); and _wind_rel is numpy.mod(x, 360)."""
    rng = np.random.default_rng(seed)
    weather = UniformWeather(tws_kn=12.0, twd_deg=twd, patches=_wind_patches(rng, n_patches))
    tws0, twd0, boxes, values = weather.wind_boxes()
    n = 600
    lon, lat = rng.uniform(-60, -15, n), rng.uniform(15, 45, n)
    wind = weather.sample(lon, lat, DEP).twd_deg
    near = np.concatenate([rng.uniform(-359, 359, n - 100), rng.choice([0.0, 180.0, -180.0, 1e-13, -1e-13], 100)])
    edges = [0.0, 180.0, -180.0, 360.0, -360.0, 1e-300, -1e-300, 1e-13, -1e-13]
    anyhow = np.concatenate([rng.uniform(-720, 1080, 200), wind[200:500] - rng.choice(edges, 300),
                             rng.choice([np.nan, np.inf, -np.inf, 0.0, -0.0, 360.0, 720.0], 100)])  # fmt: skip
    course = np.stack([wind - near, anyhow])[:, :, None]  # (nodes, arcs, samples)
    lon3, lat3 = (np.ascontiguousarray(np.broadcast_to(a[None, :, None], course.shape)) for a in (lon, lat))
    for d in (0, 1):
        side = np.full(n, 7, dtype=np.int8)
        dp_compiled._box_sides(d, course, lon3, lat3, twd0, boxes, values, side)
        with np.errstate(invalid="ignore"):  # infinite courses: NaN angles
            np.testing.assert_array_equal(side, wind_side(wind, course[d, :, 0])[0])
    x = np.concatenate([twd0 - course.ravel(), [-1e-300, -0.0, 0.0, -360.0, 360.0, -1e-14, 359.99999999999994]])
    with np.errstate(invalid="ignore"):
        np.testing.assert_array_equal([dp_compiled._wind_rel(v) for v in x], np.mod(x, 360.0))


@pytest.mark.slow
@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    k=st.integers(0, 4),
    samples=st.integers(1, 3),
    beyond=st.sampled_from(["clamp", "forbid"]),
    prune=st.booleans(),
    n_nodes=st.sampled_from([9, 41]),
    from_sides=st.sampled_from([(-1,), (0,), (1,), (0, 1)]),
)
def test_boxed_sides_rank_equals_the_sampled_kernel_on_ties(
    seed: int, k: int, samples: int, beyond: str, prune: bool, n_nodes: int, from_sides: tuple[int, ...]
) -> None:
    """One rank with side labels, departures drawn to tie (both labels of a node reached at the same time, whole
    hours, unreached labels), penalties zero in part of the wind range (arrivals over an arc from either label
    tie) and some arcs twice (arrivals over two arcs tie): the rank in one compiled call (BoxWind) gives what the
    weather's wind sampled at every arc and _rank_kernel give, label for label: arrivals, arcs and source labels
    (first of equal ones), and the arcs costed and forbidden."""
    rng = np.random.default_rng(seed)
    weather = UniformWeather(tws_kn=float(rng.uniform(1, 22)), twd_deg=float(rng.uniform(0, 360)),
                             patches=_wind_patches(rng, int(rng.integers(0, 4))))  # fmt: skip
    grid = make_grid(START_PT, FINISH_PT, n_ranks=4, n_nodes=n_nodes, spacing_km=float(rng.uniform(30, 120)))
    problem = solve.RoutingProblem(departure=DEP, weather=weather, polar=random_polar(rng), samples=samples,
                                   beyond=beyond, manoeuvres=_random_penalties(rng))  # fmt: skip
    src, valid = grid.pattern(k)
    geom = solve.grid_geometry(grid, k, samples)
    shape = valid.shape + (samples,)
    n_src = grid.start_points[0].size if k == 0 else grid.n_nodes
    t_prev = rng.choice([np.inf, 0.0, 1.0, 2.0, 3.0, float(rng.uniform(0, 3))], (n_src, len(from_sides)))
    same = rng.random(n_src) < 0.5
    t_prev[same] = t_prev[same, :1]  # both labels at once
    lon, lat, course = (np.array(np.broadcast_to(a, shape)) for a in (geom.lon_deg, geom.lat_deg, geom.course_deg))
    seg, src, valid = (np.array(np.broadcast_to(a, valid.shape)) for a in (geom.seg_nm[..., 0], src, valid))
    width = valid.shape[1]
    to, of = rng.integers(0, width, (2, width // 3 + 1))
    for a in (lon, lat, course, seg, src, valid):  # some arcs twice: arrivals over different arcs tie
        a[:, to] = a[:, of]

    def sampled(pick: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        at = [a if pick is None else a.reshape(-1, samples)[pick] for a in (lon, lat)]
        c = weather.sample(*at, DEP)
        return c.tws_kn, c.twd_deg

    bound = problem.speed_bound_kn() if prune else None
    steps = [
        dp_compiled.rank_step(
            w,
            course,
            seg,
            t_prev,
            src,
            valid,
            problem.polar,
            beyond=beyond,
            bound_kn=bound,
            from_sides=from_sides,
            penalties=problem.manoeuvres,
        )  # fmt: skip
        for w in (dp_compiled.BoxWind(*weather.wind_boxes(), lon, lat), sampled)
    ]
    for a, b in zip(*steps, strict=True):
        np.testing.assert_array_equal(a, b)
