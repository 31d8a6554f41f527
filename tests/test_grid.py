"""The rank digraph's geometry and arc pattern."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pyroute_rel import geodesy
from pyroute_rel.errors import GridError
from pyroute_rel.routing.grid import FINISH, START, make_grid, plan_grid

START_PT, FINISH_PT = (-12.0, 45.0), (-60.0, 17.5)


@pytest.mark.parametrize("n_ranks,n_nodes", [(9, 9), (20, 7), (5, 12)])
def test_ranks_are_perpendicular_to_the_great_circle(n_ranks: int, n_nodes: int) -> None:
    g = make_grid(START_PT, FINISH_PT, n_ranks=n_ranks, n_nodes=n_nodes)
    args = (*START_PT, *FINISH_PT)
    xt = geodesy.cross_track_km(*args, g.lon_deg, g.lat_deg)
    at = geodesy.along_track_km(*args, g.lon_deg, g.lat_deg)
    # every node of rank k has its foot on the great circle at the rank's centre: (k+1) * rank spacing
    expected_at = (np.arange(1, n_ranks + 1) * g.rank_spacing_km)[:, None]
    np.testing.assert_allclose(at, np.broadcast_to(expected_at, at.shape), atol=1e-6)
    # signed lateral offsets, node 0 to port (negative), spaced spacing_km apart
    np.testing.assert_allclose(xt, np.broadcast_to(g.offset_km, xt.shape), atol=1e-6)
    d = geodesy.distance_km(g.lon_deg[:, :-1], g.lat_deg[:, :-1], g.lon_deg[:, 1:], g.lat_deg[:, 1:])
    np.testing.assert_allclose(d, g.spacing_km, rtol=1e-9)
    assert g.rank_spacing_km == pytest.approx(g.route_length_km / (n_ranks + 1))
    assert g.spacing_km == pytest.approx(g.rank_spacing_km)  # square by default, as in the paper


def test_middle_node_is_on_the_great_circle_when_n_nodes_odd() -> None:
    g = make_grid(START_PT, FINISH_PT, n_ranks=15, n_nodes=11)
    xt = geodesy.cross_track_km(*START_PT, *FINISH_PT, g.lon_deg[:, 5], g.lat_deg[:, 5])
    assert np.max(np.abs(xt)) < 1e-6


def test_square_grid_spacing_is_route_length_over_ranks_plus_one() -> None:
    # Route length from pyproj's spherical geodesic (independent): 5382 km, so 160 ranks give 33.4 km
    # (the paper reports 36.3 km for its 160-node grid, from a differently built grid).
    from pyproj import Geod

    r = geodesy.EARTH_RADIUS_KM * 1000.0
    _, _, d = Geod(a=r, b=r).inv(*START_PT, *FINISH_PT)
    g = make_grid(START_PT, FINISH_PT, n_ranks=160, n_nodes=160)
    assert g.spacing_km == pytest.approx(d / 1000.0 / 161.0, rel=1e-9)


def test_all_to_all_arc_count_and_networkx_export() -> None:
    n_ranks, n = 4, 5
    g = make_grid(START_PT, FINISH_PT, n_ranks=n_ranks, n_nodes=n)
    assert g.band == n - 1 and g.width == n
    assert g.n_arcs == n + (n_ranks - 1) * n * n + n
    nxg = g.to_networkx()
    assert nxg.number_of_edges() == g.n_arcs
    assert nxg.number_of_nodes() == n_ranks * n + 2
    assert set(nxg.successors(START)) == {(0, i) for i in range(n)}
    assert set(nxg.predecessors(FINISH)) == {(n_ranks - 1, i) for i in range(n)}


@pytest.mark.slow
@given(st.integers(2, 25), st.floats(5.0, 85.0), st.floats(0.5, 4.0))
@settings(max_examples=60, deadline=None)
def test_banded_arcs_respect_max_deviation(n: int, dev: float, aspect: float) -> None:
    g0 = make_grid(START_PT, FINISH_PT, n_ranks=30, n_nodes=n)
    g = make_grid(
        START_PT, FINISH_PT, n_ranks=30, n_nodes=n, spacing_km=g0.rank_spacing_km / aspect, max_deviation_deg=dev
    )
    k_max = math.tan(math.radians(dev)) * g.rank_spacing_km / g.spacing_km
    j = np.arange(n)[:, None]
    di = np.abs(g.src_index - j)
    # exactly the pairs with |i - j| <= band exist, and band is the largest offset within the angle
    assert np.array_equal(g.arc_valid, di <= g.band)
    assert g.band == min(n - 1, math.floor(k_max + 1e-9))
    # each destination sees every source within the band exactly once
    for jj in range(n):
        srcs = sorted(g.src_index[jj][g.arc_valid[jj]].tolist())
        assert srcs == list(range(max(0, jj - g.band), min(n, jj + g.band + 1)))


def test_arcs_into_rank_shapes() -> None:
    g = make_grid(START_PT, FINISH_PT, n_ranks=5, n_nodes=7, max_deviation_deg=60.0)
    for k in range(g.n_ranks + 1):
        lon0, lat0, lon1, lat1, src, valid = g.arcs(k)
        assert lon0.shape == lat1.shape == src.shape == valid.shape
    with pytest.raises(GridError, match=r"rank index must be a whole number in \[0, 5\] \(got 6\)"):
        g.arcs(g.n_ranks + 1)


@pytest.mark.parametrize(
    "kwargs,match",
    [
        ({"n_ranks": 0, "n_nodes": 5}, "n_ranks"),
        ({"n_ranks": 5, "n_nodes": 2.5}, "n_nodes"),
        ({"n_ranks": 5, "n_nodes": 5, "spacing_km": -1.0}, "spacing_km"),
        ({"n_ranks": 5, "n_nodes": 5, "max_deviation_deg": 95.0}, "max_deviation_deg"),
        ({"n_ranks": 5, "n_nodes": 1001, "spacing_km": 50.0}, "too wide"),
    ],
)
def test_bad_grid_settings(kwargs: dict, match: str) -> None:
    with pytest.raises(GridError, match=match):
        make_grid(START_PT, FINISH_PT, **kwargs)


def test_start_equal_finish_is_an_error() -> None:
    with pytest.raises(GridError, match="must differ"):
        make_grid(START_PT, START_PT, n_ranks=3, n_nodes=3)


def test_plan_grid_layouts() -> None:
    from pyroute_rel.routing.grid import plan_grid

    sq = plan_grid(START_PT, FINISH_PT, layout="square", n_ranks=40, n_nodes=41)
    assert (sq.n_ranks, sq.n_nodes, sq.band) == (40, 41, 40) and sq.aspect == pytest.approx(1.0)
    # angular: the lateral spacing is the rank spacing / aspect, n_nodes (a square-layout setting) is not used
    ang = plan_grid(
        START_PT, FINISH_PT, n_ranks=40, n_nodes=41, aspect=4.0, half_width_km=sq.half_width_km, max_deviation_deg=45.0
    )
    assert ang.half_width_km == pytest.approx(sq.half_width_km, rel=1e-9)
    assert ang.spacing_km == pytest.approx(sq.spacing_km / 4.0)
    assert ang.n_nodes == 4 * 40 + 1 and ang.band == 4
    assert (
        plan_grid(START_PT, FINISH_PT, n_ranks=40, n_nodes=41).n_nodes
        == plan_grid(START_PT, FINISH_PT, n_ranks=40, n_nodes=7).n_nodes
    )
    # explicit half-width: nodes cover at least it, the great circle on the middle node
    hw = plan_grid(START_PT, FINISH_PT, n_ranks=40, aspect=3.0, half_width_km=1000.0)
    assert hw.half_width_km >= 1000.0 > hw.half_width_km - hw.spacing_km and hw.n_nodes % 2 == 1
    with pytest.raises(GridError, match="layout"):
        plan_grid(START_PT, FINISH_PT, layout="hexagonal")


def test_square_plan_refuses_bad_counts_and_numpy_scalars_are_numbers() -> None:
    from pyroute_rel.routing.grid import plan_grid

    s, f = (-12.0, 45.0), (-60.0, 17.5)
    with pytest.raises(GridError, match=r"n_ranks must be a whole number >= 1 \(got 0\)"):
        plan_grid(s, f, layout="square", n_ranks=0, n_nodes=5)  # was silently 160 ranks
    with pytest.raises(GridError, match=r"n_nodes must be a whole number >= 1 \(got 0\)"):
        plan_grid(s, f, layout="square", n_ranks=5, n_nodes=0)
    a = make_grid(s, f, n_ranks=5, n_nodes=5, spacing_km=np.float32(50.0), max_deviation_deg=np.float64(45.0))
    b = make_grid(s, f, n_ranks=5, n_nodes=5, spacing_km=50.0, max_deviation_deg=45.0)
    np.testing.assert_array_equal(a.lon_deg, b.lon_deg)


def test_derived_data_live_in_a_typed_cache_outside_equality_and_repr() -> None:
    from pyroute_rel.routing.grid import GridCache
    from pyroute_rel.routing.solve import grid_geometry

    a = make_grid((-12.0, 45.0), (-60.0, 17.5), n_ranks=4, n_nodes=5)
    b = make_grid((-12.0, 45.0), (-60.0, 17.5), n_ranks=4, n_nodes=5)
    assert isinstance(a.cache, GridCache) and a.cache is not b.cache
    geom = grid_geometry(a, 2, 3)
    assert a.cache.geometry[2, 3] is geom and grid_geometry(a, 2, 3) is geom  # computed once
    assert a.cache.node_xyz is not None and a.cache.node_xyz.shape == (4, 5, 3)
    assert "cache" not in repr(a) and a.n_ranks == b.n_ranks
    assert b.cache.geometry == {}  # nothing leaked to the other grid


@pytest.mark.parametrize(
    ("n_ranks", "n_nodes", "deviation"),
    [(100_000, 100_000, None), (300, 400, None), (10**9, 5, 45.0)],  # 1e15, 48 M and 5e9 candidate arcs
)
def test_too_many_arcs_refused_before_nodes_are_placed(
    n_ranks: int, n_nodes: int, deviation: float | None, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Issue 17: a square 100000 x 100000 grid allocated 74.5 GiB before the arc limit was checked."""
    import pyroute_rel.routing.grid as grid_module

    def placed(*args: object, **kw: object) -> None:
        raise AssertionError("rank_points called: nodes placed before the size check")

    monkeypatch.setattr(grid_module, "rank_points", placed)
    with pytest.raises(GridError, match=rf"\({n_ranks} ranks x {n_nodes} nodes x \d+ arcs per node\), more than"):
        make_grid((-12.0, 45.0), (-60.0, 17.5), n_ranks=n_ranks, n_nodes=n_nodes, max_deviation_deg=deviation)


