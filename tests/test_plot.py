"""Maps: coastlines and zones are single artists, holes stay empty; the shading is the failure model for the route's
own headings and times (checked against an independent evaluation), the weather drawn is the route's, the legend
names what is drawn, and drawing never imports pyplot."""

from __future__ import annotations

import numpy as np
import pytest
import shapely

from pyroute_rel import obstacles as ob
from pyroute_rel.viz.maps import _fill_polygons, new_figure


def _signed_area(xy: np.ndarray) -> float:
    x, y = xy[:, 0], xy[:, 1]
    return 0.5 * float(np.sum(x[:-1] * y[1:] - x[1:] * y[:-1]))


def test_polygons_with_holes_fill_as_one_artist_with_empty_holes() -> None:
    # exterior given clockwise and hole counter-clockwise: the worst case for the nonzero fill rule
    outer = [(0, 0), (0, 3), (3, 3), (3, 0)]
    hole = [(1, 1), (2, 1), (2, 2), (1, 2)]
    geom = shapely.MultiPolygon([shapely.Polygon(outer, [hole]), shapely.box(4, 0, 5, 1)])
    fig = new_figure()
    ax = fig.add_subplot()
    _fill_polygons(ax, geom, facecolor="r")
    assert len(ax.collections) == 1
    paths = ax.collections[0].get_paths()
    assert len(paths) == 2
    # the first path holds the exterior then the hole: opposite orientations, so the hole is not filled
    codes = paths[0].codes
    starts = np.flatnonzero(codes == paths[0].MOVETO)
    rings = np.split(paths[0].vertices, starts[1:])
    assert len(rings) == 2
    assert _signed_area(rings[0]) > 0 > _signed_area(rings[1])
    # and the hole really stays empty when drawn
    ax.set_xlim(-1, 6)
    ax.set_ylim(-1, 4)
    ax.set_axis_off()
    fig.canvas.draw()
    img = np.asarray(fig.canvas.buffer_rgba())
    to_px = ax.transData.transform
    (hx, hy), (fx, fy) = to_px((1.5, 1.5)), to_px((0.5, 0.5))
    h = img.shape[0]
    assert tuple(img[int(h - hy), int(hx), :3]) == (255, 255, 255)  # the hole: background
    assert tuple(img[int(h - fy), int(fx), :3]) == (255, 0, 0)  # the polygon: filled


def test_a_coastline_of_thousands_of_parts_is_one_artist() -> None:
    land = ob.land_geometry((-70.0, 8.0, -55.0, 20.0))  # the Caribbean: hundreds of islands
    assert len(shapely.get_parts(land)) > 100
    ax = new_figure().add_subplot()
    _fill_polygons(ax, land, facecolor="0.85")
    assert len(ax.collections) == 1
    assert len(ax.collections[0].get_paths()) == len(shapely.get_parts(land))


@pytest.mark.slow
def test_a_refined_route_map_draws_the_grid_track_too() -> None:
    from dataclasses import replace
    from pathlib import Path

    from pyroute_rel.scenario import load_scenario
    from pyroute_rel.viz.maps import plot_route

    sc = load_scenario(Path(__file__).resolve().parents[1] / "examples" / "microtransat_control.toml")
    sc = sc.with_options(n_ranks=30, land=False)
    route = replace(sc, refine=1).route()
    fig = plot_route(route)
    lines = {ln.get_label(): ln for ln in fig.axes[0].get_lines()}
    before = [k for k in lines if "before refinement" in k]
    assert len(before) == 1 and f"{route.meta['refine']['grid_voyage_time_h']:.1f} h" in before[0]
    assert "route (refined): " + f"{route.voyage_time_h:.1f} h" in lines
    np.testing.assert_array_equal(lines[before[0]].get_xdata(), route.grid_track.lon_deg)


