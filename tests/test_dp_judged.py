"""Judgements kept between DPs (:class:`pyroute_rel._kernels.dp.Judged`): in steady weather an arc's judgement by a
failure model does not depend on time, so the compiled step keeps, per grid, samples per arc and fields (weather,
model, apf), each arc's judgement at its samples and on its pieces, and takes it in later DPs instead of judging
again. A DP with judgements kept finds exactly what a DP judging afresh finds (``with kept(False)``), rank by rank
and counts included, whatever DP filled them; and each kept input changed between two calls gets the fresh answer,
where the judgements kept for the other input would have given another one (:func:`held`)."""

from __future__ import annotations

import dataclasses
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from test_dp_compiled_failure import MODELS, random_patches

import pyroute_rel._kernels.dp as dp_compiled
from pyroute_rel.boat.polar import Polar, get_polar
from pyroute_rel.routing import solve
from pyroute_rel.routing.grid import Grid, make_grid
from pyroute_rel.routing.solve import DPResult, RoutingProblem, forward_dp
from pyroute_rel.scenario import load_scenario
from pyroute_rel.store import Store, current_store, kept
from pyroute_rel.weather import UniformWeather

ROOT = Path(__file__).resolve().parents[1]
DEP = np.datetime64("2018-06-01T00:00:00")
#: The control example's course on a small square grid (no land: the compiled step judges it).
START, FINISH = (-12.0, 45.0), (-60.0, 17.5)


def example(apf: float = 0.5, n: int = 33) -> tuple[Grid, RoutingProblem]:
    """The control example on the paper's square grid of ``n`` x ``n`` nodes, no land, at ``apf``: its patches forbid
    arcs at their samples and on the pieces they cross (at apf 0.5)."""
    sc = load_scenario(ROOT / "examples" / "microtransat_control.toml").with_options(
        layout="square", n_ranks=n, n_nodes=n, land=False, apf=apf
    )
    return sc.make_grid(), sc.problem()


def warped(s: float) -> Polar:
    """The example's polar, faster upwind and slower downwind by up to ``s`` (a share; negative: the other way): another
    polar takes other arcs."""
    p = get_polar("maribot_vane")
    factor = 1.0 + s * np.cos(np.radians(p.twa_deg))[:, None]
    return Polar(name=f"warped {s:g}", twa_deg=p.twa_deg, tws_kn=p.tws_kn, speed_kn=p.speed_kn * factor)


def judged_in(store: Store) -> list[dp_compiled.Judged]:
    """The judgements kept in ``store``, least recently used first."""
    shelf = store.shelf("dp.judged")
    return [shelf.get(k) for k in shelf.keys()]


def assert_same(a: DPResult, b: DPResult) -> None:
    """Every field of two DP results equal, bit for bit (arrays, counts, the counts by reason and criterion)."""
    for f in dataclasses.fields(DPResult):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, np.ndarray):
            np.testing.assert_array_equal(x, y, err_msg=f.name)
        else:
            assert x == y, f.name


def same(a: DPResult, b: DPResult) -> bool:
    try:
        assert_same(a, b)
    except AssertionError:
        return False
    return True


def cold(grid: Grid, problem: RoutingProblem) -> DPResult:
    """The DP judging every arc afresh (nothing kept)."""
    with kept(False):
        return forward_dp(grid, problem)


@contextmanager
def held(judged: dp_compiled.Judged) -> Iterator[None]:
    """DPs in the block take ``judged`` whatever their grid, samples and fields: what judgements kept under a key
    that missed a change would give."""

    def take(grid: Grid, problem: RoutingProblem, fields: Any, need_bytes: int) -> dp_compiled.Judged:
        assert judged.lock.acquire(blocking=False)
        return judged

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(solve, "_kept_judgements", take)
        yield


def rank_steps(grid: Grid, problem: RoutingProblem) -> list[dp_compiled.RankStep]:
    """The :class:`~pyroute_rel._kernels.dp.RankStep` of every rank the compiled failure step did."""
    steps: list[dp_compiled.RankStep] = []
    real = dp_compiled.rank_step

    def record(*args: Any, **kwargs: Any) -> dp_compiled.RankStep | None:
        out = real(*args, **kwargs)
        if kwargs.get("failure") is not None and out is not None:
            steps.append(out)
        return out

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(dp_compiled, "rank_step", record)
        forward_dp(grid, problem)
    return steps


