"""The forward DP's hot loops over gridded weather, made shorter (issue 19): the same numbers as the separate kernels.

- ``Settings.fused_sampling``: :meth:`GriddedWeather.sample_at` turns the wind's (u, v) and the wave
  direction's (sin, cos) as it interpolates each point; the reference is the components interpolated, then turned by
  ``_kernels.sampling.vectors`` (the switch off). The interpolation kernel also keeps the last time's cell for the
  points that share it: the reference for that is :meth:`GriddedWeather.sample` at explicit times (other points in
  between).
- ``cost_compiled._wind_kernel`` reads the polar table itself (no array passed to an inlined helper); the reference
  is numpy's :func:`~pyroute_rel.boat.polar.boat_speed_kn` and the numpy cost path, on short axes (counted) and long
  irregular ones (found with ``polar_compiled.cell_finder``, including axes so uneven that its bins are capped).

Every comparison is to the bit (``assert_array_equal``, NaN where NaN), on random inputs with NaN cells, calm wind,
points and times outside the data, and steady and one-time blocks.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pyroute_rel._kernels.cost import sail_wind
from pyroute_rel._kernels.polar import cell_finder
from pyroute_rel.boat.polar import Polar, boat_speed_kn
from pyroute_rel.reliability.failure import list_failure_models, load_failure_model
from pyroute_rel.routing.grid import make_grid
from pyroute_rel.settings import settings_context
from pyroute_rel.weather import GriddedWeather, WeatherField
from tests.test_dp_glue import DEP, dp

FIELDS = ("tws_kn", "twd_deg", "hs_m", "wave_dir_deg", "wave_period_s", "current_u_ms", "current_v_ms")


def _weather(seed: int, times: int, *, shared_grid: bool = True) -> GriddedWeather:
    """Wind, waves and a period on a 1 deg grid with NaN cells and calm (zero) wind; ``times`` 0: steady, 1: one
    time; ``shared_grid`` False: the waves on a grid of their own (another block)."""
    rng = np.random.default_rng(seed)
    lon, lat = -26.0 + np.arange(9.0), np.arange(38.0, 46.01, 1.0)
    time = None if times == 0 else DEP.astype("datetime64[ns]") + np.arange(times) * np.timedelta64(6, "h")
    shape = (max(times, 1), lat.size, lon.size)
    u, v = rng.uniform(-12.0, 12.0, shape), rng.uniform(-12.0, 12.0, shape)
    calm = rng.random(shape) < 0.2
    u[calm], v[calm] = 0.0, 0.0
    u[rng.random(shape) < 0.01] = np.nan
    hs, wave = np.clip(rng.normal(3.0, 1.5, shape), 0.0, None), rng.uniform(0.0, 360.0, shape)
    wave[rng.random(shape) < 0.01] = np.nan
    wlon = lon if shared_grid else lon[:-1] + 0.5
    wlat = lat if shared_grid else lat[:-1] + 0.5
    waves = {"hs_m": hs, "wave_dir_deg": wave, "wave_period_s": rng.uniform(4.0, 12.0, shape)}
    fields = [WeatherField(k, a.astype(np.float32), lon, lat, time) for k, a in (("wind_u_ms", u), ("wind_v_ms", v))]
    fields += [
        WeatherField(k, a[:, : wlat.size, : wlon.size].astype(np.float32), wlon, wlat, time) for k, a in waves.items()
    ]
    return GriddedWeather(fields)


def _points(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points in and out of the grid (and on its lines), and offsets [h] in runs of equal times, some outside."""
    lon = rng.uniform(-27.0, -16.0, n)
    lat = rng.uniform(37.0, 47.0, n)
    runs = rng.uniform(-3.0, 20.0, n // 4 + 1).repeat(4)[:n]  # an arc's samples share a time
    runs[::5] = rng.uniform(-3.0, 20.0, runs[::5].size)
    lon[::3], lat[::3] = np.round(lon[::3]), np.round(lat[::3])  # on grid nodes (calm corners met exactly)
    runs[::3] = rng.choice([0.0, 6.0, 12.0, 18.0], runs[::3].size)  # at the data's times
    return lon, lat, runs


def _sample(w: GriddedWeather, prepared, offset_h, fields, fused: bool):  # type: ignore[no-untyped-def]
    with settings_context(fused_sampling=fused):
        return w.sample_at(prepared, DEP, offset_h=offset_h, fields=fields)


@settings(max_examples=25, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    times=st.sampled_from([0, 1, 5]),
    shared=st.booleans(),
    fields=st.sampled_from([None, ("tws_kn", "twd_deg"), ("tws_kn", "twd_deg", "hs_m", "wave_dir_deg"), ("hs_m",)]),
)
def test_fused_sampling_equals_the_separate_kernels(seed: int, times: int, shared: bool, fields) -> None:  # type: ignore[no-untyped-def]
    """sample_at turning the vectors as it interpolates gives the numbers of the components interpolated, then turned
    by the vector kernel: every field, NaN where NaN (missing cells, points or times outside), calm wind included."""
    w = _weather(seed, times, shared_grid=shared)
    rng = np.random.default_rng(seed)
    lon, lat, offset = _points(rng, 400)
    prepared = w.prepare(lon.reshape(100, 4), lat.reshape(100, 4))
    offset = offset.reshape(100, 4)
    got = _sample(w, prepared, offset, fields, True)
    want = _sample(w, prepared, offset, fields, False)
    for name in FIELDS:
        np.testing.assert_array_equal(getattr(got, name), getattr(want, name), err_msg=name)
    if (fields is None or "tws_kn" in fields) and times != 1:  # (one time: valid at that instant only)
        tws = got.tws_kn
        assert np.isnan(tws).any() and (tws == 0.0).any() and np.isfinite(tws).any()  # missing, calm and wind met


@pytest.mark.parametrize("times", [0, 1, 5])
def test_the_time_cell_kept_between_points_is_the_points_own(times: int) -> None:
    """Points sharing a time reuse its cell; each point's conditions are those sample() gives it alone."""
    w = _weather(3, times)
    lon, lat, offset = _points(np.random.default_rng(3), 200)
    got = w.sample_at(w.prepare(lon, lat), DEP, offset_h=offset)
    hours = np.round(offset * 3600.0 * 1e6).astype("timedelta64[us]")
    for k in range(0, lon.size, 9):  # one point at a time: no cell to keep
        alone = w.sample(lon[k], lat[k], DEP + hours[k])
        for name in FIELDS:
            np.testing.assert_array_equal(getattr(got, name)[k], getattr(alone, name), err_msg=f"{name} at {k}")


def _long_axis(rng: np.random.Generator, n: int, uneven: bool, start: float) -> np.ndarray:
    steps = rng.uniform(0.5, 8.0, n - 1)
    if uneven and n > 4:  # a few steps far below the others: the finder's bins are capped, cells stepped up rows
        steps[rng.choice(n - 1, 3, replace=False)] = 1e-6
    return start + np.concatenate([[0.0], np.cumsum(steps)])


@settings(max_examples=30, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n_twa=st.integers(2, 40),
    n_tws=st.integers(2, 40),
    uneven=st.booleans(),
    beyond=st.sampled_from(["clamp", "forbid"]),
)
def test_wind_kernel_speeds_are_numpys_on_any_axes(
    seed: int, n_twa: int, n_tws: int, uneven: bool, beyond: str
) -> None:
    """The compiled TWA, speed and time equal numpy's on short axes (counted) and long ones (the cell finder), even
    and very uneven, with points on the nodes, next to them, beyond both ends, calm, NaN and infinite wind."""
    rng = np.random.default_rng(seed)
    a = _long_axis(rng, n_twa, uneven, 0.0)
    start = rng.choice([0.0, 30.0])  # 30: a no-go zone below the first row
    twa_axis = start + a / a[-1] * (180.0 - start)
    tws_axis = _long_axis(rng, n_tws, uneven, rng.choice([0.0, 2.0]))
    speed = rng.uniform(0.0, 9.0, (n_twa, n_tws))
    polar = Polar(name="axes", twa_deg=twa_axis, tws_kn=tws_axis, speed_kn=speed)
    n = 3000
    tws = np.concatenate([rng.uniform(0.0, tws_axis[-1] + 5.0, n), tws_axis, np.nextafter(tws_axis, np.inf)])
    tws = np.concatenate([tws, [0.0, np.nan, np.inf]])
    twa_target = np.concatenate([rng.uniform(0.0, 180.0, n), twa_axis, np.nextafter(twa_axis, -np.inf), [0, 0, 0]])
    twa_target = np.resize(twa_target, tws.size)
    course = rng.uniform(0.0, 360.0, tws.size)
    twd = (course + twa_target) % 360.0
    twd[rng.random(tws.size) < 0.01] = np.nan
    seg = rng.uniform(0.0, 30.0, tws.size)
    twa, v, dt = sail_wind(tws, twd, course, seg, polar, beyond=beyond)
    from pyroute_rel.geodesy import angle_diff_deg

    want_twa = angle_diff_deg(twd, course)
    np.testing.assert_array_equal(twa, want_twa)
    with np.errstate(invalid="ignore"):
        np.testing.assert_array_equal(v, boat_speed_kn(polar, want_twa, tws, beyond=beyond))
    assert np.isfinite(v).any()


@pytest.mark.parametrize("n", [2, 3, 4, 30])
def test_cell_finder_lower_bound_steps_to_searchsorted(n: int) -> None:
    """The finder's first cell never passes the true one, and stepping up gives numpy's searchsorted cell."""
    rng = np.random.default_rng(n)
    axis = _long_axis(rng, n, True, 1.0)
    x0, scale, last, lower = cell_finder(axis)
    xs = np.concatenate([axis, np.nextafter(axis, -np.inf), np.nextafter(axis, np.inf), rng.uniform(-5, 250, 500)])
    xs = np.concatenate([xs, [-np.inf, np.inf]])
    top = n - 2
    want = np.clip(np.searchsorted(axis, xs, "right") - 1, 0, top)
    with np.errstate(invalid="ignore"):
        first = lower[np.minimum(np.maximum((xs - x0) * scale, 0.0), last).astype(np.intp)]
    assert np.all(first <= want)
    got = first.copy()
    for k in range(xs.size):
        while got[k] < top and axis[got[k] + 1] <= xs[k]:
            got[k] += 1
    np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize("apf", [1.0, 0.95])
def test_dp_is_the_same_with_the_fused_sampling_on_and_off(apf: float) -> None:
    """A forward DP over time-varying gridded weather with a failure model: arrivals, back-pointers, finish and
    counts the same with the vectors turned as they are interpolated or afterwards."""
    from tests.test_dp_glue import weather

    grid = make_grid((-13.0, 44.0), (-17.0, 41.0), n_ranks=5, n_nodes=7, spacing_km=30.0)
    w = weather(11)
    got = dp(grid, w, apf)
    with settings_context(fused_sampling=False):
        want = dp(grid, weather(11), apf)
    assert np.isfinite(got.finish_h) or apf < 1.0
    assert np.isfinite(got.arrival_h).sum() > got.arrival_h.shape[1]  # beyond the first rank
    np.testing.assert_array_equal(got.arrival_h, want.arrival_h)
    np.testing.assert_array_equal(got.back, want.back)
    assert (got.finish_h, got.finish_back, got.arcs_evaluated, got.arcs_forbidden, got.forbidden_by_reason) == (
        want.finish_h,
        want.finish_back,
        want.arcs_evaluated,
        want.arcs_forbidden,
        want.forbidden_by_reason,
    )


@pytest.mark.slow
@pytest.mark.parametrize("name", list_failure_models())
def test_compiled_evidence_index_is_the_models(name: str) -> None:
    """For every shipped failure model: the compiled evidence (quantities folded to the course, binned) is
    FailureModel.evidence_index of failure.arc_quantities: the same flat index everywhere (NaN points included: the
    fired criteria are read there) and the same unknown points, with values on the bin edges, beyond them and NaN."""
    from pyroute_rel._kernels.cost import evidence_index
    from pyroute_rel.reliability.failure import arc_quantities
    from pyroute_rel.weather import Conditions

    model = load_failure_model(name)
    rng = np.random.default_rng(len(name))
    shape = (300, 3)
    edges = np.concatenate([np.atleast_1d(np.asarray(c.edges, dtype=float)) for c in model.criteria])

    def field(low: float, high: float) -> np.ndarray:
        x = rng.uniform(low, high, shape)
        x.flat[::5] = rng.choice(edges, x.flat[::5].size)  # on edges (directions: relative to a zero course below)
        x.flat[::13] = np.nan
        return x

    course = rng.uniform(0.0, 360.0, shape)
    course.flat[::5] = 0.0
    cond = Conditions(
        tws_kn=field(0.0, 60.0),
        twd_deg=field(0.0, 360.0),
        hs_m=field(0.0, 12.0),
        wave_dir_deg=field(0.0, 360.0),
        wave_period_s=field(2.0, 18.0),
        current_u_ms=np.zeros(shape),
        current_v_ms=np.zeros(shape),
    )
    want_index, want_unknown = model.evidence_index(arc_quantities(cond, course, model.quantities))
    got_index, got_unknown = evidence_index(model, cond, course)
    np.testing.assert_array_equal(got_index, np.broadcast_to(want_index, shape))
    assert (got_unknown is None) == (want_unknown is None)
    if want_unknown is not None:
        np.testing.assert_array_equal(got_unknown, np.broadcast_to(want_unknown, shape))
    assert np.unique(got_index).size > 1
