"""No clipping (issue 16, item 2): an arc is judged on everything it crosses.

Every check here densifies arcs or tracks itself (spherical linear interpolation written out below, with the course
from the tangent of the great circle) and evaluates the weather and the failure criteria independently: patches by
their own box test read from the scenario file, gridded fields by a bilinear interpolation written out here, the
table by ``FailureModel.p_fail`` (the model's own lookup, not the cost function's gather). None of it uses the
crossing logic under test (:mod:`pyroute_rel.reliability.crossings`).
"""

from __future__ import annotations

import tomllib
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from pyroute_rel.boat.polar import get_polar
from pyroute_rel.reliability.crossings import split_fractions
from pyroute_rel.reliability.failure import load_failure_model
from pyroute_rel.routing.cost import arc_costs
from pyroute_rel.scenario import load_scenario
from pyroute_rel.weather import Patch, UniformWeather
from pyroute_rel.weather.base import Boundaries

ROOT = Path(__file__).resolve().parents[1]
CONTROL = ROOT / "examples" / "microtransat_control.toml"
R_KM = 6371.0088
DEPARTURE = np.datetime64("2018-06-01T00:00")


def _xyz(lon, lat):
    lo, la = np.radians(lon), np.radians(lat)
    return np.stack([np.cos(la) * np.cos(lo), np.cos(la) * np.sin(lo), np.sin(la)], axis=-1)


def _densify_leg(lon0, lat0, lon1, lat1, step_km):
    """Points every ``step_km`` or closer along one great-circle leg (both ends included), with the course there."""
    a, b = _xyz(lon0, lat0), _xyz(lon1, lat1)
    om = float(np.arccos(np.clip(a @ b, -1.0, 1.0)))
    n = max(1, int(np.ceil(om * R_KM / step_km)))
    t = np.linspace(0.0, 1.0, n + 1)[:, None]
    p = (np.sin((1 - t) * om) * a + np.sin(t * om) * b) / np.sin(om)
    v = (-np.cos((1 - t) * om) * a + np.cos(t * om) * b) * om / np.sin(om)  # d p / d t: the direction of travel
    lo, la = np.arctan2(p[:, 1], p[:, 0]), np.arcsin(np.clip(p[:, 2], -1, 1))
    east = -np.sin(lo) * v[:, 0] + np.cos(lo) * v[:, 1]
    north = -np.sin(la) * np.cos(lo) * v[:, 0] - np.sin(la) * np.sin(lo) * v[:, 1] + np.cos(la) * v[:, 2]
    return np.degrees(lo), np.degrees(la), np.degrees(np.arctan2(east, north)) % 360.0


def _densify_track(lon, lat, step_km=0.1):
    parts = [_densify_leg(lon[i], lat[i], lon[i + 1], lat[i + 1], step_km) for i in range(len(lon) - 1)]
    return tuple(np.concatenate([p[k] for p in parts]) for k in range(3))


def _awd(wave_from, course):
    return np.abs((np.asarray(wave_from) - course + 180.0) % 360.0 - 180.0)


def _control_fields(table, lon, lat):
    """Hs and wave direction of a uniform scenario with patches ([weather] of a scenario file), by a box test."""
    hs = np.full(lon.shape, float(table["hs_m"]))
    wd = np.full(lon.shape, float(table["wave_dir_deg"]))
    for p in table.get("patch", []):
        inside = (lon >= p["lon"][0]) & (lon <= p["lon"][1]) & (lat >= p["lat"][0]) & (lat <= p["lat"][1])
        hs = np.where(inside & ("hs_m" in p), p.get("hs_m", 0.0), hs)
        wd = np.where(inside & ("wave_dir_deg" in p), p.get("wave_dir_deg", 0.0), wd)
    return hs, wd


def _longest_run(mask):
    """Length of the longest run of True in a 1-D mask."""
    best = run = 0
    for m in mask:
        run = run + 1 if m else 0
        best = max(best, run)
    return best


MODEL = load_failure_model("dickson2018")


# --- where arcs cross lines ---------------------------------------------------------------------------------------


