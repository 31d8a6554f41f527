"""Arcs with an end on a patch edge (a waypoint, start, finish or grid node there) are judged by their interior.

Found in session 9 (tests/test_tradeoff.py's course through the waypoint (-14, 44.5), on the north edge of the patch
lon -15..-13, lat 43.5..44.5): :func:`pyroute_rel.reliability.crossings.split_fractions` found the edge through an arc's
end a hair inside the arc (fraction 1 - 1.3e-14, or 6e-15 from the start), and the sliver piece it cut off was sampled
on the edge itself, inside the closed box: some arcs that only touch the patch at the waypoint got its p_f (0.9), others
in the same position not (the crossing rounded outside the arc), and a source without boundaries (time-varying costing,
the arc one piece) never. A crossing within ``NUDGE`` of an end now cuts nothing off.

The reference is independent of :mod:`pyroute_rel.reliability.crossings` and of the cost function: each arc's interior
densified every 20 m by a spherical interpolation written out here, the patch by a box test written out here, the table
by ``FailureModel.p_fail``.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Any

import numpy as np
import pytest

from pyroute_rel.boat.polar import get_polar
from pyroute_rel.geodesy import to_xyz
from pyroute_rel.reliability.crossings import NUDGE, split_fractions
from pyroute_rel.reliability.failure import load_failure_model
from pyroute_rel.routing.cost import arc_costs
from pyroute_rel.weather import Patch, UniformWeather, WeatherBase

R_KM = 6371.0088
DEPARTURE = np.datetime64("2018-06-01T00:00")
BOX = (-15.0, -13.0, 43.5, 44.5)  # lon min, max, lat min, max
MODEL = load_failure_model("dickson2018")
BASE = {"tws_kn": 15.0, "twd_deg": 0.0, "hs_m": 1.0, "wave_dir_deg": 0.0}
WEATHER = UniformWeather(**BASE, patches=(Patch(lon=BOX[:2], lat=BOX[2:], values={"hs_m": 4.0}),))


@dataclass(frozen=True)
class Boundless(WeatherBase):
    """The same weather as a source that varies in time and says nothing of where it changes (the arc is judged as
    one piece, its ends nudged inside)."""

    inner: Any
    steady = False
    time_steps = None

    @property
    def fields(self) -> frozenset[str]:
        return self.inner.fields

    @property
    def max_current_ms(self) -> float:
        return self.inner.max_current_ms

    def sample(self, lon: Any, lat: Any, time: Any) -> Any:
        return self.inner.sample(lon, lat, time)

    def check_coverage(self, *args: Any) -> None:
        return None

    def prepare(self, lon: Any, lat: Any) -> tuple[Any, Any]:
        return lon, lat

    def sample_at(self, prepared: Any, departure: Any, *, offset_h: Any = None, fields: Any = None) -> Any:
        return self.inner.sample(*prepared, departure)  # steady inside: the time does not matter


def interior(lon0: float, lat0: float, lon1: float, lat1: float) -> tuple[float, bool]:
    """The largest p_f on the arc's interior (both ends left out) densified every 20 m, and whether that interior
    has a point in the box."""
    a, b = (np.array([np.cos(np.radians(la)) * np.cos(np.radians(lo)), np.cos(np.radians(la)) * np.sin(np.radians(lo)),
                      np.sin(np.radians(la))]) for lo, la in ((lon0, lat0), (lon1, lat1)))  # fmt: skip
    om = float(np.arccos(np.clip(a @ b, -1.0, 1.0)))
    n = max(2, int(np.ceil(om * R_KM / 0.02)))
    t = np.linspace(0.0, 1.0, n + 1)[1:-1, None]
    p = (np.sin((1 - t) * om) * a + np.sin(t * om) * b) / np.sin(om)
    v = (-np.cos((1 - t) * om) * a + np.cos(t * om) * b) * om / np.sin(om)  # the direction of travel
    lo, la = np.arctan2(p[:, 1], p[:, 0]), np.arcsin(np.clip(p[:, 2], -1, 1))
    east = -np.sin(lo) * v[:, 0] + np.cos(lo) * v[:, 1]
    north = -np.sin(la) * np.cos(lo) * v[:, 0] - np.sin(la) * np.sin(lo) * v[:, 1] + np.cos(la) * v[:, 2]
    lo, la, course = np.degrees(lo), np.degrees(la), np.degrees(np.arctan2(east, north)) % 360.0
    inside = (lo >= BOX[0]) & (lo <= BOX[1]) & (la >= BOX[2]) & (la <= BOX[3])
    hs = np.where(inside, 4.0, BASE["hs_m"])
    awd = np.abs((BASE["wave_dir_deg"] - course + 180.0) % 360.0 - 180.0)
    return float(MODEL.p_fail({"hs_m": hs, "awd_deg": awd}).max()), bool(inside.any())


def edge_arcs() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Arcs of 20 to 60 km from points on the box's edges (corners, the two-leg course's waypoint (-14, 44.5), and
    points along each edge), in 18 directions, each sailed away from the edge point and towards it; and the first
    legs of that course's grid, whose ends are its nodes and the waypoint."""
    rng = np.random.default_rng(9)
    w, e, s, n = BOX
    pts = [(w, s), (w, n), (e, s), (e, n), (-14.0, 44.5)]
    pts += [(x, y) for x in rng.uniform(w, e, 3) for y in (s, n)] + [
        (x, y) for y in rng.uniform(s, n, 3) for x in (w, e)
    ]
    lon0, lat0, lon1, lat1 = [], [], [], []
    for x, y in pts:
        for ang in np.radians(np.arange(18) * 20.0 + rng.uniform(-5.0, 5.0)):
            d = rng.uniform(0.2, 0.55)
            fx, fy = x + d * np.sin(ang) / np.cos(np.radians(y)), y + d * np.cos(ang)
            lon0 += [x, fx]
            lat0 += [y, fy]
            lon1 += [fx, x]
            lat1 += [fy, y]
    # the arcs of the two-leg course into and out of the waypoint (their nodes are the grid's, as computed)
    into = [(-12.870558472974693, 43.72408178745204), (-13.101998393402312, 44.197547133559745),
            (-13.337185973812836, 44.67053765772632), (-13.576241851181464, 45.14303757496147),
            (-13.81929133216454, 45.61503045785762)]  # fmt: skip
    out = [(-13.31510189517465, 43.02875078151132), (-13.990973083085805, 43.51834666792356),
           (-14.677856195910977, 44.003896585986716), (-15.376026850262576, 44.48526397233116),
           (-16.085763118727613, 44.9623077489332)]  # fmt: skip
    for (x, y), (u, v) in zip(into, out, strict=True):
        lon0 += [x, -14.0]
        lat0 += [y, 44.5]
        lon1 += [-14.0, u]
        lat1 += [44.5, v]
    return np.array(lon0), np.array(lat0), np.array(lon1), np.array(lat1)


