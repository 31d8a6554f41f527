"""The exact crab angle (pyroute_rel.boat.crab, issue 16 item 3) against independent references.

- Closed form: with a polar of one speed V at every angle, ``sin(delta) = -c_cross / V`` and the speed made good
  is ``sqrt(V**2 - c_cross**2) + c_along``.
- Scalar reference: for each point, headings scanned every 0.01 deg and every sign change refined with
  ``scipy.optimize.brentq`` (an independent root finder), the best speed made good kept.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from scipy.optimize import brentq, minimize_scalar

from pyroute_rel.boat.crab import hold_course
from pyroute_rel.boat.polar import BUILTIN_POLARS, MIN_SPEED_KN, Polar, boat_speed_kn
from pyroute_rel.units import KN_PER_MS

VANE = BUILTIN_POLARS["maribot_vane"]


def _flat(v_kn: float) -> Polar:
    return Polar("flat", twa_deg=[0.0, 180.0], tws_kn=[0.0, 40.0], speed_kn=[[v_kn, v_kn], [v_kn, v_kn]])


@pytest.mark.slow
@settings(max_examples=200, deadline=None)
@given(
    course=st.floats(0.0, 359.9),
    speed=st.floats(0.5, 12.0),
    cur_dir=st.floats(0.0, 359.9),
    cur=st.floats(0.0, 3.0),
)
def test_constant_speed_polar_matches_the_closed_form(course, speed, cur_dir, cur) -> None:
    u, v = cur * math.sin(math.radians(cur_dir)), cur * math.cos(math.radians(cur_dir))
    s = hold_course(course, 45.0, 10.0, u, v, _flat(speed))
    crs = math.radians(course)
    c_along = (u * math.sin(crs) + v * math.cos(crs)) * KN_PER_MS
    c_cross = (u * math.cos(crs) - v * math.sin(crs)) * KN_PER_MS
    if abs(c_cross) >= speed:  # no heading cancels the cross current
        assert not bool(s.ok)
        return
    sog = math.sqrt(speed**2 - c_cross**2) + c_along
    if sog < MIN_SPEED_KN:
        assert not bool(s.ok)
        return
    assert bool(s.ok)
    assert float(s.sog_kn) == pytest.approx(sog, rel=1e-9, abs=1e-9)
    delta = math.degrees(math.asin(-c_cross / speed))
    assert float(s.heading_deg) == pytest.approx((course + delta) % 360.0, abs=1e-7) or abs(
        float(s.heading_deg) - (course + delta) % 360.0
    ) == pytest.approx(360.0, abs=1e-7)


def _reference(course, twd, tws, u, v, polar, factor=1.0):
    """Best speed made good over all headings that hold the course, or None: g sampled every 0.01 deg, at the
    headings where the true wind angle meets a polar angle, and at g's extremes between those headings (scipy's
    bounded minimize_scalar), every sign change refined with scipy's brentq."""
    crs = math.radians(course)
    c_along = (u * math.sin(crs) + v * math.cos(crs)) * KN_PER_MS
    c_cross = (u * math.cos(crs) - v * math.sin(crs)) * KN_PER_MS

    def V(d):  # noqa: N802
        twa = abs(((twd - (course + d)) + 180.0) % 360.0 - 180.0)
        return float(boat_speed_kn(polar, twa, tws)) * factor

    def g(d):
        return V(d) * math.sin(math.radians(d)) + c_cross

    if c_cross == 0.0:
        return V(0.0) + c_along
    rel = twd - course
    knots = [((rel - s * a + 180.0) % 360.0) - 180.0 for a in (*polar.twa_deg, 0.0, 180.0) for s in (1, -1)]
    grid = np.unique(np.concatenate([np.linspace(-90.0, 90.0, 18001), [k for k in knots if -90 < k < 90], [0.0]]))
    twa = np.abs(((twd - (course + grid)) + 180.0) % 360.0 - 180.0)
    vals = boat_speed_kn(polar, twa, tws) * factor * np.sin(np.radians(grid)) + c_cross
    points = [(float(d), float(x)) for d, x in zip(grid, vals, strict=True)]
    edges = sorted({-90.0, 90.0, *(k for k in knots if -90 < k < 90)})
    for a, b in zip(edges[:-1], edges[1:], strict=True):  # between knots g may turn once: add its extremes
        for sign in (1.0, -1.0):
            m = minimize_scalar(
                lambda d, sign=sign: -sign * g(d), bounds=(a, b), method="bounded", options={"xatol": 1e-13}
            )
            points.append((float(m.x), g(float(m.x))))
    points.sort()
    best = None
    for (a, ga), (b, gb) in zip(points[:-1], points[1:], strict=True):
        if ga == 0.0:
            root = a
        elif (ga < 0) != (gb < 0) and gb != 0.0:
            root = brentq(g, a, b, xtol=1e-300, rtol=4 * np.finfo(float).eps, maxiter=3000)  # roots near 1e-262 deg
        else:
            continue
        sog = V(root) * math.cos(math.radians(root)) + c_along
        best = sog if best is None else max(best, sog)
    return best