@pytest.mark.slow
def test_split_fractions_find_every_change_of_side_of_a_box_edge():
    rng = np.random.default_rng(16)
    box = (-43.0, -37.0, 30.0, 36.0)
    bounds = Boundaries(np.array([-43.0, -37.0]), np.array([30.0, 36.0]), np.array([box]), continuous=False)
    found = 0
    for _ in range(200):
        lon0, lat0 = rng.uniform(-45, -35), rng.uniform(28, 38)
        lon1, lat1 = lon0 + rng.uniform(-1.5, 1.5), lat0 + rng.uniform(-1.5, 1.5)
        lo, la, _ = _densify_leg(lon0, lat0, lon1, lat1, 0.005)  # every 5 m
        inside = (lo >= box[0]) & (lo <= box[1]) & (la >= box[2]) & (la <= box[3])
        changes = np.flatnonzero(inside[1:] != inside[:-1])
        f = split_fractions(_xyz([lon0], [lat0]), _xyz([lon1], [lat1]), bounds)[0]
        f = f[np.isfinite(f)]
        n = lo.size - 1
        for c in changes:  # each change of side, between dense points c and c + 1, has a crossing there
            assert np.any(np.abs(f - (c + 0.5) / n) <= 1.0 / n), (lon0, lat0, lon1, lat1, c / n, f)
            found += 1
    assert found > 30  # the arcs do cross the edges


# --- one arc: p_f is the worst met anywhere along it ------------------------------------------------------------------


def _control_weather():
    table = tomllib.loads(CONTROL.read_text())["weather"]
    w = UniformWeather(
        tws_kn=table["tws_kn"],
        twd_deg=table["twd_deg"],
        hs_m=table["hs_m"],
        wave_dir_deg=table["wave_dir_deg"],
        patches=tuple(
            Patch(
                lon=tuple(p["lon"]),
                lat=tuple(p["lat"]),
                values={k: v for k, v in p.items() if k.endswith(("_m", "_deg"))},
            )
            for p in table["patch"]
        ),
    )
    return table, w


@pytest.mark.slow
def test_arc_p_f_is_the_largest_p_f_on_the_arc_densified_every_10_m():
    """Random arcs of up to ~100 km about the control course's patches (waves from 240 in Area 1: head seas on
    south-westerly headings): with one sample per arc, the cost function forbids exactly the arcs that meet
    p_f > apf on the arc densified every 10 m, and an allowed arc's p_f is the largest met there."""
    table, w = _control_weather()
    polar = get_polar("maribot_vane")
    rng = np.random.default_rng(2018)
    n = 300
    lon0 = rng.uniform(-45.5, -34.5, n)
    lat0 = rng.uniform(27.5, 38.5, n)
    ang = rng.uniform(0, 2 * np.pi, n)
    d = rng.uniform(0.05, 0.9, n)
    lon1, lat1 = lon0 + d * np.sin(ang) / np.cos(np.radians(lat0)), lat0 + d * np.cos(ang)
    costs = arc_costs(lon0, lat0, lon1, lat1, 0.0, departure=DEPARTURE, weather=w, polar=polar, failure=MODEL, apf=0.5)
    dense = np.empty(n)
    for i in range(n):
        lo, la, course = _densify_leg(lon0[i], lat0[i], lon1[i], lat1[i], 0.01)
        hs, wd = _control_fields(table, lo, la)
        dense[i] = MODEL.p_fail({"hs_m": hs, "awd_deg": _awd(wd, course)}).max()
    assert set(np.unique(dense).tolist()) == {0.0, 0.9, 1.0}  # the arcs meet every class
    allowed = np.isfinite(costs.time_h)
    np.testing.assert_array_equal(allowed, dense <= 0.5)
    np.testing.assert_array_equal(costs.p_f[allowed], dense[allowed])
    # an arc its samples already forbid keeps their p_f (above apf, at most the arc's largest)
    assert np.all((costs.p_f[~allowed] > 0.5) & (costs.p_f[~allowed] <= dense[~allowed]))


# --- routes never enter where their forbidden criteria fire -------------------------------------------------------


CASES = {
    "default": {},
    "refine5": {"refine": 5},
    "square81": {"layout": "square", "n_ranks": 81, "n_nodes": 81},
}


