"""A route that ends on a finish line never crosses it on an arc that meets an obstacle, whether the obstacles are
tested lazily (only the arcs the DP would pick) or for every arc."""

from __future__ import annotations

import dataclasses
import tomllib
from pathlib import Path

import numpy as np
import pytest

from pyroute_rel.routing.solve import forward_dp
from pyroute_rel.scenario import scenario_from_mapping

COURSE = Path(__file__).resolve().parents[1] / "examples" / "microtransat_real_course.toml"


class _Blocked:
    """An obstacle mask (the solver's ArcMask protocol) blocking a given set of arcs (rank, node, arc), learnt
    arc by arc as the real mask does where its sweep does not apply."""

    timed = False

    def __init__(self, grid, arcs: set[tuple[int, int, int]]) -> None:
        self.grid = grid
        self.arcs = arcs
        self._known: dict[int, np.ndarray] = {}

    def known(self, k: int) -> np.ndarray:
        if k not in self._known:
            self._known[k] = np.zeros(self.grid.pattern(k)[0].shape, dtype=bool)
        return self._known[k]

    def learn(self, k: int, select=None) -> None:
        known = self.known(k)
        known |= True if select is None else select

    def _all(self, k: int) -> np.ndarray:
        out = np.zeros(self.grid.pattern(k)[0].shape, dtype=bool)
        for kk, j, c in self.arcs:
            if kk == k:
                out[j, c] = True
        return out

    def hits(self, k: int, times) -> np.ndarray:
        return self._all(k) & self.known(k)

    def __call__(self, k: int, times) -> np.ndarray:
        self.learn(k)
        return self.hits(k, times)


def _crossing_arc(grid, res) -> tuple[int, int, int]:
    src, _ = grid.pattern(res.end_rank)
    (c,) = np.flatnonzero(src[res.end_node] == res.end_src)[:1]
    return res.end_rank, res.end_node, int(c)


@pytest.mark.slow
def test_the_finish_line_is_never_crossed_on_an_arc_known_only_lazily() -> None:
    table = tomllib.loads(COURSE.read_text())
    table["grid"] = {"n_ranks": 30, "half_width_km": 600.0}
    table["avoid"] = {"land": False}
    sc = scenario_from_mapping(table, base_dir=COURSE.parent, source=str(COURSE))
    grid = sc.make_grid()
    base = sc.problem(grid=grid)
    blocked: set[tuple[int, int, int]] = set()
    not_best = 0
    for _ in range(6):  # block the arc each route crosses the line on, one after another
        eager = forward_dp(
            grid, dataclasses.replace(base, blocked=_Blocked(grid, set(blocked))), cost_hook=lambda k, c: None
        )
        lazy = forward_dp(grid, dataclasses.replace(base, blocked=_Blocked(grid, set(blocked))))
        assert eager.end_rank is not None and np.isfinite(eager.finish_h)
        assert lazy.finish_h == eager.finish_h
        assert (lazy.end_rank, lazy.end_node, lazy.end_src) == (eager.end_rank, eager.end_node, eager.end_src)
        arc = _crossing_arc(grid, eager)
        assert arc not in blocked
        k, j, _ = arc
        not_best += int(eager.back[k, j] != eager.end_src) if k < grid.n_ranks else 0
        blocked.add(arc)
    assert not_best > 0  # some crossing arcs were not their node's best: the lazy DP never tested them itself