@pytest.mark.slow
def test_a_course_across_the_antimeridian_maps_continuously_and_splits_its_geojson(tmp_path) -> None:
    import json

    from pyroute_rel.cli import main
    from pyroute_rel.scenario import scenario_from_mapping
    from pyroute_rel.viz.maps import plot_route

    sc = scenario_from_mapping(
        {
            "route": {"start": [170.0, 30.0], "finish": [-170.0, 32.0]},
            "grid": {"n_ranks": 20},
            "weather": {"kind": "uniform", "tws_kn": 15.0, "twd_deg": 0.0},
        }
    )
    route = sc.route()
    fig = plot_route(route)
    ax = fig.axes[0]
    (track,) = [ln for ln in ax.get_lines() if ln.get_label().startswith("route")]
    x = np.asarray(track.get_xdata())
    assert np.all(np.abs(np.diff(x)) < 5.0) and x[0] == 170.0 and x[-1] == 190.0  # no jump across the map
    lo, hi = ax.get_xlim()
    assert 160.0 < lo < 170.0 and 190.0 < hi < 200.0  # framed on the course, not the whole world
    assert ax.xaxis.get_major_formatter()(185.0, 0) == "-175"
    # GeoJSON: split at +-180 into a MultiLineString (RFC 7946 section 3.1.9), the parts meeting on the seam
    path = tmp_path / "am.toml"
    path.write_text(
        "[route]\nstart = [170.0, 30.0]\nfinish = [-170.0, 32.0]\n[grid]\nn_ranks = 20\n"
        '[weather]\nkind = "uniform"\ntws_kn = 15.0\ntwd_deg = 0.0\n'
    )
    assert main(["route", str(path), "--quiet", "--out", str(tmp_path / "o")]) == 0
    geom = json.loads((tmp_path / "o" / "route.geojson").read_text())["features"][0]["geometry"]
    assert geom["type"] == "MultiLineString" and len(geom["coordinates"]) == 2
    west, east = geom["coordinates"]
    assert west[-1][0] == 180.0 and east[0][0] == -180.0 and west[-1][1] == east[0][1]
    assert all(lon > 0 for lon, _ in west) and all(lon < 0 for lon, _ in east)


# ------------------------------------------------------------------ the shading and the weather the map draws
#
# The reference below is written independently of pyroute_rel.geodesy, .risk and .weather: it densifies the track
# every 1 km by spherical linear interpolation, finds the nearest point by brute force (haversine), takes the
# great-circle course there towards the leg's end (the standard initial-bearing formula) and the time at which the
# route passes (linear along the leg), and evaluates the dickson2018 model by its published table: WH (hs >= 4 m) and
# WD (apparent wave direction < 60 deg) give P(fail) 0, 0.9, 1 for 0, 1, 2 criteria met (Dickson et al. 2018,
# Table 1, as failure_models/dickson2018.toml states it).

EARTH_KM = 6371.0088
KN_PER_MS = 3600.0 / 1852.0


def _xyz(lon, lat):
    lo, la = np.radians(lon), np.radians(lat)
    return np.stack([np.cos(la) * np.cos(lo), np.cos(la) * np.sin(lo), np.sin(la)], axis=-1)


def _dense_track(route, step_km=1.0):
    """Points every ``step_km`` along the route's legs, with the course there [deg] and the time [h]."""
    lon, lat = route.lon_deg, route.lat_deg
    out_lon, out_lat, out_course, out_t = [], [], [], []
    for i in range(lon.size - 1):
        a, b = _xyz(lon[i], lat[i]), _xyz(lon[i + 1], lat[i + 1])
        ang = np.arccos(np.clip(a @ b, -1.0, 1.0))
        n = max(int(np.ceil(ang * EARTH_KM / step_km)), 1)
        f = (np.arange(n) + 0.5) / n
        p = (np.sin((1 - f) * ang)[:, None] * a + np.sin(f * ang)[:, None] * b) / np.sin(ang)
        plat, plon = np.degrees(np.arcsin(p[:, 2])), np.degrees(np.arctan2(p[:, 1], p[:, 0]))
        p1, p2, dl = np.radians(plat), np.radians(lat[i + 1]), np.radians(lon[i + 1] - plon)
        y = np.sin(dl) * np.cos(p2)
        x = np.cos(p1) * np.sin(p2) - np.sin(p1) * np.cos(p2) * np.cos(dl)
        out_lon.append(plon)
        out_lat.append(plat)
        out_course.append(np.degrees(np.arctan2(y, x)) % 360.0)
        out_t.append(route.elapsed_h[i] + route.legs.wait_h[i] + f * route.legs.time_h[i])
    return tuple(np.concatenate(v) for v in (out_lon, out_lat, out_course, out_t))