def assert_same_steps(a: list[dp_compiled.RankStep], b: list[dp_compiled.RankStep]) -> None:
    assert len(a) == len(b) > 0
    for x, y in zip(a, b, strict=True):
        for name, u, v in zip(dp_compiled.RankStep._fields, x, y, strict=True):
            if isinstance(u, np.ndarray):
                np.testing.assert_array_equal(u, v, err_msg=name)
            else:
                assert u == v, name


def test_a_warm_dp_equals_a_cold_one_rank_by_rank() -> None:
    """The example at apf 0.5, where arcs are forbidden at their samples and on their pieces: the second DP, with every
    judgement kept, finds each rank's arrivals, arcs and counters (costed, forbidden, failed, by criterion) of a DP
    that keeps nothing, and the first DP, filling them, does too."""
    grid, problem = example()
    want = cold(grid, problem)
    with kept(False):
        want_steps = rank_steps(grid, problem)
    with kept() as store:
        first_steps = rank_steps(grid, problem)
        (judged,) = judged_in(store)
        states = np.concatenate([s.ravel() for s in judged._ranks.values()])
        assert (states & dp_compiled._FORBID).any() and (states & dp_compiled._OVER).any()  # both kinds forbid
        warm_steps = rank_steps(grid, problem)
        warm = forward_dp(grid, problem)
        assert judged_in(store) == [judged] and not judged.lock.locked()
    assert_same_steps(first_steps, want_steps)
    assert_same_steps(warm_steps, want_steps)
    assert_same(warm, want)
    assert want.forbidden_by_reason["failure"] > 0 and sum(want.forbidden_by_criterion.values()) > 0


def test_judgements_kept_by_another_dp_change_nothing() -> None:
    """Judgements kept by DPs that went another way over the same grid and fields (another polar, which the key
    leaves out: it changes the arcs' times and which arcs are costed and judged, not a judgement): the DP finds and
    counts what it finds alone, so an arc judged by another DP counts only where this one judges it."""
    grid, problem = example()
    other = dataclasses.replace(problem, polar=warped(0.4))
    forbid = dataclasses.replace(problem, beyond="forbid")
    with kept() as store:
        forward_dp(grid, other)
        forward_dp(grid, forbid)
        got = forward_dp(grid, problem)
        assert len(judged_in(store)) == 1
    want = cold(grid, problem)
    assert_same(got, want)
    assert not same(cold(grid, other), want)  # (the other DP did go another way)


def changed(what: str) -> tuple[Grid, RoutingProblem, Grid, RoutingProblem]:
    """The example at apf 0.5, and the same with one kept input changed."""
    grid, problem = example()
    if what == "apf":
        return grid, problem, grid, dataclasses.replace(problem, apf=0.95)
    if what == "model":
        return grid, problem, grid, dataclasses.replace(problem, failure=MODELS["wind_wave_multistate"])
    if what == "weather":  # Area 2's waves below the wave-height criterion
        w = problem.weather
        assert isinstance(w, UniformWeather) and w.patches[0].values == {"hs_m": 4.0}
        patches = (dataclasses.replace(w.patches[0], values={"hs_m": 3.0}), *w.patches[1:])
        return grid, problem, grid, dataclasses.replace(problem, weather=dataclasses.replace(w, patches=patches))
    assert what == "grid"  # the same course and shape, nodes 10 % further apart
    other = make_grid(START, FINISH, n_ranks=grid.n_ranks, n_nodes=grid.n_nodes, spacing_km=1.1 * grid.spacing_km)
    return grid, problem, other, problem


@pytest.mark.parametrize("what", ["apf", "model", "weather", "grid"])
def test_a_changed_input_gets_a_fresh_judgement(what: str) -> None:
    """Each kept input (apf, failure model, the weather's patch values, the grid) changed between two DPs on otherwise
    the same objects: the second finds what a DP keeping nothing finds, and judgements kept for the first would have
    given another answer (the change matters)."""
    grid1, problem1, grid2, problem2 = changed(what)
    with kept() as store:
        first = forward_dp(grid1, problem1)
        second = forward_dp(grid2, problem2)
        assert len(judged_in(store)) == 2
    want = cold(grid2, problem2)
    assert_same(second, want)
    assert_same(first, cold(grid1, problem1))
    with kept() as store:
        forward_dp(grid1, problem1)
        (judged,) = judged_in(store)
        with held(judged):
            stale = forward_dp(grid2, problem2)
    assert not same(stale, want)


