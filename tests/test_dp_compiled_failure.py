"""The compiled rank step with a failure model on uniform weather with patches (issue 32): the compiled judgement of
one arc on the pieces it crosses equals :func:`pyroute_rel.reliability.crossings.arc_extremes` bit for bit, the compiled
test of which arcs need it is sound, and the DP through it equals the numpy path (lazy and eager judgement) on random
problems and on the example."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import pyroute_rel._kernels.dp as dp_compiled
from pyroute_rel import geodesy
from pyroute_rel._kernels.crossings import arc_p_f, box_fields, needs_judging
from pyroute_rel.boat.polar import get_polar
from pyroute_rel.reliability import crossings
from pyroute_rel.reliability.failure import load_failure_model
from pyroute_rel.routing import solve
from pyroute_rel.routing.cost import geometry_costs
from pyroute_rel.routing.grid import make_grid
from pyroute_rel.routing.route import build_route
from pyroute_rel.routing.solve import RoutingProblem, forward_dp
from pyroute_rel.scenario import load_scenario
from pyroute_rel.settings import settings_context
from pyroute_rel.weather import Patch, UniformWeather

ROOT = Path(__file__).resolve().parents[1]
DEP = np.datetime64("2018-06-01T00:00:00")
MODELS = {name: load_failure_model(name) for name in ("dickson2018", "wind_wave_multistate")}
POLAR = get_polar("maribot_vane")


def props(n: int) -> settings:
    return settings(max_examples=n, derandomize=True, deadline=None, database=None)


def random_patches(
    rng: np.random.Generator,
    lon: tuple[float, float],
    lat: tuple[float, float],
    base_hs: tuple[float, ...] = (1.0, 4.5),
) -> UniformWeather:
    """Up to four boxes setting waves and wind (heights either side of the 4 m criterion, any direction), and waves
    of a height drawn from ``base_hs`` [m] elsewhere."""
    patches = []
    for _ in range(int(rng.integers(1, 5))):
        lo0 = max(float(rng.uniform(*lon)), -180.0)  # (some on the antimeridian)
        la0 = min(float(rng.uniform(*lat)), 89.8)
        values: dict[str, float] = {}
        if rng.random() < 0.7:
            values["hs_m"] = float(rng.choice([1.0, 3.5, 4.0, 6.0]))
        if rng.random() < 0.5:
            values["wave_dir_deg"] = float(rng.uniform(0.0, 359.0))
        if rng.random() < 0.4:
            values["twd_deg"] = float(rng.uniform(0.0, 359.0))
        if rng.random() < 0.4:
            values["tws_kn"] = float(rng.uniform(0.0, 40.0))
        values = values or {"hs_m": 4.5}
        lo1 = min(lo0 + float(rng.uniform(0.2, 6.0)), 180.0)
        la1 = min(la0 + float(rng.uniform(0.2, 6.0)), 90.0)  # (some up to the pole)
        patches.append(Patch(lon=(lo0, lo1), lat=(la0, la1), values=values))
    return UniformWeather(
        tws_kn=float(rng.uniform(5.0, 25.0)),
        twd_deg=float(rng.uniform(0.0, 360.0)),
        hs_m=float(rng.choice(base_hs)),
        wave_dir_deg=float(rng.uniform(0.0, 360.0)),
        patches=tuple(patches),
    )


def compiled_arcs(weather: UniformWeather, model, apf: float, a: np.ndarray, b: np.ndarray):  # type: ignore[no-untyped-def]
    f = box_fields(weather, model, apf)
    assert f is not None
    pieces = (f.base, f.boxes, f.values, f.relative, f.edges, f.n_edges, f.right, f.bin_state, f.fill_state,
              f.n_slots, f.stride, f.p_flat, f.over, f.bits)  # fmt: skip
    cuts = np.empty(3 * f.lon_lines.size + 2 * f.lat_lines.size + 4)
    work = np.empty((f.base.size, 4))
    reach = np.zeros((f.base.size, int(f.n_slots.max())), dtype=bool)
    p = np.empty(len(a))
    bits = np.empty(len(a), dtype=np.uint32)
    for i in range(len(a)):
        p[i], bits[i] = arc_p_f(a[i], b[i], f.lon_lines, f.lat_lines, pieces, cuts, work, reach)
    return p, bits


# the regions the arcs are drawn in: mid-Atlantic, across the equator, across the antimeridian (from either side),
# near the pole
REGIONS = [((-35.0, -5.0), (20.0, 40.0)), ((-30.0, -20.0), (-6.0, 6.0)), ((172.0, 179.0), (-10.0, 10.0)),
           ((-179.0, -172.0), (-10.0, 10.0)), ((-20.0, 20.0), (80.0, 86.0))]  # fmt: skip


@pytest.mark.slow
@props(40)
@given(seed=st.integers(0, 2**32 - 1), region=st.sampled_from(REGIONS), model=st.sampled_from(sorted(MODELS)),
       apf=st.sampled_from([0.0, 0.02, 0.2, 0.5, 0.95]))  # fmt: skip
def test_arc_p_f_equals_arc_extremes(seed: int, region, model: str, apf: float) -> None:  # type: ignore[no-untyped-def]
    """Random arcs (up to 4 deg each way, some across the equator, the antimeridian or near the pole) in random
    patches: the largest p_f and the criteria fired above apf are those of the numpy judgement, bit for bit."""
    rng = np.random.default_rng(seed)
    (lo0, lo1), (la0, la1) = region
    weather = random_patches(rng, (lo0 - 2.0, lo1), (la0 - 2.0, la1))
    n = 400
    lon0, lat0 = rng.uniform(lo0, lo1, n), rng.uniform(la0, la1, n)
    lon1 = (lon0 + rng.uniform(-4.0, 4.0, n) + 180.0) % 360.0 - 180.0
    lat1 = np.clip(lat0 + rng.uniform(-4.0, 4.0, n), -89.0, 89.0)
    a, b = geodesy.to_xyz(lon0, lat0), geodesy.to_xyz(lon1, lat1)
    ext = crossings.arc_extremes(a, b, np.zeros(n), np.ones(n), departure=DEP, weather=weather, polar=POLAR,
                                 failure=MODELS[model], apf=apf)  # fmt: skip
    p, bits = compiled_arcs(weather, MODELS[model], apf, a, b)
    np.testing.assert_array_equal(p, ext.p_f)
    np.testing.assert_array_equal(bits, ext.fired_bits)
    assert ext.pieces > n and np.unique(ext.p_f).size > 1  # the draws cut arcs and meet different seas


@pytest.mark.slow
@props(30)
@given(seed=st.integers(0, 2**32 - 1), model=st.sampled_from(sorted(MODELS)), samples=st.integers(1, 4),
       region=st.sampled_from(REGIONS))  # fmt: skip
def test_arcs_passed_over_are_judged_by_their_samples(seed: int, model: str, samples: int, region) -> None:  # type: ignore[no-untyped-def]
    """Soundness of ``needs_judging`` (and of the numpy path's ``needs_pieces``): where it says an arc's samples
    judge it alone, the largest p_f along the whole arc (the numpy judgement on every piece) is that of its samples;
    in the regions of :data:`REGIONS` (patches ending on the antimeridian, arcs near the pole)."""
    rng = np.random.default_rng(seed)
    (lo0, lo1), (la0, la1) = region
    weather = random_patches(rng, (lo0 - 2.0, lo1), (la0 - 2.0, la1))
    m = MODELS[model]
    n = 300
    lon0, lat0 = rng.uniform(lo0, lo1, n), rng.uniform(la0, la1, n)
    lon1 = (lon0 + rng.uniform(-3.0, 3.0, n) + 180.0) % 360.0 - 180.0
    lat1 = np.clip(lat0 + rng.uniform(-3.0, 3.0, n), -89.5, 89.5)
    from pyroute_rel.routing.cost import arc_geometry

    geom = arc_geometry(lon0, lat0, lon1, lat1, samples=samples)
    c = geometry_costs(geom, 0.0, departure=DEP, weather=weather, polar=POLAR, failure=m, apf=1.0, exact_p_f=False)
    ext = crossings.arc_extremes(geom.a_xyz, geom.b_xyz, np.zeros(n), np.ones(n), departure=DEP, weather=weather,
                                 polar=POLAR, failure=m)  # fmt: skip
    f = box_fields(weather, m, 1.0)
    assert f is not None
    work = np.empty(f.base.size)
    course = np.broadcast_to(geom.course_deg, (n, samples))
    seg = np.broadcast_to(geom.seg_nm[..., 0], (n,))
    passed = np.array([not needs_judging(geom.lon_deg[i], geom.lat_deg[i], np.ascontiguousarray(course[i]),
                                         float(seg[i]), f.boxes, f.base, f.values, f.relative, f.edges, f.n_edges,
                                         work) for i in range(n)])  # fmt: skip
    assert (~passed).sum() > 0  # arcs that need their pieces are drawn
    finite = np.isfinite(c.p_f)
    np.testing.assert_array_equal(ext.p_f[passed & finite], c.p_f[passed & finite])
    close = crossings.needs_pieces(geom.lon_deg, geom.lat_deg, geom.course_deg, geom.seg_nm, np.zeros(n), c.time_h,
                                   weather=weather, failure=m, departure=DEP)  # fmt: skip
    assert close is not None
    skipped = ~np.broadcast_to(close, (n,)) & finite
    np.testing.assert_array_equal(ext.p_f[skipped], c.p_f[skipped])


def test_a_patch_beyond_the_antimeridian_is_met() -> None:
    """An arc whose sample is west of 180 deg and whose end is in a patch bounded by -180 deg (found in review): both
    paths judge it on its pieces, and the seas it meets there forbid it."""
    m = MODELS["dickson2018"]
    w = UniformWeather(tws_kn=10.0, twd_deg=0.0, hs_m=1.0, wave_dir_deg=270.0,
                       patches=(Patch(lon=(-180.0, -179.9), lat=(0.0, 1.0), values={"hs_m": 6.0}),))  # fmt: skip
    from pyroute_rel.routing.cost import arc_geometry

    g = arc_geometry(np.array([179.7]), np.array([0.5]), np.array([-179.95]), np.array([0.5]), samples=1)
    assert g.lon_deg[0, 0] > 0.0  # the sample is on the other side of the antimeridian
    c = geometry_costs(g, 0.0, departure=DEP, weather=w, polar=POLAR, failure=m, apf=0.5)
    assert c.p_f[0] == 0.9 and not np.isfinite(c.time_h[0])
    f = box_fields(w, m, 0.5)
    assert f is not None
    course = np.ascontiguousarray(np.broadcast_to(g.course_deg, (1, 1))[0])
    assert needs_judging(g.lon_deg[0], g.lat_deg[0], course, float(g.seg_nm[0, 0]), f.boxes, f.base, f.values,
                         f.relative, f.edges, f.n_edges, np.empty(f.base.size))  # fmt: skip


def test_arcs_along_the_equator() -> None:
    """A grid whose middle row lies on the equator (arcs along it: no crossing of it to find, where a division by
    zero used to stop the compiled step), with no patch and the head-seas edge near the course."""
    grid = make_grid((-25.0, 0.0), (-15.0, 0.0), n_ranks=4, n_nodes=33, spacing_km=10.0)
    w = UniformWeather(tws_kn=12.0, twd_deg=0.0, hs_m=1.0, wave_dir_deg=150.0)
    problem = RoutingProblem(departure=DEP, weather=w, polar=POLAR, failure=MODELS["dickson2018"], apf=0.2)
    compiled, lazy, eager = three_ways(grid, problem)
    assert np.isfinite(compiled.finish_h)
    assert_same_dp(compiled, lazy)
    assert_same_dp(compiled, eager)
    a, b = geodesy.to_xyz(np.array([-21.0]), np.array([0.0])), geodesy.to_xyz(np.array([-19.0]), np.array([0.0]))
    ext = crossings.arc_extremes(a, b, np.zeros(1), np.ones(1), departure=DEP, weather=w, polar=POLAR,
                                 failure=MODELS["dickson2018"], apf=0.2)  # fmt: skip
    p, bits = compiled_arcs(w, MODELS["dickson2018"], 0.2, a, b)
    assert p[0] == ext.p_f[0] and bits[0] == ext.fired_bits[0]


def counted(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """Count the ranks the compiled failure kernel did."""
    seen = [0]
    real = dp_compiled._boxed_fail_rank

    def wrapper(*args):  # type: ignore[no-untyped-def]
        seen[0] += 1
        return real(*args)

    monkeypatch.setattr(dp_compiled, "_boxed_fail_rank", wrapper)
    return seen


def three_ways(grid, problem: RoutingProblem):  # type: ignore[no-untyped-def]
    """The DP through the compiled kernel, the numpy path judging lazily, and judging every arc eagerly."""
    with pytest.MonkeyPatch.context() as mp:
        ranks = counted(mp)
        compiled = forward_dp(grid, problem)
    assert ranks[0] > 0 or not np.isfinite(compiled.arrival_h[0]).any()  # (or nothing got past the first rank)
    with settings_context(compiled_rank_step=False):
        lazy = forward_dp(grid, problem)
        with settings_context(lazy_pieces=False):
            eager = forward_dp(grid, problem)
    return compiled, lazy, eager


def assert_same_dp(a: solve.DPResult, b: solve.DPResult) -> None:
    np.testing.assert_array_equal(a.arrival_h, b.arrival_h)
    np.testing.assert_array_equal(a.back, b.back)
    assert (a.finish_h, a.finish_back, a.dead_rank) == (b.finish_h, b.finish_back, b.dead_rank)
    assert (a.arcs_evaluated, a.arcs_pruned) == (b.arcs_evaluated, b.arcs_pruned)


@pytest.mark.slow
@props(20)
@given(seed=st.integers(0, 2**32 - 1), model=st.sampled_from(sorted(MODELS)),
       apf=st.sampled_from([0.02, 0.2, 0.5, 0.95, 1.0]), samples=st.integers(1, 3), n_nodes=st.integers(33, 48),
       beyond=st.sampled_from(["clamp", "forbid"]))  # fmt: skip
def test_compiled_failure_dp_equals_numpy(seed: int, model: str, apf: float, samples: int, n_nodes: int,
                                          beyond: str) -> None:  # fmt: skip
    """All-to-all square grids (the DP prunes) through random patches of waves and wind: arrival times,
    back-pointers and arcs costed are those of the numpy path, lazy and eager; arcs forbidden for other reasons
    are counted alike, and those forbidden by the failure model are at most the eager count (only the arcs the DP
    would pick are judged on their pieces) and at least those forbidden at their samples."""
    rng = np.random.default_rng(seed)
    weather = random_patches(rng, (-22.0, -12.0), (37.0, 45.0), base_hs=(1.0, 2.0))
    grid = make_grid((-12.5, 44.5), (-20.0, 39.0), n_ranks=int(rng.integers(2, 6)), n_nodes=n_nodes,
                     spacing_km=float(rng.uniform(8.0, 30.0)))  # fmt: skip
    problem = RoutingProblem(departure=DEP, weather=weather, polar=POLAR, failure=MODELS[model], apf=apf,
                             samples=samples, beyond=beyond)  # fmt: skip
    compiled, lazy, eager = three_ways(grid, problem)
    assert_same_dp(compiled, lazy)
    assert_same_dp(compiled, eager)
    for name, n in compiled.forbidden_by_reason.items():
        if name == "failure":
            assert n <= eager.forbidden_by_reason[name]
        else:
            assert n == eager.forbidden_by_reason[name] == lazy.forbidden_by_reason[name]
    for name, n in compiled.forbidden_by_criterion.items():
        assert n <= eager.forbidden_by_criterion[name]
    if np.isfinite(eager.finish_h):
        r0, r1 = build_route(grid, problem, eager), build_route(grid, problem, compiled)
        assert r1.voyage_time_h == r0.voyage_time_h and r1.max_failure_probability == r0.max_failure_probability
        np.testing.assert_array_equal(r1.lon_deg, r0.lon_deg)


@pytest.mark.slow
@pytest.mark.parametrize("apf", [0.5, 0.2])
def test_compiled_failure_dp_on_the_example(apf: float) -> None:
    """The paper's square grid of the control example (81 x 81, no land) at apf 0.5 and 0.2: the compiled DP
    finds the numpy path's arrivals, back-pointers and arcs costed; arcs are forbidden by the failure model, for the
    same criteria (their counts may differ: the numpy path judges in batches, the compiled step one arc at a time)."""
    sc = load_scenario(ROOT / "examples" / "microtransat_control.toml").with_options(
        layout="square", n_ranks=81, n_nodes=81, land=False, apf=apf
    )
    grid, problem = sc.make_grid(), sc.problem()
    compiled, lazy, eager = three_ways(grid, problem)
    assert_same_dp(compiled, lazy)
    assert_same_dp(compiled, eager)
    assert compiled.forbidden_by_reason["failure"] > 0
    assert compiled.forbidden_by_criterion.keys() == eager.forbidden_by_criterion.keys()
