"""The forward DP's Python glue over time-varying gridded weather, done once where it does not change (issue 19).

What the DP asks at every rank is now kept between ranks: the columns and turned rows a set of fields samples
(``_Block.plan``), the fields a failure model needs, its table and its entries above apf (``judge_tables``), its
largest p_f; contiguous inputs go to the kernels as they are (no copy). Whatever is kept must not leak from one
route, member, model or apf into another: each is checked against the numpy reference paths (the settings
``compiled_march`` and ``fused_sampling`` off, which keep nothing of the sort) and against the same route computed
alone.
"""

from __future__ import annotations

import numpy as np
import pytest

from pyroute_rel._kernels.cost import judge_tables, sail_wind
from pyroute_rel.boat.polar import get_polar
from pyroute_rel.errors import WeatherError
from pyroute_rel.reliability.failure import load_failure_model
from pyroute_rel.routing import solve
from pyroute_rel.routing.cost import REASONS
from pyroute_rel.routing.grid import make_grid
from pyroute_rel.routing.solve import RoutingProblem, forward_dp
from pyroute_rel.settings import settings_context
from pyroute_rel.weather import GriddedWeather, WeatherField

DEP = np.datetime64("2018-06-01T00:00:00")
POLAR = get_polar("maribot_vane")
MODELS = {name: load_failure_model(name) for name in ("dickson2018", "wind_wave_multistate")}
GRID = make_grid((-13.0, 44.0), (-17.0, 41.0), n_ranks=6, n_nodes=7, spacing_km=30.0)


def weather(seed: int) -> GriddedWeather:
    """Wind and waves on a 1 deg grid every 6 h over 8 days, random from ``seed``."""
    rng = np.random.default_rng(seed)
    lon, lat = -26.0 + np.arange(19.0), np.arange(35.0, 49.01, 1.0)
    time = DEP.astype("datetime64[ns]") + np.arange(33) * np.timedelta64(6, "h")
    shape = (time.size, lat.size, lon.size)
    values = {
        "wind_u_ms": rng.uniform(-9.0, 9.0, shape),
        "wind_v_ms": rng.uniform(-9.0, 9.0, shape),
        "hs_m": np.clip(rng.normal(3.5, 1.5, shape), 0.0, None),
        "wave_dir_deg": rng.uniform(0.0, 360.0, shape),
    }
    return GriddedWeather(
        [WeatherField(k, v.astype(np.float32), lon, lat, time, source="t", variable=k) for k, v in values.items()]
    )


def dp(w: GriddedWeather, model: str, apf: float, *, n_wait: int = 0) -> solve.DPResult:
    problem = RoutingProblem(
        departure=DEP,
        weather=w,
        polar=POLAR,
        failure=MODELS[model],
        apf=apf,
        samples=2,
        time_step_h=3.0 if n_wait else None,
        max_wait_h=3.0 * n_wait if n_wait else 0.0,
    )
    return forward_dp(GRID, problem)


def reference(w: GriddedWeather, model: str, apf: float, *, n_wait: int = 0) -> solve.DPResult:
    """The DP on the numpy paths: nothing kept between ranks but the located points."""
    with settings_context(compiled_march=False, fused_sampling=False):
        return dp(w, model, apf, n_wait=n_wait)


def assert_same(a: solve.DPResult, b: solve.DPResult) -> None:
    np.testing.assert_array_equal(a.arrival_h, b.arrival_h)
    np.testing.assert_array_equal(a.back, b.back)
    if a.wait_h is not None or b.wait_h is not None:
        np.testing.assert_array_equal(a.wait_h, b.wait_h)
    assert (a.finish_h, a.finish_back, a.dead_rank) == (b.finish_h, b.finish_back, b.dead_rank)
    assert (a.arcs_evaluated, a.arcs_forbidden, a.arcs_pruned) == (b.arcs_evaluated, b.arcs_forbidden, b.arcs_pruned)
    assert a.forbidden_by_reason == b.forbidden_by_reason
    assert a.forbidden_by_criterion == b.forbidden_by_criterion


@pytest.mark.slow
@pytest.mark.parametrize("n_wait", [0, 2])  # 0: one departure (the DP's short cut); 2: the waiting loop
def test_routes_equal_the_numpy_paths_whatever_was_routed_before(n_wait: int) -> None:
    """Members, models and apf one after another in one process (each keeps its own plan, fields and tables)
    give what each gives on the reference paths, and the first again after the others what it gave first."""
    cases = [
        (weather(1), "dickson2018", 0.95),
        (weather(2), "wind_wave_multistate", 0.5),
        (weather(3), "dickson2018", 0.2),
    ]
    first = [dp(w, m, apf, n_wait=n_wait) for w, m, apf in cases]
    assert any(r.arcs_forbidden for r in first) and any(np.isfinite(r.finish_h) for r in first)  # not vacuous
    assert any(r.forbidden_by_reason["failure"] for r in first)
    for (w, m, apf), got in zip(cases, first, strict=True):
        assert_same(got, reference(w, m, apf, n_wait=n_wait))
    assert_same(dp(*cases[0], n_wait=n_wait), first[0])