def test_nothing_is_kept_when_the_store_keeps_nothing() -> None:
    grid, problem = example()
    with kept(False) as store:
        forward_dp(grid, problem)
        assert judged_in(store) == [] and store.sizes().get("dp.judged", 0) == 0
    with kept() as store:
        forward_dp(grid, problem)
        assert len(judged_in(store)) == 1
    assert "dp.judged" not in store.sizes() or store.sizes()["dp.judged"] == 0  # dropped with its store


def test_judgements_too_big_for_the_memory_are_not_kept(monkeypatch: pytest.MonkeyPatch) -> None:
    """Beyond the shelf's bound, beside the DP's peak beyond the memory budget, or for a model of more criteria than a
    judgement holds, nothing is kept (and the DP finds what it finds)."""
    grid, problem = example()
    want = cold(grid, problem)
    monkeypatch.setattr(solve, "JUDGED_MAX_BYTES", 1000)
    with kept() as store:
        assert_same(forward_dp(grid, problem), want)
        assert judged_in(store) == []
    monkeypatch.undo()
    monkeypatch.setattr(dp_compiled.Judged, "MAX_CRITERIA", 1)  # (dickson2018 has two)
    with kept() as store:
        assert_same(forward_dp(grid, problem), want)
        assert judged_in(store) == []
    monkeypatch.undo()
    monkeypatch.setattr(solve, "budget_bytes", lambda max_memory=None: (1, "a tiny budget"))
    with kept() as store:
        assert_same(forward_dp(grid, problem), want)
        assert judged_in(store) == []
    monkeypatch.undo()
    n = grid.n_nodes
    assert dp_compiled.Judged.BYTES_PER_ARC == 2  # (the figure of the docs: 2 bytes per arc of the compiled ranks)
    with kept() as store:
        forward_dp(grid, problem)
        assert judged_in(store)[0].nbytes == 2 * (n + (n - 1) * n * grid.width + n)  # (from the start, inner, finish)


def test_a_dp_in_another_thread_judges_afresh_while_one_holds_them() -> None:
    """Kernels write judgements without the GIL: a DP takes them only when no other DP holds them, else it judges
    afresh (and finds the same)."""
    grid, problem = example()
    want = cold(grid, problem)
    with kept() as store:
        forward_dp(grid, problem)
        (judged,) = judged_in(store)
        before = {k: s.copy() for k, s in judged._ranks.items()}
        assert judged.lock.acquire(blocking=False)  # held by another DP
        try:
            got: list[DPResult] = []
            t = threading.Thread(target=lambda: got.append(forward_dp(grid, problem)))
            t.start()
            t.join()
        finally:
            judged.lock.release()
        assert_same(got[0], want)
        for k, s in judged._ranks.items():
            np.testing.assert_array_equal(s, before[k])
    assert current_store() is not store


@pytest.mark.slow
@settings(max_examples=30, derandomize=True, deadline=None, database=None)
@given(seed=st.integers(0, 2**32 - 1), model=st.sampled_from(sorted(MODELS)), samples=st.integers(1, 3),
       apfs=st.lists(st.sampled_from([0.02, 0.2, 0.5, 0.95]), min_size=3, max_size=3),
       polars=st.lists(st.sampled_from([0.0, 0.4, -0.4]), min_size=3, max_size=3))  # fmt: skip
def test_dps_in_turn_equal_cold_ones(seed: int, model: str, samples: int, apfs: list[float],
                                     polars: list[float]) -> None:  # fmt: skip
    """Three DPs in turn on one grid of random patches (apf and polar drawn for each, so judgements are kept by one
    and taken by another going another way): each equals the same DP keeping nothing."""
    rng = np.random.default_rng(seed)
    weather = random_patches(rng, (-22.0, -12.0), (37.0, 45.0), base_hs=(1.0, 2.0))
    grid = make_grid((-12.5, 44.5), (-20.0, 39.0), n_ranks=int(rng.integers(2, 6)), n_nodes=int(rng.integers(33, 41)),
                     spacing_km=float(rng.uniform(8.0, 30.0)))  # fmt: skip
    problems = [
        RoutingProblem(departure=DEP, weather=weather, polar=warped(s), failure=MODELS[model], apf=apf, samples=samples)
        for apf, s in zip(apfs, polars, strict=True)
    ]
    with kept():
        got = [forward_dp(grid, p) for p in problems]
    for g, p in zip(got, problems, strict=True):
        assert_same(g, cold(grid, p))
