"""Sailing many tracks in many ensemble members at once (issue 19's re-evaluation, made fast) gives, bit for bit, what
sailing each track alone in each member alone gives: the reference is ``evaluate_track`` (and ``sail_tracks``) of
one track in one member's weather, on a small time-varying gridded ensemble with waves, islands of missing data, an
exclusion zone, tracks that run out of the data's time, and the dickson2018 failure model at apf < 1 and = 1.

The pieces a leg is cut into are cut once for every member (``ArcPieces.take``): the same as cutting the legs alone.
A direction's variation bound stops at the first neighbour pair more than 90 deg apart: checked against the bound
computed from every neighbour pair with numpy. Nothing is kept from one call to the next (no cache to invalidate):
a second call with the members in another order gives the columns in that order.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from test_evaluate import load_example

from pyroute_rel import geodesy, load_scenario
from pyroute_rel.analysis import evaluate
from pyroute_rel.boat.polar import get_polar
from pyroute_rel.reliability import crossings
from pyroute_rel.reliability.crossings import arc_extremes, arc_pieces, needs_pieces
from pyroute_rel.reliability.failure import load_failure_model
from pyroute_rel.routing.cost import arc_geometry
from pyroute_rel.weather.base import Boundaries
from pyroute_rel.weather.gridded import GriddedWeather, WeatherField
from pyroute_rel.weather.io.readers import weather_from_dataset

N_MEMBERS = 3


def _ensemble() -> list[GriddedWeather]:
    make = load_example("make_ensemble_example")
    ds = make.make_ensemble(N_MEMBERS, resolution_deg=2.0, step_h=12.0, days=9.0)
    for name in ds.data_vars:  # islands of missing data: every field, and the waves alone elsewhere
        dims = ds[name].dims
        if {"latitude", "longitude"} <= set(dims):
            island = (abs(ds.latitude - 33.0) <= 2.0) & (abs(ds.longitude + 20.0) <= 2.0)
            ds[name] = ds[name].where(~island)
            if name.startswith(("swh", "mwd", "mwp")):
                ds[name] = ds[name].where(~((abs(ds.latitude - 41.0) <= 2.0) & (abs(ds.longitude + 30.0) <= 2.0)))
    return [weather_from_dataset(ds, member=k) for k in range(N_MEMBERS)]


MEMBERS = _ensemble()


def _tracks(seed: int, n: int) -> list[np.ndarray]:
    """Random tracks across the data: 2 to 9 points, some long enough to outlast the data's 9 days."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        k = int(rng.integers(2, 10))
        start = rng.uniform([-36.0, 24.0], [-10.0, 50.0])
        steps = rng.normal(0.0, 1.5, (k - 1, 2)) + rng.uniform(-2.5, 2.5, 2)
        pts = np.vstack([start, start + np.cumsum(steps, axis=0)])
        out.append(np.clip(pts, [-39.0, 21.0], [-1.0, 54.0]))
    return out


def _scenario(tmp_path: Path, apf: float):
    ring = [[-26.0, 44.0], [-22.0, 44.0], [-22.0, 47.0], [-26.0, 47.0], [-26.0, 44.0]]
    zone = {"type": "Polygon", "coordinates": [ring]}
    (tmp_path / "zone.geojson").write_text(json.dumps(zone))
    (tmp_path / "s.toml").write_text(
        '[route]\nstart = [-14.0, 31.0]\nfinish = [-26.0, 22.0]\ndeparture = "2018-06-01T00:00:00Z"\n'
        '[grid]\nn_ranks = 8\n[avoid]\nland = false\nzones = ["zone.geojson"]\n'
        '[weather]\nkind = "uniform"\ntws_kn = 12.0\ntwd_deg = 0.0\n'
        f'[failure]\nmodel = "dickson2018"\napf = {apf}\n'
    )
    return load_scenario(tmp_path / "s.toml")


