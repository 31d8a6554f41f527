"""Data derived from an immutable object is kept by that object, never in a table keyed by its identity (issue 33):
a polar's and a manoeuvre table's kernel tables, and the owner of points a gridded source located. Each test makes
objects one after another (so that a new one may take a dead one's id) and checks that every answer is the new
object's own."""

from __future__ import annotations

import gc

import numpy as np
import pytest

from pyroute_rel._kernels import polar as polar_compiled
from pyroute_rel._kernels.cost import sail_wind
from pyroute_rel.boat.manoeuvre import ManoeuvrePenalties
from pyroute_rel.boat.polar import Polar, boat_speed_kn
from pyroute_rel.errors import WeatherError
from pyroute_rel.weather import GriddedWeather, WeatherField

DEP = np.datetime64("2018-06-01T00:00:00")


def polar(seed: int) -> Polar:
    rng = np.random.default_rng(seed)
    twa = np.array([0.0, 40.0, 60.0, 90.0, 120.0, 180.0])
    tws = np.array([0.0, 8.0, 16.0, 24.0])
    speed = rng.uniform(1.0, 9.0, (twa.size, tws.size))
    speed[0] = 0.0
    speed[:, 0] = 0.0
    return Polar(name=f"p{seed}", twa_deg=twa, tws_kn=tws, speed_kn=speed)


@pytest.mark.slow
def test_each_polar_is_sailed_with_its_own_tables() -> None:
    """Twenty polars made and dropped one after another (ids are reused): the compiled speeds are each polar's own
    (the numpy path's), and its kernel tables are kept by the polar itself."""
    tws = np.full((50, 1), 13.0)
    twd = np.zeros((50, 1))
    course = np.linspace(0.0, 359.0, 50)[:, None]
    seg = np.ones((50, 1))
    for seed in range(20):
        p = polar(seed)
        _, v, _ = sail_wind(tws, twd, course, seg, p, beyond="clamp")
        want = boat_speed_kn(p, np.minimum(course, 360.0 - course), tws, beyond="clamp")
        np.testing.assert_allclose(v, want, rtol=1e-12, atol=1e-12)
        assert polar_compiled.tables(p) is polar_compiled.tables(p)  # made once, kept by the polar
        np.testing.assert_array_equal(polar_compiled.tables(p)[2], p.speed_kn.reshape(-1))
        del p
        gc.collect()


@pytest.mark.slow
def test_each_manoeuvre_table_is_its_own() -> None:
    from pyroute_rel._kernels.dp import _penalty_tables

    for k in range(10):
        p = ManoeuvrePenalties(tack_s=[[0.0, 100.0 * (k + 1)], [20.0, 50.0]], gybe_s=[[8.0, 10.0 * (k + 1)]])
        got = _penalty_tables(p)
        assert got is _penalty_tables(p)
        np.testing.assert_array_equal(got[1], np.asarray(p.tack_penalty_s, dtype=float))
        np.testing.assert_array_equal(got[3], np.asarray(p.gybe_penalty_s, dtype=float))
        del p, got
        gc.collect()


def weather(shift: float) -> GriddedWeather:
    lon, lat = np.arange(-20.0, -9.9, 1.0) + shift, np.arange(35.0, 45.01, 1.0)
    time = DEP.astype("datetime64[ns]") + np.arange(5) * np.timedelta64(6, "h")
    rng = np.random.default_rng(int(shift * 10))
    shape = (time.size, lat.size, lon.size)
    return GriddedWeather(
        [
            WeatherField(k, rng.uniform(-8.0, 8.0, shape).astype(np.float32), lon, lat, time, source="t", variable=k)
            for k in ("wind_u_ms", "wind_v_ms")
        ]
    )


@pytest.mark.slow
def test_points_located_by_a_dropped_source_are_not_taken_by_a_new_one() -> None:
    """A new source (which may have the dropped one's id) refuses points the dropped one located, on another grid;
    a source on the same grid takes them over (:meth:`GriddedWeather.reuse`) and samples them as its own."""
    lon, lat = np.array([-15.3, -12.1]), np.array([39.2, 41.7])
    for k in range(10):
        old = weather(0.5 * k)
        prepared = old.prepare(lon, lat)
        del old
        gc.collect()
        new = weather(0.5 * k + 0.25)  # another grid
        with pytest.raises(WeatherError, match="prepared for another weather source"):
            new.sample_at(prepared, DEP, offset_h=np.zeros(2))
        assert new.reuse(prepared) is None
        same = weather(0.5 * k + 0.25)
        mine = same.reuse(same.prepare(lon, lat))
        taken = new.reuse(mine)
        assert taken is not None
        np.testing.assert_array_equal(
            new.sample_at(taken, DEP, offset_h=np.zeros(2)).tws_kn, new.sample(lon, lat, DEP).tws_kn
        )