def _candidates(route, lon, lat, slack_km=6.0):
    """For each point, the indices of the dense track's points within ``slack_km`` of its nearest one (brute
    force, haversine): the library matches points to track samples 10 km apart, so its choice is one of these."""
    track = _dense_track(route)
    lon, lat = np.ravel(lon), np.ravel(lat)
    p2, l2 = np.radians(track[1]), np.radians(track[0])
    out = []
    for s in range(0, lon.size, 200):
        p1, l1 = np.radians(lat[s : s + 200, None]), np.radians(lon[s : s + 200, None])
        h = np.sin((p2 - p1) / 2) ** 2 + np.cos(p1) * np.cos(p2) * np.sin((l2 - l1) / 2) ** 2
        d = 2 * EARTH_KM * np.arcsin(np.sqrt(h))
        out += [np.flatnonzero(row <= row.min() + slack_km) for row in d]
    return track, out


def _spread(values, candidates):
    """Per point, the smallest and largest of ``values`` over its candidates."""
    return np.array([values[c].min() for c in candidates]), np.array([values[c].max() for c in candidates])


def _dickson(hs_m, wave_from_deg, heading_deg):
    awd = np.abs((np.asarray(wave_from_deg) - heading_deg + 180.0) % 360.0 - 180.0)
    n = (np.asarray(hs_m) >= 4.0).astype(int) + (awd < 60.0).astype(int)
    return np.array([0.0, 0.9, 1.0])[n], n


def _classes(p, n, apf):
    return np.where(p > apf, 2, np.where(n > 0, 1, 0))


def _control(apf, n_ranks=40, **extra):
    from pyroute_rel.scenario import scenario_from_mapping

    patches = [
        {"name": "Area 2", "lon": [-45.0, -35.0], "lat": [28.0, 38.0], "hs_m": 4.0},
        {"name": "Area 1", "lon": [-43.0, -37.0], "lat": [30.0, 36.0], "wave_dir_deg": 240.0},
    ]
    mapping = {
        "route": {"start": [-12.0, 45.0], "finish": [-60.0, 17.5], "departure": "2018-06-01T00:00:00Z"},
        "grid": {"n_ranks": n_ranks},
        "weather": {"kind": "uniform", "tws_kn": 15.0, "twd_deg": 0.0, "hs_m": 1.0, "wave_dir_deg": 0.0,
                    "patch": patches},
        "avoid": {"land": False},
        "failure": {"model": "dickson2018", "apf": apf},
    }  # fmt: skip
    for key, value in extra.items():  # a None value drops a setting
        merged = {**mapping.get(key, {}), **value}
        mapping[key] = {k: v for k, v in merged.items() if v is not None}
    return scenario_from_mapping(mapping)


def _control_conditions(lon, lat):
    """The control weather at points, from the scenario's definition (patches: later ones on top)."""
    in2 = (lon >= -45.0) & (lon <= -35.0) & (lat >= 28.0) & (lat <= 38.0)
    in1 = (lon >= -43.0) & (lon <= -37.0) & (lat >= 30.0) & (lat <= 36.0)
    return np.where(in2, 4.0, 1.0), np.where(in1, 240.0, 0.0)


def _unambiguous(reference, heading, hours, delta_deg=3.0, delta_h=1.0):
    """Points whose reference class does not change when the heading moves by +-delta_deg or the time by
    +-delta_h (where the library's 10 km track samples may legitimately pick a neighbouring course or time)."""
    base = reference(heading, hours)
    same = np.ones(base.shape, dtype=bool)
    for dh in (-delta_deg, delta_deg):
        same &= reference(heading + dh, hours) == base
    for dt in (-delta_h, delta_h):
        same &= reference(heading, hours + dt) == base
    return same


