"""Engines are settings, not module flags (issue 33): one settings module, a context that restores them, threads and
worker processes that run with the caller's settings, and each setting choosing its engine (the same numbers)."""

from __future__ import annotations

import contextvars
import importlib
import pkgutil
from pathlib import Path

import numpy as np
import pytest

import pyroute_rel
import pyroute_rel._kernels.dp as dp_compiled
from pyroute_rel.analysis import ensemble
from pyroute_rel.batch import sweep
from pyroute_rel.errors import ScenarioError
from pyroute_rel.resources import thread_map
from pyroute_rel.routing.solve import forward_dp
from pyroute_rel.scenario import load_scenario
from pyroute_rel.settings import Settings, get_settings, set_settings, settings_context

ROOT = Path(__file__).resolve().parents[1]
FIELDS = ("compiled_rank_step", "compiled_march", "lazy_pieces", "locate_cache", "fused_sampling")


def test_defaults_are_the_fast_engines() -> None:
    s = get_settings()
    assert s == Settings() and all(getattr(s, name) is True for name in FIELDS)


def test_a_context_sets_and_restores_even_on_error() -> None:
    with settings_context(lazy_pieces=False, compiled_march=False) as s:
        assert s is get_settings() and not s.lazy_pieces and not s.compiled_march and s.locate_cache
        with settings_context(lazy_pieces=True):  # nested: the inner one wins, then the outer one is back
            assert get_settings().lazy_pieces and not get_settings().compiled_march
        assert not get_settings().lazy_pieces
    assert get_settings() == Settings()
    with pytest.raises(ZeroDivisionError), settings_context(fused_sampling=False):
        1 / 0  # noqa: B018
    assert get_settings() == Settings()


def test_set_settings_holds_for_the_rest_of_its_context() -> None:
    def inside() -> tuple[Settings, Settings]:
        before = get_settings()
        set_settings(locate_cache=False)
        return before, get_settings()

    before, after = contextvars.copy_context().run(inside)
    assert before == Settings() and after == Settings(locate_cache=False)
    assert get_settings() == Settings()  # the copy's change stayed in it


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"lazy_piece": False}, "unknown setting 'lazy_piece'"),
        ({"lazy_pieces": 0}, "lazy_pieces must be True or False"),
    ],
)
def test_bad_settings_are_named(changes: dict, message: str) -> None:
    with pytest.raises(ScenarioError, match=message), settings_context(**changes):
        pass  # pragma: no cover
    assert get_settings() == Settings()


def test_threads_run_with_the_callers_settings() -> None:
    with settings_context(compiled_march=False):
        seen = thread_map(lambda _: get_settings().compiled_march, range(6), 2)
    assert seen == [False] * 6
    assert thread_map(lambda _: get_settings().compiled_march, range(6), 2) == [True] * 6


@pytest.mark.parametrize("init", [sweep._pin_threads, ensemble._worker_init])
def test_worker_processes_start_with_the_callers_settings(init, monkeypatch: pytest.MonkeyPatch) -> None:  # type: ignore[no-untyped-def]
    """The initializers the sweep's and the ensemble's process pools run (with the caller's settings as their
    argument) set them in the worker; run here in a copied context (and environment) so that nothing leaks."""
    monkeypatch.setattr(ensemble, "_begin", lambda: None)
    monkeypatch.setattr(sweep, "_limit_pools", lambda: None)  # (the thread pools are not limited here)
    monkeypatch.setenv("PYROUTE_REL_THREADS", "2")

    def start() -> Settings:
        init(Settings(compiled_rank_step=False))
        return get_settings()

    assert contextvars.copy_context().run(start) == Settings(compiled_rank_step=False)
    assert get_settings() == Settings()


def test_no_module_holds_an_engine_flag() -> None:
    """The old module booleans are gone from every module of the package (a test or a benchmark that sets one would
    change nothing, silently)."""
    old = {"LAZY_PIECES", "COMPILED_RANK_STEP", "COMPILED_MARCH", "LOCATE_CACHE", "FUSED_SAMPLING", "COMPILED_GLUE"}
    for info in pkgutil.walk_packages(pyroute_rel.__path__, "pyroute_rel."):
        if info.name.endswith("__main__") or ".cli." in info.name:
            continue
        module = importlib.import_module(info.name)
        assert not old & set(vars(module)), info.name


def test_the_rank_step_setting_chooses_the_engine(monkeypatch: pytest.MonkeyPatch) -> None:
    """``compiled_rank_step``: the DP hands ranks to the compiled step, or never; the route is the same."""
    calls = [0]
    real = dp_compiled.rank_step

    def counting(*args, **kw):  # type: ignore[no-untyped-def]
        calls[0] += 1
        return real(*args, **kw)

    monkeypatch.setattr(dp_compiled, "rank_step", counting)
    sc = load_scenario(ROOT / "examples" / "microtransat_control.toml").with_options(
        layout="square", n_ranks=30, n_nodes=40, failure_model="none", land=False
    )
    grid, problem = sc.make_grid(), sc.problem()
    fast = forward_dp(grid, problem)
    assert calls[0] > 0
    calls[0] = 0
    with settings_context(compiled_rank_step=False):
        slow = forward_dp(grid, problem)
    assert calls[0] == 0
    np.testing.assert_array_equal(fast.arrival_h, slow.arrival_h)
    np.testing.assert_array_equal(fast.back, slow.back)
