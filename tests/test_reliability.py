"""Exposure-based reliability (issue 16 item 1): the voyage's failure probability adds up time in conditions.

A failure model's p_f is the probability of failure over ``exposure_h`` hours in those conditions; a leg adds the
hazard ``-ln(1 - p_f) dt / exposure_h`` and the voyage fails with ``1 - exp(-sum)``. References here are closed forms
(uniform conditions) and the old per-leg product ``1 - prod(1 - p_f_leg)`` computed in the test, for comparison.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pyroute_rel.errors import FailureModelError
from pyroute_rel.geodesy import distance_km
from pyroute_rel.reliability.exposure import EXPOSURE_STEP_KM, failure_probability, hazard
from pyroute_rel.reliability.failure import DEFAULT_EXPOSURE_H, FailureModel, load_failure_model
from pyroute_rel.routing.route import Route
from pyroute_rel.scenario import scenario_from_mapping
from pyroute_rel.units import KM_PER_NM

#: One criterion, hs_m >= 4 m, with P(fail | fired) = P_BAND over EXPOSURE hours (0 otherwise).
P_BAND = 0.005
EXPOSURE = 2.0
BIF = """network band {{
}}
variable WH {{
  type discrete [ 2 ] {{ false, true }};
}}
variable F {{
  type discrete [ 2 ] {{ pass, fail }};
}}
probability ( WH ) {{
  table 0.9, 0.1;
}}
probability ( F | WH ) {{
  (false) 1.0, 0.0;
  (true) {q!r}, {p!r};
}}
"""
TOML = """name = "band"
network = "band.bif"
{exposure}
[target]
node = "F"
state = "fail"