@pytest.mark.slow
@pytest.mark.parametrize("apf", [0.95, 0.5])
@pytest.mark.parametrize("case", sorted(CASES))
def test_control_routes_stay_out_of_forbidden_conditions(apf, case):
    """The track densified every 100 m, the criteria evaluated on it independently: no stretch of more than two
    steps (0.2 km along the track, so at most 0.1 km from where the conditions are allowed) meets p_f > apf, and the
    route's reported largest p_f is the largest met on the densified track."""
    table = tomllib.loads(CONTROL.read_text())["weather"]
    route = load_scenario(CONTROL).with_options(apf=apf, **CASES[case]).route()
    lon, lat, course = _densify_track(np.asarray(route.lon_deg), np.asarray(route.lat_deg), 0.1)
    course[-1] = course[-2]
    hs, wd = _control_fields(table, lon, lat)
    p = MODEL.p_fail({"hs_m": hs, "awd_deg": _awd(wd, course)})
    assert _longest_run(p > apf) <= 1
    assert route.max_failure_probability == p.max()
    # the exposure integral (1 km sub-arcs) meets no forbidden conditions either: at apf 0.5 no criterion may fire;
    # at 0.95, head seas (WD) occur only in Area 1, inside Area 2's 4 m waves, where both fire (p_f 1)
    hours = route.exposure_by_criterion_h
    assert hours["WD: awd_deg < 60 deg"] == 0.0
    if apf == 0.5:
        assert hours["WH: hs_m >= 4 m"] == 0.0 and route.voyage_failure_probability == 0.0


@pytest.mark.slow
def test_square_81_voyage_matches_the_reference_router_and_32_samples():
    """81 x 81 at apf 0.95: an independent reference router gives 778.852 h (issue 16); 32 weather samples per arc
    judge the arcs finely without the crossings (within 0.05 %)."""
    sc = load_scenario(CONTROL).with_options(apf=0.95, layout="square", n_ranks=81, n_nodes=81)
    plain = sc.route().voyage_time_h
    fine = sc.with_options(samples_per_arc=32).route().voyage_time_h
    assert plain == pytest.approx(778.852, rel=5e-4)
    assert plain == pytest.approx(fine, rel=5e-4)


# --- gridded weather: one cell of 5 m waves in 1 m seas -------------------------------------------------------------


def _sharp_grid():
    lon = np.arange(-20.0, -9.99, 0.5)
    lat = np.arange(38.0, 47.01, 0.5)
    hs = np.ones((lat.size, lon.size))
    j, i = np.searchsorted(lat, 42.5), np.searchsorted(lon, -15.5)
    hs[j : j + 2, i : i + 2] = 5.0  # the corners of the cell [-15.5, -15] x [42.5, 43]
    return lon, lat, hs


def _bilinear(lon, lat, values, x, y):
    i = np.clip(np.searchsorted(lon, x, side="right") - 1, 0, lon.size - 2)
    j = np.clip(np.searchsorted(lat, y, side="right") - 1, 0, lat.size - 2)
    fx = (x - lon[i]) / (lon[i + 1] - lon[i])
    fy = (y - lat[j]) / (lat[j + 1] - lat[j])
    v = values
    return (v[j, i] * (1 - fx) + v[j, i + 1] * fx) * (1 - fy) + (v[j + 1, i] * (1 - fx) + v[j + 1, i + 1] * fx) * fy


def _sharp_weather():
    xr = pytest.importorskip("xarray")
    from pyroute_rel.weather.io.readers import weather_from_dataset

    lon, lat, hs = _sharp_grid()
    dims = ("latitude", "longitude")
    shape = hs.shape
    ds = xr.Dataset(
        {
            "u10": (dims, np.zeros(shape), {"units": "m s**-1"}),
            "v10": (dims, np.full(shape, -7.0), {"units": "m s**-1"}),  # from the north
            "swh": (dims, hs, {"units": "m"}),
            "mwd": (dims, np.zeros(shape), {"units": "Degree true"}),
        },
        coords={"latitude": lat, "longitude": lon},
    )
    return weather_from_dataset(ds, source="sharp"), (lon, lat, hs)