@pytest.mark.slow
def test_the_shading_is_the_failure_model_for_the_routes_own_headings() -> None:
    from matplotlib.path import Path as MplPath

    from pyroute_rel.reliability.risk import route_risk_field
    from pyroute_rel.viz.maps import plot_route

    route = _control(0.95).route()
    fig = plot_route(route)
    ax = fig.axes[0]
    x0, x1 = ax.get_xlim()
    y0, y1 = ax.get_ylim()
    lon, lat = np.meshgrid(np.linspace(x0, x1, 60), np.linspace(y0, y1, 45))
    field = route_risk_field(route, lon, lat)
    (_, _, course, hours), near = _candidates(route, lon, lat)
    hs, wave_from = _control_conditions(lon.ravel(), lat.ravel())
    p_ref, n_ref = _dickson(hs[:, None], wave_from[:, None], course[None, :])
    cls_ref = _classes(p_ref, n_ref, 0.95)
    lo, hi = (np.array([f(cls_ref[i, c]) for i, c in enumerate(near)]) for f in (np.min, np.max))
    ok = lo == hi  # the class of every candidate course agrees
    assert ok.mean() > 0.95
    np.testing.assert_array_equal(field.risk_class.ravel()[ok], lo[ok])
    p_lo = np.array([p_ref[i, c].min() for i, c in enumerate(near)])
    np.testing.assert_array_equal(field.p_f.ravel()[ok], p_lo[ok])
    # the library's course is one of the candidates' (to the 1 km spacing of the reference track)
    gap = [
        np.min(np.abs((course[c] - h + 180.0) % 360.0 - 180.0))
        for c, h in zip(near, field.heading_deg.ravel(), strict=True)
    ]
    assert max(gap) < 0.1
    hs, wave_from = hs.reshape(lon.shape), wave_from.reshape(lon.shape)
    # the route's apf 0.95 forbids Area 1 (both criteria: p_f 1) and allows Area 2 (wave height: p_f 0.9); nothing
    # fires outside the patches: waves from the north are never on the bow of a route sailing south-west
    in2 = hs >= 4.0
    assert set(np.unique(field.risk_class[~in2])) == {0}
    assert (field.risk_class[in2 & (wave_from == 240.0)] == 2).all()
    assert (field.risk_class[in2 & (wave_from == 0.0)] == 1).all()

    # the figure: the shaded areas lie inside the patches (to a cell of its mesh), with p_f and apf in the legend
    shaded = {c.get_gid(): c for c in ax.collections if (c.get_gid() or "").startswith("risk")}
    assert sorted(shaded) == ["risk 1 0", "risk 2 0"]
    cell = max((x1 - x0), (y1 - y0)) / 100
    for gid, box in (("risk 2 0", (-43.0, -37.0, 30.0, 36.0)), ("risk 1 0", (-45.0, -35.0, 28.0, 38.0))):
        xy = np.concatenate([p.vertices for p in shaded[gid].get_paths()])
        assert xy[:, 0].min() > box[0] - cell and xy[:, 0].max() < box[1] + cell
        assert xy[:, 1].min() > box[2] - cell and xy[:, 1].max() < box[3] + cell
    path = MplPath.make_compound_path(*shaded["risk 2 0"].get_paths())
    assert path.contains_point((-40.0, 33.0)) and not path.contains_point((-44.0, 33.0))
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    assert "forbidden: p_f 1 > apf 0.95" in legend
    assert "criteria fire, allowed: p_f 0.9 <= apf 0.95" in legend
    assert "apf 0.95" in ax.get_title() and f"largest leg p_f {route.max_failure_probability:g})" in ax.get_title()