[[criteria]]
node = "WH"
quantity = "hs_m"
operator = ">="
threshold = 4.0
fired = "true"
"""


def write_model(folder: Path, *, p: float = P_BAND, exposure: str = f"exposure_h = {EXPOSURE!r}") -> Path:
    (folder / "band.bif").write_text(BIF.format(p=p, q=1.0 - p), encoding="utf-8")
    path = folder / "band.toml"
    path.write_text(TOML.format(exposure=exposure), encoding="utf-8")
    return path


def straight(model: Path, n_ranks: int, *, patch_lon: list[float], apf: float = 1.0) -> Route:
    """West along the equator, 20 deg (2224 km), on a beam reach (15 kn from the north: no reason to leave the
    great circle), with 4.5 m waves over ``patch_lon`` from 30 S to 30 N: the route cannot avoid the band."""
    return scenario_from_mapping(
        {
            "route": {"start": [0.0, 0.0], "finish": [-20.0, 0.0]},
            "grid": {"n_ranks": n_ranks},
            "weather": {
                "kind": "uniform",
                "tws_kn": 15.0,
                "twd_deg": 0.0,
                "hs_m": 1.0,
                "wave_dir_deg": 0.0,
                "patch": [{"lon": patch_lon, "lat": [-30.0, 30.0], "hs_m": 4.5}],
            },
            "avoid": {"land": False},
            "failure": {"model": str(model), "apf": apf},
        }
    ).route()


def old_formula(route: Route) -> float:
    """The per-leg product used before exposure: each leg one independent trial."""
    return float(1.0 - np.prod(1.0 - route.legs.p_f))


def test_voyage_probability_converges_with_the_grid_where_the_per_leg_product_does_not(tmp_path: Path) -> None:
    model = write_model(tmp_path)
    band = [-13.0, -7.0]  # 6 deg of the 20: 667 km of 2224 km, about 79 h of the voyage at 4.54 kn
    routes = {n: straight(model, n, patch_lon=band) for n in (40, 80, 160, 320)}
    new = np.array([r.voyage_failure_probability for r in routes.values()])
    old = np.array([old_formula(r) for r in routes.values()])
    # the route stays on the equator at one speed: the hours in the band are the band's length over the speed
    speed_kmh = float(routes[40].legs.sog_kn[0]) * KM_PER_NM
    band_h = float(distance_km(-13.0, 0.0, -7.0, 0.0)) / speed_kmh
    step_h = EXPOSURE_STEP_KM / speed_kmh  # each edge of the band is placed to half a sub-arc
    for r in routes.values():
        assert np.all(r.lat_deg == 0.0)
        np.testing.assert_allclose(r.legs.sog_kn, r.legs.sog_kn[0], rtol=1e-12)
        assert r.exposure_by_criterion_h["WH: hs_m >= 4 m"] == pytest.approx(band_h, abs=step_h)
    expected = 1.0 - (1.0 - P_BAND) ** (band_h / EXPOSURE)  # 0.18 for about 79 h / 2 h
    np.testing.assert_allclose(new, expected, rtol=2 * step_h / band_h)
    assert (new.max() - new.min()) / new.min() < 0.02  # the acceptance: < 2 % between 40 and 320 ranks
    assert old.max() / old.min() > 5.0  # the per-leg product grows with the legs in the band (about 12 to 97)
    assert list(old) == sorted(old)


def test_uniform_conditions_give_the_closed_form(tmp_path: Path) -> None:
    """T hours in conditions with p_f = p everywhere: ``1 - (1 - p) ** (T / exposure_h)``, however many legs."""
    p = 0.2
    model = write_model(tmp_path, p=p)
    for n in (10, 37):
        route = straight(model, n, patch_lon=[-30.0, 10.0])  # the band covers the whole course
        T = route.voyage_time_h
        assert route.voyage_failure_probability == pytest.approx(1.0 - (1.0 - p) ** (T / EXPOSURE), rel=1e-12)
        assert route.exposure_by_criterion_h["WH: hs_m >= 4 m"] == pytest.approx(T, rel=1e-12)
        # each leg: its own duration
        np.testing.assert_allclose(route.legs.p_fail_leg, 1.0 - (1.0 - p) ** (route.legs.time_h / EXPOSURE), rtol=1e-12)
        assert np.all(route.legs.p_f == p) and route.max_failure_probability == p
        summary = route.summary()
        assert summary["voyage_failure_probability"] == route.voyage_failure_probability
        assert summary["exposure_by_criterion_h"] == route.exposure_by_criterion_h
        assert summary["failure_exposure_h"] == EXPOSURE


def test_certain_failure_and_no_model(tmp_path: Path) -> None:
    sure = straight(write_model(tmp_path, p=1.0), 10, patch_lon=[-13.0, -7.0])
    assert sure.voyage_failure_probability == 1.0 and sure.legs.p_fail_leg.max() == 1.0
    assert sure.legs.p_fail_leg[0] == 0.0  # legs outside the band: no exposure
    safe = scenario_from_mapping(
        {
            "route": {"start": [0.0, 0.0], "finish": [-5.0, 0.0]},
            "grid": {"n_ranks": 6},
            "weather": {"kind": "uniform", "tws_kn": 15.0, "twd_deg": 0.0},
            "avoid": {"land": False},
        }
    ).route()
    assert safe.voyage_failure_probability == 0.0 and safe.exposure_by_criterion_h == {}
    assert np.all(safe.legs.p_fail_leg == 0.0) and safe.summary()["failure_exposure_h"] is None


@settings(max_examples=60, deadline=None)
@given(
    p=st.floats(1e-4, 0.999),
    parts=st.lists(st.floats(0.01, 50.0), min_size=1, max_size=8),
    exposure=st.floats(0.1, 100.0),
)
def test_hazards_add_up_like_one_stay(p: float, parts: list[float], exposure: float) -> None:
    """Cutting T hours into pieces does not change the failure probability: 1 - (1 - p) ** (T / exposure_h)."""
    total = failure_probability(np.sum(hazard(p, np.array(parts), exposure)))
    assert float(total) == pytest.approx(1.0 - (1.0 - p) ** (sum(parts) / exposure), rel=1e-9)


def test_exposure_h_is_validated_and_defaults(tmp_path: Path) -> None:
    assert load_failure_model(write_model(tmp_path)).exposure_h == EXPOSURE
    assert load_failure_model(write_model(tmp_path, exposure="")).exposure_h == DEFAULT_EXPOSURE_H
    assert load_failure_model("dickson2018").exposure_h == 4.4  # 703.9 h / 161 legs of the paper's grid
    assert load_failure_model("dickson2018").describe()["exposure_h"] == 4.4
    for bad in ("0", "-1.0", "inf", "nan", '"4 h"', "true"):
        with pytest.raises(FailureModelError, match=r"band\.toml: 'exposure_h' must be a finite number of hours > 0"):
            load_failure_model(write_model(tmp_path, exposure=f"exposure_h = {bad}"), cache=False)
    model = load_failure_model("dickson2018")
    values = {f: getattr(model, f) for f in model.__dataclass_fields__}
    with pytest.raises(FailureModelError, match="exposure_h"):
        FailureModel(**{**values, "exposure_h": math.nan})


def test_apf_semantics_are_unchanged(tmp_path: Path) -> None:
    """``p_f > apf`` forbids, whatever the exposure: with p_f 0.005 in the band, apf 0.004 goes around (no
    sailable way around here: infeasible), apf 0.005 goes through."""
    model = write_model(tmp_path)
    through = straight(model, 20, patch_lon=[-13.0, -7.0], apf=P_BAND)
    assert through.max_failure_probability == P_BAND
    from pyroute_rel.errors import NoFeasibleRouteError

    with pytest.raises(NoFeasibleRouteError):
        straight(model, 20, patch_lon=[-13.0, -7.0], apf=0.004)


def test_files_carry_the_new_fields(tmp_path: Path) -> None:
    """CSV and GeoJSON only gain fields: ``leg_p_fail_leg`` (before the manoeuvre columns) and the voyage's exposure."""
    import csv
    import io

    from pyroute_rel.outputs import to_csv, to_geojson

    route = straight(write_model(tmp_path), 12, patch_lon=[-13.0, -7.0])
    rows = list(csv.reader(io.StringIO(to_csv(route))))
    assert rows[0][-5:] == ["leg_p_f", "leg_p_fail_leg", "leg_side", "leg_manoeuvre", "leg_manoeuvre_h"]
    np.testing.assert_allclose([float(r[-4]) for r in rows[1:-1]], route.legs.p_fail_leg, rtol=1e-5, atol=1e-12)
    doc = to_geojson(route)
    line = doc["features"][0]["properties"]
    assert line["voyage_failure_probability"] == route.voyage_failure_probability
    assert line["exposure_by_criterion_h"] == route.exposure_by_criterion_h
    assert [f["properties"]["leg_p_fail_leg"] for f in doc["features"][1:-1]] == route.legs.p_fail_leg.tolist()