@pytest.mark.slow
@pytest.mark.parametrize("apf", [0.02, 1.0])
def test_tracks_sailed_in_members_together_are_each_track_evaluated_alone(tmp_path: Path, apf: float):
    sc = _scenario(tmp_path, apf)
    problem = evaluate.evaluation_problem(sc)
    problems = [replace(problem, weather=w) for w in MEMBERS]
    tracks = [
        *_tracks(seed=2, n=3),
        np.array([[-24.0, 33.5], [-16.0, 33.0]]),  # through the island of missing weather
        np.array([[-29.0, 45.5], [-27.0, 45.0], [-19.0, 45.5]]),  # through the zone
        np.array([[-38.0, 40.0], [-2.0, 42.0], [-38.0, 44.0], [-30.0, 44.0]]),  # past the data's end
    ]
    together = evaluate.sail_in_members(problems, tracks, avoid=sc.avoid)
    fig = evaluate.member_figures(problems, tracks, avoid=sc.avoid)
    assert fig.voyage_time_h.shape == (len(tracks), N_MEMBERS)
    reasons = set()
    for j, w in enumerate(MEMBERS):
        for i, track in enumerate(tracks):
            ev = evaluate.evaluate_track(sc, track, weather=w)  # the reference: this track in this member alone
            alone = evaluate.sail_tracks(problems[j], [track], avoid=sc.avoid)[0]
            got = together[j][i]
            for name in ("elapsed_h", "land", "zone"):
                assert np.array_equal(getattr(got, name), getattr(alone, name), equal_nan=name == "elapsed_h")
            for name in ("time_h", "p_f", "reason"):
                a, b = getattr(got.costs, name), getattr(alone.costs, name)
                assert a.tobytes() == b.tobytes(), (name, i, j)
            assert got.elapsed_h.tobytes() == ev.elapsed_h.tobytes()
            assert fig.voyage_time_h[i, j].tobytes() == np.float64(ev.voyage_time_h).tobytes()
            assert fig.max_p_f[i, j] == alone.max_p_f
            assert fig.feasible[i, j] == ev.feasible == alone.feasible
            flat = {r for leg in ev.leg_reasons for r in leg}
            assert fig.over_apf[i, j] == ("p_f" in flat)
            assert fig.on_land[i, j] == ("land" in flat)
            assert fig.blocked[i, j] == bool(flat - {"p_f"})
            reasons |= flat
    # the cases compared: legs over apf (apf < 1), in the zone, through missing weather, past the data's end
    assert {"zone", "weather"} <= reasons and (("p_f" in reasons) == (apf < 1.0))
    assert np.isfinite(fig.voyage_time_h).any() and np.isinf(fig.voyage_time_h).any()
    # nothing kept from the call before: the members in another order give their columns in that order
    again = evaluate.member_figures(problems[::-1], tracks, avoid=sc.avoid)
    assert again.voyage_time_h.tobytes() == fig.voyage_time_h[:, ::-1].tobytes()
    assert again.max_p_f.tobytes() == fig.max_p_f[:, ::-1].tobytes()


def test_pieces_taken_for_some_arcs_are_those_arcs_cut_alone():
    rng = np.random.default_rng(3)
    a = geodesy.to_xyz(rng.uniform(-40.0, 0.0, 40), rng.uniform(20.0, 55.0, 40))
    b = geodesy.to_xyz(rng.uniform(-40.0, 0.0, 40), rng.uniform(20.0, 55.0, 40))
    bounds = Boundaries(np.arange(-40.0, 1.0, 2.0), np.arange(20.0, 56.0, 2.0), None, True)
    idx = np.array([5, 5, 0, 39, 12, 7, 7, 7, 30])  # any order, repeats
    taken = arc_pieces(a, b, bounds).take(idx)
    alone = arc_pieces(a[idx], b[idx], bounds)
    for name in ("a_xyz", "u_xyz", "omega", "arc", "s0", "s1", "lon_deg", "lat_deg", "course_deg"):
        assert getattr(taken, name).tobytes() == getattr(alone, name).tobytes(), name
    assert alone.arc.size > 2 * idx.size  # the arcs cross grid lines: pieces to take
    # and judged with them, in a time-varying member: the numbers of arc_extremes cutting the arcs itself
    model = load_failure_model("dickson2018")
    t0, dt = rng.uniform(0.0, 100.0, idx.size), rng.uniform(5.0, 60.0, idx.size)
    kw = dict(
        departure=np.datetime64("2018-06-01T00:00", "s"),
        weather=MEMBERS[1],
        polar=get_polar("maribot_vane"),
        failure=model,
    )
    cut = arc_pieces(a, b, MEMBERS[1].boundaries).take(idx)
    with_pieces = arc_extremes(a[idx], b[idx], t0, dt, pieces=cut, **kw)
    without = arc_extremes(a[idx], b[idx], t0, dt, **kw)
    assert with_pieces.p_f.tobytes() == without.p_f.tobytes() and with_pieces.pieces == without.pieces