def _time_varying_weather(tmp_path=None):
    """Uniform in space, varying in time: the wind veers 0.3 deg/h from the north at 15 kn, the waves (from the
    east, following a westbound route) grow 1/40 m per hour from 2 m: 4 m, where WH fires, 80 h after departure."""
    import xarray as xr

    from pyroute_rel.weather.io.readers import weather_from_dataset

    hours = np.arange(0.0, 481.0, 6.0)
    lon, lat = np.arange(-40.0, 10.01, 1.0), np.arange(20.0, 60.01, 1.0)
    twd = np.radians(0.3 * hours)
    ws = 15.0 / KN_PER_MS
    shape = (hours.size, lat.size, lon.size)
    series = {
        "u10": -ws * np.sin(twd),
        "v10": -ws * np.cos(twd),
        "swh": 2.0 + hours / 40.0,
        "mwd": np.full(hours.size, 90.0),
    }
    units = {"u10": "m s**-1", "v10": "m s**-1", "swh": "m", "mwd": "Degree true"}
    data = {
        k: (("time", "latitude", "longitude"), np.broadcast_to(v.astype(np.float32)[:, None, None], shape),
            {"units": units[k]})
        for k, v in series.items()
    }  # fmt: skip
    time = np.datetime64("2018-06-01T00:00") + (hours * 3600).astype("timedelta64[s]")
    ds = xr.Dataset(data, coords={"time": time, "latitude": lat, "longitude": lon})
    # the reference interpolates the stored (float32) values linearly in time
    stored = {k: np.asarray(v, dtype=np.float32).astype(float) for k, v in series.items()}
    if tmp_path is not None:
        ds.to_netcdf(tmp_path / "weather.nc")
        return None, hours, stored
    return weather_from_dataset(ds), hours, stored


@pytest.mark.slow
def test_file_weather_is_drawn_and_judged_at_the_time_the_route_passes() -> None:
    from dataclasses import replace

    from pyroute_rel.reliability.risk import route_risk_field
    from pyroute_rel.scenario import scenario_from_mapping
    from pyroute_rel.viz.maps import plot_route

    weather, hours_axis, stored = _time_varying_weather()
    sc = scenario_from_mapping(
        {
            "route": {"start": [-5.0, 45.0], "finish": [-20.0, 38.0], "departure": "2018-06-01T00:00:00Z"},
            "grid": {"n_ranks": 20},
            "weather": {"kind": "uniform", "tws_kn": 15.0, "twd_deg": 0.0},
            "avoid": {"land": False},
            "failure": {"model": "dickson2018", "apf": 0.95},
        }
    )
    route = replace(sc, weather=weather).route()
    assert route.elapsed_h[-1] > 120.0  # the waves reach 4 m on the way (80 h)
    lon, lat = np.meshgrid(np.linspace(-24.0, -1.0, 60), np.linspace(34.0, 49.0, 40))
    field = route_risk_field(route, lon, lat)
    (_, _, course, hours), near = _candidates(route, lon, lat)
    # the time the route passes nearest: one of the candidates' (to the 1 km spacing of the reference track)
    slowest_kmh = float(np.min(route.legs.sog_kn)) * 1.852
    gap = [np.min(np.abs(hours[c] - t)) for c, t in zip(near, field.elapsed_h.ravel(), strict=True)]
    assert max(gap) <= 1.0 / slowest_kmh

    def hs_at(t):
        return np.interp(t, hours_axis, stored["swh"])

    cls_ref = [_classes(*_dickson(hs_at(hours[c]), 90.0, course[c]), 0.95) for c in near]
    lo, hi = np.array([c.min() for c in cls_ref]), np.array([c.max() for c in cls_ref])
    ok = lo == hi
    assert ok.mean() > 0.9
    np.testing.assert_array_equal(field.risk_class.ravel()[ok], lo[ok])
    assert {0, 1} <= set(np.unique(lo[ok]))  # calm early, 4 m waves (p_f 0.9) later

    # the figure draws that weather: wave height in colour, wind barbs [kn] (velocity, blowing to)
    fig = plot_route(route)
    ax = fig.axes[0]
    (mesh,) = [c for c in ax.collections if c.get_gid() == "hs"]
    (barbs,) = [c for c in ax.collections if c.get_gid() == "wind"]
    x0, x1 = ax.get_xlim()
    y0, y1 = ax.get_ylim()
    drawn = np.ma.filled(mesh.get_array(), np.nan)  # the map's mesh: map_mesh over the axes' limits
    lon_m, lat_m = np.meshgrid(np.linspace(x0, x1, drawn.shape[1]), np.linspace(y0, y1, drawn.shape[0]))
    every = (slice(None, None, 7), slice(None, None, 7))
    (_, _, _, t_dense), near_m = _candidates(route, lon_m[every], lat_m[every])
    hs_lo, hs_hi = _spread(hs_at(t_dense), near_m)
    hs_drawn = drawn[every].ravel()
    assert np.all((hs_drawn >= hs_lo - 1e-5) & (hs_drawn <= hs_hi + 1e-5))
    xy = barbs.get_offsets()
    _, near_b = _candidates(route, xy[:, 0], xy[:, 1])
    for name, drawn in (("u10", barbs.u), ("v10", barbs.v)):
        lo_b, hi_b = _spread(np.interp(t_dense, hours_axis, stored[name]) * KN_PER_MS, near_b)
        assert np.all((drawn >= lo_b - 1e-4) & (drawn <= hi_b + 1e-4)), name
    assert xy.shape[0] > 100