def test_a_course_through_a_waypoint_adds_up_its_legs(tmp_path: Path) -> None:
    """Two legs of a course (through a mark inside the band): the voyage's hours per criterion are the legs' sums,
    and its failure probability is that of the summed hazards, which uniform band crossing gives in closed form."""
    model = write_model(tmp_path)
    course = scenario_from_mapping(
        {
            "route": {"start": [0.0, 0.0], "finish": [-20.0, 0.0], "waypoints": [[-10.0, 0.0]]},
            "grid": {"n_ranks": 12},
            "weather": {
                "kind": "uniform",
                "tws_kn": 15.0,
                "twd_deg": 0.0,
                "patch": [{"lon": [-13.0, -7.0], "lat": [-30.0, 30.0], "hs_m": 4.5}],
            },
            "avoid": {"land": False},
            "failure": {"model": str(model), "apf": 1.0},
        }
    ).route()
    first, second = course.course_legs
    key = "WH: hs_m >= 4 m"
    assert (
        course.exposure_by_criterion_h[key] == first.exposure_by_criterion_h[key] + second.exposure_by_criterion_h[key]
    )
    assert first.exposure_by_criterion_h[key] > 0 and second.exposure_by_criterion_h[key] > 0  # the mark is inside
    hours = course.exposure_by_criterion_h[key]
    assert course.voyage_failure_probability == pytest.approx(1.0 - (1.0 - P_BAND) ** (hours / EXPOSURE), rel=1e-12)
    both = 1.0 - (1.0 - first.voyage_failure_probability) * (1.0 - second.voyage_failure_probability)
    assert course.voyage_failure_probability == pytest.approx(both, rel=1e-12)