@pytest.mark.slow
def test_gridded_arc_p_f_is_the_largest_on_the_arc_densified():
    """Arcs across a single cell of 5 m waves (bilinear: Hs >= 4 m on a small diamond about it): the arc's p_f is
    the largest on the arc densified every 10 m, with Hs interpolated here (and the arcs forbidden are those that
    meet p_f > apf there)."""
    w, (glon, glat, ghs) = _sharp_weather()
    polar = get_polar("maribot_vane")
    rng = np.random.default_rng(5)
    n = 200
    lon0, lat0 = rng.uniform(-16.5, -14.0, n), rng.uniform(42.0, 43.5, n)
    ang = rng.uniform(0, 2 * np.pi, n)
    d = rng.uniform(0.1, 1.0, n)
    lon1, lat1 = lon0 + d * np.sin(ang) / np.cos(np.radians(lat0)), lat0 + d * np.cos(ang)
    costs = arc_costs(lon0, lat0, lon1, lat1, 0.0, departure=DEPARTURE, weather=w, polar=polar, failure=MODEL, apf=0.5)
    dense = np.empty(n)
    for i in range(n):
        lo, la, course = _densify_leg(lon0[i], lat0[i], lon1[i], lat1[i], 0.01)
        hs = _bilinear(glon, glat, ghs, lo, la)
        dense[i] = MODEL.p_fail({"hs_m": hs, "awd_deg": _awd(0.0, course)}).max()
    assert 0.0 < dense.mean() < 1.0  # some arcs meet the 4 m waves, some do not
    allowed = np.isfinite(costs.time_h)
    np.testing.assert_array_equal(allowed, dense <= 0.5)
    np.testing.assert_array_equal(costs.p_f[allowed], dense[allowed])
    # an arc its samples already forbid keeps their p_f (above apf, at most the arc's largest)
    assert np.all((costs.p_f[~allowed] > 0.5) & (costs.p_f[~allowed] <= dense[~allowed]))


@pytest.mark.slow
def test_gridded_route_goes_round_a_single_cell_of_high_waves():
    """A route past the 5 m cell at apf 0.5: no stretch of the track densified every 100 m meets Hs >= 4 m (beyond
    one step), and the reported largest p_f is the densified track's."""
    w, (glon, glat, ghs) = _sharp_weather()
    sc = load_scenario(CONTROL).with_options(apf=0.5, land=False, n_ranks=30)
    sc = replace(sc, weather=w, start=(-12.0, 45.0), finish=(-18.5, 40.5))
    route = sc.route()
    lon, lat, course = _densify_track(np.asarray(route.lon_deg), np.asarray(route.lat_deg), 0.1)
    course[-1] = course[-2]
    p = MODEL.p_fail({"hs_m": _bilinear(glon, glat, ghs, lon, lat), "awd_deg": _awd(0.0, course)})
    assert _longest_run(p > 0.5) <= 1
    assert route.max_failure_probability == p.max()


@pytest.mark.slow
def test_forbidden_arcs_are_exactly_those_that_enter_the_patch():
    """The library's forbidden arcs (the example of ``Route.forbidden_arcs``: one patch of 4.5 m waves at apf 0.5):
    among the arcs leaving the nodes the DP reached, those forbidden by the failure model are exactly those whose
    great circle, densified every 50 m, enters the patch."""
    from pyroute_rel import scenario_from_mapping

    box = (-17.0, -15.0, 41.0, 44.0)
    sc = scenario_from_mapping(
        {
            "route": {"start": [-12.0, 45.0], "finish": [-20.0, 40.0]},
            "grid": {"n_ranks": 20},
            "weather": {
                "kind": "uniform",
                "tws_kn": 15.0,
                "twd_deg": 0.0,
                "hs_m": 1.0,
                "patch": [{"lon": list(box[:2]), "lat": list(box[2:]), "hs_m": 4.5}],
            },
            "avoid": {"land": False},
            "failure": {"model": "dickson2018", "apf": 0.5},
        }
    )
    route = sc.route()
    table = route.forbidden_arcs()
    failure = np.char.find(table.reason.astype(str), "failure") >= 0
    listed = set(
        zip(table.rank[failure].tolist(), table.dst[failure].tolist(), table.src[failure].tolist(), strict=True)
    )
    grid, arrival = route.grid, route.dp.arrival_h
    entering = set()
    for k in range(grid.n_ranks + 1):
        lon0, lat0, lon1, lat1, src, valid = (np.asarray(a) for a in grid.arcs(k))
        lon0, lat0, lon1, lat1, src = np.broadcast_arrays(lon0, lat0, lon1, lat1, src)
        live = valid & (np.isfinite(arrival[k - 1][src]) if k > 0 else True)
        for d, c in zip(*np.nonzero(live), strict=True):
            lo, la, _ = _densify_leg(lon0[d, c], lat0[d, c], lon1[d, c], lat1[d, c], 0.05)
            if np.any((lo >= box[0]) & (lo <= box[1]) & (la >= box[2]) & (la <= box[3])):
                entering.add((k, int(d if k < grid.n_ranks else c), int(src[d, c])))
    assert len(listed) > 100
    assert listed == entering