@pytest.mark.slow
def test_lines_zones_and_every_legs_grid_are_drawn_and_named() -> None:
    from dataclasses import replace

    from pyroute_rel.obstacles.zones import Zone
    from pyroute_rel.viz.maps import plot_route

    sc = _control(
        1.0,
        n_ranks=30,
        route={"start": None, "start_line": [[-16.0, 51.0], [-8.0, 45.0]],
               "finish_line": [[-60.0, 10.0], [-60.0, 25.0]], "waypoints": [[-30.0, 30.0]]},
    )  # fmt: skip
    zone = Zone("test box", shapely.box(-25.0, 38.0, -22.0, 41.0))
    sc = replace(sc, avoid=replace(sc.avoid, zones=(zone,)))
    route = sc.route()
    assert len(route.grids) == 2
    ax = plot_route(route).axes[0]
    lines = {ln.get_gid(): ln for ln in ax.get_lines() if ln.get_gid()}
    for i, grid in enumerate(route.grids):
        edge = lines[f"grid extent {i}"]
        np.testing.assert_array_equal(edge.get_ydata()[: grid.n_ranks], grid.lat_deg[:, 0])
        np.testing.assert_array_equal(edge.get_ydata()[grid.n_ranks : 2 * grid.n_ranks], grid.lat_deg[::-1, -1])
    np.testing.assert_array_equal(lines["waypoints"].get_xydata(), [[-30.0, 30.0]])
    start, finish = lines["start line"], lines["finish line"]
    assert start.get_color() != finish.get_color()
    np.testing.assert_allclose(finish.get_xdata(), -60.0)
    assert finish.get_ydata().min() == 10.0 and finish.get_ydata().max() == 25.0
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    for name in ("start line", "finish line", "waypoints", "exclusion zone: test box", "grid extent (each leg)"):
        assert name in legend