def test_judge_tables_are_the_models_per_apf_and_not_shared_with_it() -> None:
    model = load_failure_model("dickson2018")
    hi, lo = judge_tables(model, 0.95), judge_tables(model, 0.2)
    for apf, (p_flat, over, bits) in ((0.95, hi), (0.2, lo)):
        np.testing.assert_array_equal(p_flat, model.p_flat)
        np.testing.assert_array_equal(over, model.p_flat > apf)
        np.testing.assert_array_equal(bits, model.fired_bits_flat)
        assert not np.shares_memory(p_flat, model.p_flat) and not np.shares_memory(bits, model.fired_bits_flat)
    assert (hi[1] != lo[1]).any()  # another apf, other entries above it
    assert judge_tables(model, 0.95) is hi  # kept
    other = load_failure_model("dickson2018")  # an equal model is its own entry
    assert judge_tables(other, 0.95) is not hi


def points() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(5)
    lon, lat = rng.uniform(-24.0, -10.0, (40, 3)), rng.uniform(36.0, 48.0, (40, 3))
    return lon, lat, rng.uniform(0.0, 150.0, (40, 3))


@pytest.mark.parametrize("fields", [("tws_kn", "twd_deg"), ["hs_m", "tws_kn", "twd_deg"], None])
def test_sampled_fields_equal_sampling_every_point(fields: list[str] | tuple[str, ...] | None) -> None:
    """:meth:`GriddedWeather.sample_at` (its plan kept per set of fields, a contiguous offset passed as it is)
    against every field sampled at points prepared anew, the components turned afterwards
    (``fused_sampling`` off): the fields asked for equal, the others NaN (no current in the data: 0 where asked
    for)."""
    w = weather(4)
    lon, lat, hours = points()
    prepared = w.prepare(lon, lat)
    offset = hours.copy()
    for _ in range(2):  # the second time from the plans kept
        got = w.sample_at(prepared, DEP, offset_h=offset, fields=fields)
        strided = w.sample_at(prepared, DEP, offset_h=np.asfortranarray(hours), fields=fields)  # copied
        with settings_context(fused_sampling=False):  # every field, its components turned afterwards
            want = w.sample_at(w.prepare(lon, lat), DEP, offset_h=hours[::-1][::-1])
        np.testing.assert_array_equal(offset, hours)  # not written
        for name in ("tws_kn", "twd_deg", "hs_m", "wave_dir_deg", "wave_period_s", "current_u_ms", "current_v_ms"):
            a, b, ref = getattr(got, name), getattr(strided, name), getattr(want, name)
            assert a.shape == lon.shape
            np.testing.assert_array_equal(a, b)
            if fields is None or name in fields:
                np.testing.assert_array_equal(a, ref)
            else:
                assert np.isnan(a).all()
    assert np.isnan(want.wave_period_s).all() and not want.current_u_ms.any()


def test_unknown_fields_are_refused_each_time() -> None:
    w = weather(4)
    prepared = w.prepare(*points()[:2])
    for _ in range(2):  # (a refusal is not kept as a plan)
        with pytest.raises(WeatherError, match="'fields' must be Conditions fields"):
            w.sample_at(prepared, DEP, offset_h=0.0, fields=("tws_kn", "speed"))


def test_sail_wind_takes_read_only_and_strided_inputs_without_writing_them() -> None:
    """Inputs that are not contiguous writable float64 are copied for the kernel (never a view it could write)."""
    rng = np.random.default_rng(9)
    tws, twd, course = rng.uniform(0, 30, (50, 4)), rng.uniform(0, 360, (50, 4)), rng.uniform(0, 360, (50, 4))
    seg = rng.uniform(0.5, 3.0, (50, 1))
    want = sail_wind(tws.copy(), twd.copy(), course.copy(), seg.copy(), POLAR)
    frozen = [a.copy() for a in (tws, twd, course, seg)]
    for a in frozen:
        a.setflags(write=False)
    got = sail_wind(*frozen, POLAR)
    got_f = sail_wind(np.asfortranarray(tws), np.repeat(twd, 2, axis=1)[:, ::2], course, seg, POLAR)
    for x, y, z in zip(want, got, got_f, strict=True):
        np.testing.assert_array_equal(x, y)
        np.testing.assert_array_equal(x, z)
    for a, b in zip(frozen, (tws, twd, course, seg), strict=True):
        np.testing.assert_array_equal(a, b)


def test_tally_counts_each_reason_as_the_arcs_with_its_bit() -> None:
    """The tally's per-reason counts (one product over the 256 flag combinations) against a count per arc."""
    rng = np.random.default_rng(3)
    live = rng.random((30, 9)) < 0.8
    reason = rng.integers(0, 32, (30, 9)).astype(np.uint8) * (rng.random((30, 9)) < 0.6)
    tally = solve._Tally()
    tally.add(live, live, reason, None, None)
    tally.add(live, live & (rng.random((30, 9)) < 0.5), reason[::-1], None, None)
    for name, bit in REASONS.items():
        want = int(((reason & bit) != 0)[live].sum()) + int(((reason[::-1] & bit) != 0)[live].sum())
        assert tally.by_reason[name] == want, name
    assert tally.forbidden == int((reason != 0)[live].sum()) + int((reason[::-1] != 0)[live].sum())