def test_vertices_that_are_a_pieces_points_are_not_sampled_again_and_change_nothing(monkeypatch: pytest.MonkeyPatch):
    """The quantities at each parabola's vertex copied where the vertex is one of the piece's three points: the
    same numbers as sampling every vertex (the reference: the weather sampled at all of them)."""
    rng = np.random.default_rng(8)
    n = 300
    a = geodesy.to_xyz(rng.uniform(-38.0, -2.0, n), rng.uniform(22.0, 53.0, n))
    b = geodesy.to_xyz(rng.uniform(-38.0, -2.0, n), rng.uniform(22.0, 53.0, n))
    t0, dt = rng.uniform(0.0, 150.0, n), rng.uniform(5.0, 60.0, n)
    kw = dict(departure=np.datetime64("2018-06-01T00:00", "s"), weather=MEMBERS[2], polar=get_polar("maribot_vane"))
    model = load_failure_model("dickson2018")
    fast = arc_extremes(a, b, t0, dt, failure=model, apf=0.02, **kw)
    sampled = []

    def every_vertex(judge, pieces, timing, rv, q):  # the vertices sampled, all of them
        fv = pieces.s0[:, None] + (pieces.s1 - pieces.s0)[:, None] * rv
        tv = timing.at(pieces.arc, fv)
        lon, lat, course = crossings._points(pieces.a_xyz, pieces.u_xyz, pieces.omega, pieces.arc, fv)
        sampled.append(lon.size)
        return {k: v for k, (v, _) in crossings._quantities(judge, lon, lat, course, tv).items()}

    monkeypatch.setattr(crossings, "_at_vertices", every_vertex)
    slow = arc_extremes(a, b, t0, dt, failure=model, apf=0.02, **kw)
    assert fast.p_f.tobytes() == slow.p_f.tobytes() and fast.fired_bits.tobytes() == slow.fired_bits.tobytes()
    assert np.unique(fast.p_f).size > 2 and sampled[0] == 2 * fast.pieces  # several p_f; two quantities a piece


def _wave_weather(directions: np.ndarray) -> GriddedWeather:
    """Uniform wind and 2 m waves from ``directions`` [deg] (time, lat, lon) on a 1-degree grid, 6-hourly."""
    nt, ny, nx = directions.shape
    lon, lat = np.arange(nx, dtype=float) - 30.0, np.arange(ny, dtype=float) + 30.0
    time = np.datetime64("2018-06-01T00:00", "ns") + np.arange(nt) * np.timedelta64(6, "h")
    ones = np.ones(directions.shape)

    def field(name: str, values: np.ndarray) -> WeatherField:
        return WeatherField(name, values, lon, lat, time, source="test", variable=name)

    return GriddedWeather(
        [
            field("wind_u_ms", 5.0 * ones),
            field("wind_v_ms", ones),
            field("hs_m", 2.0 * ones),
            field("wave_dir_deg", directions),
        ]  # fmt: skip
    )