@pytest.mark.parametrize("weather", ["uniform", pytest.param("file", marks=pytest.mark.slow)])
def test_route_out_draws_its_map_without_pyplot(tmp_path, weather) -> None:
    import subprocess
    import sys

    if weather == "file":
        _time_varying_weather(tmp_path)
        table = '[weather]\nkind = "file"\npaths = ["weather.nc"]\n'
    else:
        table = (
            '[weather]\nkind = "uniform"\ntws_kn = 15.0\ntwd_deg = 0.0\nhs_m = 1.0\n[[weather.patch]]\n'
            "lon = [-15.0, -10.0]\nlat = [40.0, 43.0]\nhs_m = 4.0\n"
        )
    (tmp_path / "s.toml").write_text(
        '[route]\nstart = [-5.0, 45.0]\nfinish = [-20.0, 38.0]\ndeparture = "2018-06-01T00:00:00Z"\n'
        f'[grid]\nn_ranks = 12\n{table}[failure]\nmodel = "dickson2018"\napf = 0.95\n[avoid]\nland = false\n'
    )
    code = (
        "import sys\nfrom pyroute_rel.cli import main\n"
        f"rc = main(['route', {str(tmp_path / 's.toml')!r}, '--quiet', '--out', {str(tmp_path / 'o')!r}])\n"
        "print('\\n', rc, 'matplotlib.figure' in sys.modules, 'matplotlib.pyplot' in sys.modules)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=300)
    assert out.stdout.splitlines()[-1].split() == ["0", "True", "False"], out.stdout + out.stderr
    assert (tmp_path / "o" / "route.png").stat().st_size > 10_000


def test_probabilities_keep_their_digits() -> None:
    from hypothesis import given
    from hypothesis import strategies as st

    from pyroute_rel.reliability.risk import format_probability

    @given(st.floats(min_value=1e-12, max_value=1.0 - 1e-12))
    def check(p: float) -> None:
        text = format_probability(p)
        q = float(text)
        assert 0.0 < q < 1.0, text  # never printed as 0 or 1
        assert abs(q - p) <= 0.05 * min(p, 1.0 - p) * (1 + 1e-9), text  # two significant digits of what matters

    check()
    assert [format_probability(p) for p in (0.001, 0.0, 1.0, 0.95)] == ["0.001", "0", "1", "0.95"]


@pytest.mark.slow
def test_a_small_probability_keeps_its_digits_on_the_map(tmp_path) -> None:
    from test_reliability import straight, write_model

    from pyroute_rel.viz.maps import plot_route

    route = straight(write_model(tmp_path, p=0.001), 20, patch_lon=[-12.0, -8.0])
    assert route.max_failure_probability == pytest.approx(0.001, rel=1e-12)
    ax = plot_route(route).axes[0]
    assert "largest leg p_f 0.001)" in ax.get_title()  # was "max p_f 0.00"
    voyage = float(ax.get_title().split("voyage p_f ")[1].split(":")[0])
    assert voyage == pytest.approx(route.voyage_failure_probability, rel=0.05) and voyage > 0.0
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    assert "criteria fire, allowed: p_f 0.001 <= apf 1" in legend


@pytest.mark.slow
def test_in_a_current_the_shading_uses_the_heading_the_craft_steers() -> None:
    """West along the equator with 0.5 m/s of current to the north (as in test_reliability): the craft heads south
    of west to hold its course; waves from 208 deg are 62 deg off the course (WD would not fire) but within 60 deg of
    the heading, so the map shades WD (p_f 0.9) along the track, as the router's costs say leg by leg."""
    from pyroute_rel.reliability.risk import route_risk_field
    from pyroute_rel.scenario import scenario_from_mapping

    route = scenario_from_mapping(
        {
            "route": {"start": [0.0, 0.0], "finish": [-10.0, 0.0]},
            "grid": {"n_ranks": 10},
            "weather": {"kind": "uniform", "tws_kn": 15.0, "twd_deg": 0.0, "hs_m": 1.0, "wave_dir_deg": 208.0,
                        "current_u_ms": 0.0, "current_v_ms": 0.5},
            "avoid": {"land": False},
            "failure": {"model": "dickson2018", "apf": 1.0},
        }
    ).route()  # fmt: skip
    assert np.all(route.legs.p_f == 0.9)
    lon, lat = np.meshgrid(np.linspace(-9.5, -0.5, 10), [-0.2, 0.0, 0.2])
    field = route_risk_field(route, lon, lat)
    assert np.all(_dickson(1.0, 208.0, field.course_deg)[0] == 0.0)  # on the course alone WD would not fire
    south_of_course = (field.course_deg - field.heading_deg + 180.0) % 360.0 - 180.0
    assert np.all((south_of_course > 5.0) & (south_of_course < 20.0))
    np.testing.assert_array_equal(field.p_f, 0.9)
    np.testing.assert_array_equal(field.risk_class, 1)