@settings(max_examples=50, deadline=None)
@given(
    course=st.floats(0.0, 359.9),
    twd=st.floats(0.0, 359.9),
    tws=st.floats(2.0, 24.0),
    cur_dir=st.floats(0.0, 359.9),
    cur=st.floats(0.01, 1.5),
    factor=st.sampled_from([1.0, 0.7]),
)
@example(course=0.0, twd=1.0, tws=2.0, cur_dir=3e-262, cur=1.0, factor=1.0)  # cross currents of ~1e-262 kn
@example(course=1.2e-226, twd=0.01, tws=2.0, cur_dir=0.0, cur=1.0, factor=1.0)
def test_speed_made_good_equals_a_scanned_exact_root(course, twd, tws, cur_dir, cur, factor) -> None:
    """The acceptance of issue 16 item 3: the speed made good equals the exact root's to 1e-6 (relative)."""
    u, v = cur * math.sin(math.radians(cur_dir)), cur * math.cos(math.radians(cur_dir))
    s = hold_course(course, twd, tws, u, v, VANE, speed_factor=factor)
    ref = _reference(course, twd, tws, u, v, VANE, factor)
    if ref is None or ref < MIN_SPEED_KN:
        assert not bool(s.ok)
        return
    assert bool(s.ok)
    assert float(s.sog_kn) == pytest.approx(ref, rel=1e-6)
    # the heading really holds the course: no velocity across it
    crs = math.radians(course)
    c_cross = (u * math.cos(crs) - v * math.sin(crs)) * KN_PER_MS
    delta = math.radians(float(s.heading_deg) - course)
    assert float(s.boat_speed_kn) * math.sin(delta) + c_cross == pytest.approx(0.0, abs=1e-8)
    assert float(s.boat_speed_kn) == pytest.approx(
        float(boat_speed_kn(VANE, float(s.twa_deg), tws)) * factor, rel=1e-12
    )


def test_without_current_the_craft_steers_its_course() -> None:
    course = np.array([0.0, 45.0, 200.0])
    s = hold_course(course, 90.0, 12.0, 0.0, 0.0, VANE)
    np.testing.assert_array_equal(s.heading_deg, course)
    np.testing.assert_array_equal(s.sog_kn, boat_speed_kn(VANE, np.abs(90.0 - course) % 360, 12.0))
    assert s.ok.all()


def test_a_current_no_heading_can_stem_cannot_be_sailed() -> None:
    # 3 m/s (5.8 kn) across the course; the vane polar tops out near 5 kn in 12 kn of wind
    s = hold_course(0.0, 90.0, 12.0, 3.0, 0.0, VANE)
    assert not bool(s.ok)
    assert float(s.sog_kn) == 0.0


def test_shapes_broadcast() -> None:
    s = hold_course(np.zeros((2, 3)), 90.0, 12.0, 0.3, np.zeros(3), VANE)
    assert s.heading_deg.shape == s.sog_kn.shape == s.ok.shape == (2, 3)


def test_two_roots_within_a_degree_are_not_missed() -> None:
    """Close-hauled with a tiny cross current (hypothesis found it): V sin(delta) rises above |c_cross| and falls
    back within one degree of heading, where a stepped scan sees nothing; the smallest root is the best one."""
    u, v = 0.0, 1.0  # 1 m/s along the course, and the course 0.002 deg off north: a cross current of 6.6e-5 kn
    s = hold_course(0.001953125, 1.0, 2.0, u, v, VANE)
    ref = _reference(0.001953125, 1.0, 2.0, u, v, VANE)
    assert float(s.sog_kn) == pytest.approx(ref, rel=1e-9)


@pytest.mark.parametrize("v_ms", [0.4, -0.4, 1.2])
def test_arc_cost_uses_the_exact_crab_angle(v_ms: float) -> None:
    """An arc along the equator (course 090 all the way) in 14 kn of wind from 100 deg and a cross current: its time
    is its length over the exact speed made good of the scanned reference (the old one-step crab angle was 1.75 %
    optimistic on such an arc, issue 16)."""
    from pyroute_rel import geodesy
    from pyroute_rel.routing.cost import arc_costs
    from pyroute_rel.weather import UniformWeather

    dep = np.datetime64("2018-06-01T00:00")
    weather = UniformWeather(tws_kn=14.0, twd_deg=100.0, current_v_ms=v_ms)
    c = arc_costs(0.0, 0.0, 1.0, 0.0, 0.0, departure=dep, weather=weather, polar=VANE, samples=4)
    sog = _reference(90.0, 100.0, 14.0, 0.0, v_ms, VANE)
    assert float(c.time_h) == pytest.approx(float(geodesy.distance_nm(0.0, 0.0, 1.0, 0.0)) / sog, rel=1e-9)