def _angle_sum(directions: np.ndarray) -> float:
    """The largest angle between neighbours' directions along each axis, summed [deg]: every neighbour pair's angle
    from their unit vectors as stored (float32 sine and cosine), ``acos(a.b / (|a| |b|))``."""
    rad = np.deg2rad(directions.astype(np.float32))
    s, c = np.sin(rad).astype(float), np.cos(rad).astype(float)
    total = 0.0
    for axis in (2, 1, 0):  # lon, lat, time
        n = directions.shape[axis] - 1
        ax, ay = (np.take(x, np.arange(n), axis=axis) for x in (s, c))
        bx, by = (np.take(x, np.arange(1, n + 1), axis=axis) for x in (s, c))
        cos = (ax * bx + ay * by) / np.sqrt((ax * ax + ay * ay) * (bx * bx + by * by))
        total += float(np.degrees(np.arccos(min(1.0, max(-1.0, float(cos.min()))))))
    return total


def test_a_directions_variation_is_its_neighbours_largest_angles_or_none_past_90_deg():
    rng = np.random.default_rng(5)
    smooth = 100.0 + np.cumsum(rng.uniform(0.0, 3.0, (6, 5, 7)), axis=2) + rng.uniform(0.0, 2.0, (6, 5, 7))
    v = _wave_weather(smooth).variation("wave_dir_deg")
    spread = _angle_sum(smooth)  # the bound from every neighbour pair
    assert v is not None and 10.0 < spread < 90.0
    assert (v.fixed, v.per_lon, v.per_lat, v.per_h) == (4.0 * spread, spread, spread, spread / 6.0)
    rough = smooth.copy()
    rough[4, 3, 2] += 120.0  # one neighbour pair over 90 deg apart: no bound
    assert _angle_sum(rough) >= 90.0
    w = _wave_weather(rough)
    assert w.variation("wave_dir_deg") is None
    # needs_pieces then says "any arc may need it" before sampling the weather (which would fail here)
    geom = arc_geometry(-28.0, 31.0, -25.0, 33.0, samples=4)
    w.sample = w.sample_at = None  # type: ignore[method-assign]
    model = load_failure_model("dickson2018")
    none = needs_pieces(geom.lon_deg, geom.lat_deg, geom.course_deg, geom.seg_nm, np.zeros(()), np.ones(()),
                        weather=w, failure=model, departure=np.datetime64("2018-06-01T00:00", "s"))  # fmt: skip
    assert none is None


def test_members_stacked_within_a_box_answer_as_stacked_whole_and_refuse_points_outside():
    from pyroute_rel.errors import WeatherError
    from pyroute_rel.weather.gridded import stack_members

    rng = np.random.default_rng(11)
    box = (-31.3, -17.0, 29.5, 40.2)  # grid lines every 2 deg (odd latitudes): cells [-32, -16] x [29, 41] stacked
    lon = rng.uniform(box[0], box[1], (40, 3))
    lat = rng.uniform(box[2], box[3], (40, 3))
    lon[0, 0], lat[1, 1], lon[2, 2], lat[3, 0] = box[0], box[3], -18.0, 31.0  # on the box edges, on grid lines
    member = np.sort(rng.integers(0, N_MEMBERS, 40))
    off = rng.uniform(0.0, 230.0, (40, 3))  # past the data's 9 days too
    whole, part = stack_members(MEMBERS), stack_members(MEMBERS, box=box)
    assert whole is not None and part is not None
    assert part.nbytes == whole.nbytes * (9 * 7) // (21 * 18)  # 9 of 21 longitudes, 7 of 18 latitudes
    kw = dict(offset_h=off)
    a = whole.sample_at(whole.prepare(lon, lat, member), np.datetime64("2018-06-01T00:00", "ns"), **kw)
    b = part.sample_at(part.prepare(lon, lat, member), np.datetime64("2018-06-01T00:00", "ns"), **kw)
    for name in ("tws_kn", "twd_deg", "hs_m", "wave_dir_deg", "wave_period_s"):
        assert getattr(a, name).tobytes() == getattr(b, name).tobytes(), name
    assert np.isnan(a.hs_m).any() and np.isfinite(a.hs_m).any()  # the islands and past the data's end, compared
    with pytest.raises(WeatherError, match="points outside the stacked members' box"):
        part.prepare(lon + 0.5, lat, member)
    wide = stack_members(MEMBERS, box=(-45.0, -17.0, 29.5, 40.2))  # past the grid's longitudes: all of them kept
    assert wide is not None and wide.nbytes == whole.nbytes * 7 // 18