ARCS = edge_arcs()


@functools.cache
def reference() -> list[tuple[float, bool]]:
    return [interior(*arc) for arc in zip(*ARCS, strict=True)]


@pytest.mark.slow
def test_an_arc_with_an_end_on_a_patch_edge_has_its_interiors_p_f():
    """Every arc from or to a point on an edge: the cost function's p_f (samples and crossings) is the largest met on
    its interior densified every 20 m; an arc that only touches the box at its end point meets nothing of it."""
    lon0, lat0, lon1, lat1 = ARCS
    polar = get_polar("maribot_vane")
    costs = arc_costs(lon0, lat0, lon1, lat1, 0.0, departure=DEPARTURE, weather=WEATHER, polar=polar, failure=MODEL)
    ref = np.array([p for p, _ in reference()])
    assert set(np.unique(ref).tolist()) == {0.0, 0.9, 1.0}  # arcs outside, into 4 m waves, and into head seas in them
    np.testing.assert_array_equal(costs.p_f, ref)
    # the discriminating arcs: the waypoint's, touching the box only there, in 1 m seas (WH does not fire) and with
    # waves abaft the beam (nor WD): p_f 0, however the crossing of the edge through their end rounds
    assert (ref[-10:] == 0.0).sum() >= 4


def test_steady_and_boundless_costing_agree_on_arcs_that_touch_a_patch_at_an_end():
    """The time-varying costing of a source without boundaries judges an arc as one piece with its ends nudged
    inside; the steady costing cuts it at the patch edges. On an arc whose interior stays out of the box, both give
    the interior's p_f (they differed at the waypoint of tests/test_tradeoff.py's course: 0.9 and 0)."""
    lon0, lat0, lon1, lat1 = ARCS
    outside = np.array([p == 0.0 and not enters for p, enters in reference()])
    assert outside.sum() > 30
    polar = get_polar("maribot_vane")
    kw = {"departure": DEPARTURE, "polar": polar, "failure": MODEL}
    args = (lon0[outside], lat0[outside], lon1[outside], lat1[outside], 0.0)
    steady = arc_costs(*args, weather=WEATHER, **kw)
    boundless = arc_costs(*args, weather=Boundless(WEATHER), **kw)
    np.testing.assert_array_equal(steady.p_f, 0.0)
    np.testing.assert_array_equal(boundless.p_f, 0.0)
    # the time-varying march cuts its steps every MAX_STEP_H on a source without time steps: the same time to rounding
    np.testing.assert_allclose(boundless.time_h, steady.time_h, rtol=1e-13)


@pytest.mark.parametrize(("lon", "lat"), [(-14.0, 44.5), (-15.0, 44.0), (-13.0, 43.5), (-14.3, 43.5)])
def test_no_crossing_is_found_within_the_nudge_of_an_arc_end(lon, lat):
    """Lines through an arc's end: no split fraction within NUDGE of 0 or 1, whatever the direction."""
    from pyroute_rel.weather.base import Boundaries

    bounds = Boundaries(np.array(BOX[:2]), np.array(BOX[2:]), np.array([BOX]), continuous=False)
    ang = np.radians(np.arange(0.0, 360.0, 7.5))
    lon1 = lon + 0.4 * np.sin(ang) / np.cos(np.radians(lat))
    lat1 = lat + 0.4 * np.cos(ang)
    a = to_xyz(np.full(ang.size, lon), np.full(ang.size, lat))
    b = to_xyz(lon1, lat1)
    for f in (split_fractions(a, b, bounds), split_fractions(b, a, bounds)):
        f = f[np.isfinite(f)]
        assert np.all((f > NUDGE) & (f < 1.0 - NUDGE))
