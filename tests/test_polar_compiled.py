"""The compiled polar lookup (pyroute_rel._kernels.polar) finds numpy's cells and speeds, on short and long axes."""

from __future__ import annotations

import numba
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import pyroute_rel.routing.solve as solve
from pyroute_rel._kernels.polar import SHORT_AXIS, cell, tables
from pyroute_rel.boat.polar import Polar, boat_speed_kn
from pyroute_rel.routing.grid import make_grid
from tests.test_dp_compiled import assert_same, both
from tests.test_solve import DEP, FINISH_PT, START_PT, random_weather


@numba.njit
def _cells(xs, axis, inv):  # type: ignore[no-untyped-def]
    out = np.empty(xs.size, dtype=np.int64)
    for k in range(xs.size):
        out[k] = cell(xs[k], axis, inv)
    return out


def _axis(rng: np.random.Generator, n: int, uniform: bool) -> np.ndarray:
    """A strictly increasing axis of ``n`` values >= 0 (a TWS axis): uniform but for its first step, or with
    random steps."""
    steps = np.full(n - 1, 5.0) if uniform else rng.uniform(0.1, 10.0, n - 1)
    if uniform and n > 1:
        steps[0] = rng.uniform(0.5, 20.0)
    start = rng.uniform(0.0, 5.0)
    return np.concatenate([[start], start + np.cumsum(steps)])


@pytest.mark.slow
@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(2, 3 * SHORT_AXIS), uniform=st.booleans())
def test_cell_is_numpys_searchsorted(seed: int, n: int, uniform: bool) -> None:
    """On axes shorter and longer than SHORT_AXIS (counted, or guessed from the spacing and corrected), uniform or
    not: the cell is ``clip(searchsorted(axis, x, "right") - 1, 0, n - 2)`` for points on the nodes, next to them,
    between, beyond both ends and infinite."""
    rng = np.random.default_rng(seed)
    axis = _axis(rng, n, uniform)
    span = axis[-1] - axis[0] + 1.0
    xs = np.concatenate(
        [
            axis,
            np.nextafter(axis, -np.inf),
            np.nextafter(axis, np.inf),
            rng.uniform(axis[0] - span, axis[-1] + span, 200),
            [-np.inf, np.inf, -1e300, 1e300],
        ]
    )
    polar = Polar("axis", twa_deg=[0.0, 180.0], tws_kn=axis, speed_kn=np.ones((2, n)))
    _, tws, _, _, inv = tables(polar)  # the TWS axis, as the kernels take it
    expected = np.clip(np.searchsorted(axis, xs, "right") - 1, 0, n - 2)
    np.testing.assert_array_equal(_cells(xs, tws, inv), expected)


def _long_polar(rng: np.random.Generator) -> Polar:
    """A polar with more rows and columns than SHORT_AXIS inner ones (the guessed cells), irregularly spaced."""
    twa = np.concatenate([[0.0, 28.0], np.sort(rng.choice(np.arange(30.0, 181.0, 3.0), 34, replace=False))])
    tws = np.concatenate([[0.0], np.cumsum(rng.uniform(0.5, 2.0, 24))])
    speed = rng.uniform(0.5, 8.0, (twa.size, tws.size))
    speed[0] = 0.0
    speed[:, 0] = 0.0
    assert twa.size - 2 > SHORT_AXIS and tws.size - 2 > SHORT_AXIS
    return Polar(name="long", twa_deg=twa, tws_kn=tws, speed_kn=speed)


@pytest.mark.parametrize("beyond", ["clamp", "forbid"])
def test_long_polar_speeds_are_numpys(beyond: str) -> None:
    """The compiled wind kernel's speeds with a long-axis polar are boat_speed_kn's, bit for bit (on the nodes too)."""
    from pyroute_rel._kernels.cost import sail_wind

    rng = np.random.default_rng(7)
    polar = _long_polar(rng)
    n = 5000
    tws = np.concatenate([rng.uniform(0.0, 45.0, n), rng.choice(polar.tws_kn, n)])
    course = rng.uniform(0.0, 360.0, tws.size)
    twd = np.where(rng.random(tws.size) < 0.4, (course + rng.choice(polar.twa_deg, tws.size)) % 360.0, 0.0)
    twa, speed, _ = sail_wind(tws, twd, course, np.ones(tws.size), polar, beyond=beyond)
    np.testing.assert_array_equal(speed, boat_speed_kn(polar, twa, tws, beyond=beyond))


@pytest.mark.parametrize("prune", [True, False])
def test_long_polar_dp_is_the_numpy_dp(prune: bool, monkeypatch: pytest.MonkeyPatch) -> None:
    """The compiled rank step with a long-axis polar, pruned (the wind sampled at the arcs costed) or not, gives the
    numpy path's arrivals, back-pointers and counts, bit for bit."""
    rng = np.random.default_rng(11)
    grid = make_grid(START_PT, FINISH_PT, n_ranks=8, n_nodes=47, spacing_km=60.0)
    problem = solve.RoutingProblem(
        departure=DEP, weather=random_weather(rng), polar=_long_polar(rng), samples=2, prune=prune
    )
    compiled, numpy_path = both(grid, problem, monkeypatch)
    assert np.isfinite(compiled.finish_h)
    assert_same(compiled, numpy_path, counts=not prune)