def test_time_varying_weather_counts_the_hours_when_the_criterion_fires(tmp_path: Path) -> None:
    """Gridded weather whose Hs falls linearly from 5 m at departure to 3 m 40 h later (then stays): hs >= 4 m for
    the first 20 h wherever the craft is, so the route spends 20 h where WH fires (to the midpoint sampling of a
    1 km sub-arc: half of 1 km at 4.54 kn, 0.06 h)."""
    from pyroute_rel.boat.polar import get_polar
    from pyroute_rel.routing.route import route_on_grid
    from pyroute_rel.routing.solve import RoutingProblem
    from pyroute_rel.units import KN_PER_MS
    from pyroute_rel.weather import GriddedWeather, WeatherField

    t0 = np.datetime64("2018-06-01T00:00", "ns")
    times = t0 + np.array([0, 40, 400]) * np.timedelta64(3600, "s")
    lon, lat = np.array([-25.0, 0.0, 5.0]), np.array([-10.0, 0.0, 10.0])

    def field(name: str, values: list[float]) -> WeatherField:
        data = np.broadcast_to(np.array(values, dtype=np.float32)[:, None, None], (3, lat.size, lon.size))
        return WeatherField(name, np.ascontiguousarray(data), lon, lat, times, source="test", variable=name)

    north = -15.0 / KN_PER_MS  # 15 kn from the north blows to the south
    weather = GriddedWeather(
        [field("wind_u_ms", [0.0] * 3), field("wind_v_ms", [north] * 3), field("hs_m", [5.0, 3.0, 3.0])]
    )
    problem = RoutingProblem(
        departure=t0,
        weather=weather,
        polar=get_polar("maribot_vane"),
        failure=load_failure_model(write_model(tmp_path)),
    )
    grid = scenario_from_mapping(
        {
            "route": {"start": [0.0, 0.0], "finish": [-20.0, 0.0]},
            "grid": {"n_ranks": 30},
            "avoid": {"land": False},
            "weather": {"kind": "uniform", "tws_kn": 15.0, "twd_deg": 0.0},
        }
    ).leg_grids()[0]
    route = route_on_grid(grid, problem)
    speed_kmh = float(route.legs.sog_kn[0]) * KM_PER_NM
    assert route.exposure_by_criterion_h["WH: hs_m >= 4 m"] == pytest.approx(
        20.0, abs=0.5 * EXPOSURE_STEP_KM / speed_kmh
    )
    hours = route.exposure_by_criterion_h["WH: hs_m >= 4 m"]
    assert route.voyage_failure_probability == pytest.approx(1.0 - (1.0 - P_BAND) ** (hours / EXPOSURE), rel=1e-12)


def test_criteria_see_the_heading_the_craft_steers_in_a_current() -> None:
    """West along the equator with 0.5 m/s of current to the north: the craft heads about 12 deg south of west to
    hold its course. Waves from 208 deg are 62 deg off the course (WD, awd < 60 deg, would not fire) but about 50 deg
    off the heading: WD fires all the way, as the router's cost function (same heading) says, leg by leg."""
    route = scenario_from_mapping(
        {
            "route": {"start": [0.0, 0.0], "finish": [-10.0, 0.0]},
            "grid": {"n_ranks": 10},
            "weather": {
                "kind": "uniform",
                "tws_kn": 15.0,
                "twd_deg": 0.0,
                "hs_m": 1.0,
                "wave_dir_deg": 208.0,
                "current_u_ms": 0.0,
                "current_v_ms": 0.5,
            },
            "avoid": {"land": False},
            "failure": {"model": "dickson2018", "apf": 1.0},
        }
    ).route()
    assert np.all(route.legs.p_f == 0.9)  # the cost function: WD fired on every leg
    sailing_h = float(route.legs.time_h.sum())
    assert route.exposure_by_criterion_h["WD: awd_deg < 60 deg"] == pytest.approx(sailing_h, rel=1e-12)
    assert route.exposure_by_criterion_h["WH: hs_m >= 4 m"] == 0.0
    assert route.voyage_failure_probability == pytest.approx(1.0 - 0.1 ** (sailing_h / 4.4), rel=1e-12)


def test_legs_refuse_a_leg_probability_outside_0_1(tmp_path: Path) -> None:
    from pyroute_rel.routing.route import Legs

    route = straight(write_model(tmp_path), 6, patch_lon=[-13.0, -7.0])
    values = dict(route.legs)
    assert Legs(**values).p_fail_leg.tolist() == route.legs.p_fail_leg.tolist()
    with pytest.raises(ValueError, match=r"Legs\.p_fail_leg must be probabilities in \[0, 1\]"):
        Legs(**{**values, "p_fail_leg": values["p_fail_leg"] + 1.5})
    with pytest.raises(TypeError, match="p_fail_leg"):  # required: a route's legs always know it
        Legs(**{k: v for k, v in values.items() if k != "p_fail_leg"})


def test_hazard_of_a_tiny_exposure_is_inf_or_zero_never_nan() -> None:
    # exposure_h = 1e-320 [h] (subnormal, accepted as > 0): dt_h / exposure_h overflows to inf. p_f = 0 must stay
    # no hazard (it gave 0 * inf = nan, and summary.json a nan voyage_failure_probability), p_f > 0 is certain
    # failure (inf), and a missing p_f (nan) stays nan; no RuntimeWarning escapes.
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        h = hazard([0.0, 0.5, float("nan")], [10.0, 10.0, 10.0], 1e-320)
    assert h[0] == 0.0
    assert h[1] == float("inf")
    assert np.isnan(h[2])