@pytest.mark.parametrize("current", [False, True])
def test_pieces_sample_only_the_judged_fields_with_the_same_numbers(current):
    """The pieces of time-varying gridded weather are sampled for the failure model's fields (and the current)
    only: those fields equal ``weather.sample``'s at the same points and times, bit for bit; with a current every
    field is sampled (the crab heading needs the wind)."""
    xr = pytest.importorskip("xarray")
    from pyroute_rel.reliability.crossings import _sample_fields
    from pyroute_rel.weather.io.readers import weather_from_dataset

    rng = np.random.default_rng(3)
    lon, lat = np.arange(-20.0, -9.99, 0.5), np.arange(38.0, 47.01, 0.5)
    time = DEPARTURE + np.arange(5) * np.timedelta64(6, "h")
    dims = ("time", "latitude", "longitude")
    shape = (time.size, lat.size, lon.size)
    data = {
        "u10": (dims, rng.normal(0.0, 6.0, shape), {"units": "m s**-1"}),
        "v10": (dims, rng.normal(0.0, 6.0, shape), {"units": "m s**-1"}),
        "swh": (dims, rng.uniform(0.5, 5.0, shape), {"units": "m"}),
        "mwd": (dims, rng.uniform(0.0, 360.0, shape), {"units": "Degree true"}),
    }
    if current:
        data["uo"] = (dims, rng.normal(0.0, 0.3, shape), {"units": "m s**-1"})
        data["vo"] = (dims, rng.normal(0.0, 0.3, shape), {"units": "m s**-1"})
    w = weather_from_dataset(xr.Dataset(data, coords={"time": time, "latitude": lat, "longitude": lon}))
    plon, plat = rng.uniform(-19.9, -10.1, (50, 3)), rng.uniform(38.1, 46.9, (50, 3))
    t = DEPARTURE + (rng.uniform(0.0, 23.0, (50, 3)) * 3.6e6).astype("timedelta64[ms]")
    got = _sample_fields(w, plon, plat, t, MODEL)
    want = w.sample(plon, plat, t)
    assert want.has_current == current
    names = ["hs_m", "wave_dir_deg", "current_u_ms", "current_v_ms"]
    if current:
        names += ["tws_kn", "twd_deg", "wave_period_s"]
    for name in names:
        np.testing.assert_array_equal(getattr(got, name), getattr(want, name))
    if not current:  # the wind was not sampled
        assert np.isnan(got.tws_kn).all()


def test_piece_points_component_by_component_equal_the_vector_form():
    """The pieces' points and courses, computed component by component, are the vector form's ``p = a cos(t) +
    u sin(t)``, ``v = u cos(t) - a sin(t)`` (written out here) bit for bit, on arcs anywhere on the sphere."""
    from pyroute_rel import geodesy
    from pyroute_rel.reliability.crossings import _frame, _points

    rng = np.random.default_rng(11)
    n = 5000
    a = geodesy.to_xyz(rng.uniform(-180, 180, n), rng.uniform(-89, 89, n))
    b = geodesy.to_xyz(rng.uniform(-180, 180, n), rng.uniform(-89, 89, n))
    omega, u = _frame(a, b)
    arc = rng.integers(0, n, 8000)
    f = rng.uniform(0.0, 1.0, (arc.size, 3))
    t = f * omega[arc][:, None]
    c, s = np.cos(t)[..., None], np.sin(t)[..., None]
    p = a[arc][:, None, :] * c + u[arc][:, None, :] * s
    v = u[arc][:, None, :] * c - a[arc][:, None, :] * s
    x, y, z = p[..., 0], p[..., 1], p[..., 2]
    lon, lat = np.degrees(np.arctan2(y, x)), np.degrees(np.arcsin(np.clip(z, -1.0, 1.0)))
    lr = np.radians(lon)
    east = -np.sin(lr) * v[..., 0] + np.cos(lr) * v[..., 1]
    north = v[..., 2] * np.sqrt(x * x + y * y) - z * (np.cos(lr) * v[..., 0] + np.sin(lr) * v[..., 1])
    for got, want in zip(_points(a, u, omega, arc, f), (lon, lat, geodesy.bearing_deg(east, north)), strict=True):
        np.testing.assert_array_equal(got, want)