def test_grid_nodes_over_the_budget_are_refused(monkeypatch: pytest.MonkeyPatch) -> None:
    from pyroute_rel.errors import MemoryBudgetError
    from pyroute_rel.routing.grid import NODE_BYTES

    monkeypatch.setenv("PYROUTE_REL_MAX_MEMORY", "1G")
    # band 0 (arcs within 1e-3 deg): one arc per node, so 20 M nodes pass the arc limit; their placement alone takes
    # 20e6 x 64 bytes = 1.2 GiB, plus the process
    with pytest.raises(MemoryBudgetError, match=r"grid 4000000 x 5\) but the budget PYROUTE_REL_MAX_MEMORY is 1.0 GiB"):
        make_grid((-12.0, 45.0), (-60.0, 17.5), n_ranks=4_000_000, n_nodes=5, spacing_km=1.0, max_deviation_deg=1e-3)
    assert NODE_BYTES * 4_000_000 * 5 > 1024**3


@pytest.mark.parametrize("start", [("a", "b"), (1.0,), (1.0, 2.0, 3.0), None])
def test_plan_grid_refuses_a_start_that_is_not_a_lon_lat_pair(start: object) -> None:
    # The angular layout measured the route before make_grid checked the points: ('a', 'b') raised a bare
    # ValueError, (1.0,) an IndexError.
    with pytest.raises(GridError, match=r"start must be a pair \[lon, lat\] of numbers"):
        plan_grid(start, (-60.0, 17.5), n_ranks=20)  # type: ignore[arg-type]
