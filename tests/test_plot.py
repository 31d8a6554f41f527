"""Maps: coastlines and zones are single artists, holes stay empty."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import shapely  # noqa: E402

from pyroute_rel import obstacles as ob  # noqa: E402
from pyroute_rel.plot import _fill_polygons  # noqa: E402


def _signed_area(xy: np.ndarray) -> float:
    x, y = xy[:, 0], xy[:, 1]
    return 0.5 * float(np.sum(x[:-1] * y[1:] - x[1:] * y[:-1]))


def test_polygons_with_holes_fill_as_one_artist_with_empty_holes() -> None:
    # exterior given clockwise and hole counter-clockwise: the worst case for the nonzero fill rule
    outer = [(0, 0), (0, 3), (3, 3), (3, 0)]
    hole = [(1, 1), (2, 1), (2, 2), (1, 2)]
    geom = shapely.MultiPolygon([shapely.Polygon(outer, [hole]), shapely.box(4, 0, 5, 1)])
    fig, ax = plt.subplots()
    try:
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
    finally:
        plt.close(fig)


def test_a_coastline_of_thousands_of_parts_is_one_artist() -> None:
    land = ob.land_geometry((-70.0, 8.0, -55.0, 20.0))  # the Caribbean: hundreds of islands
    assert len(shapely.get_parts(land)) > 100
    fig, ax = plt.subplots()
    try:
        _fill_polygons(ax, land, facecolor="0.85")
        assert len(ax.collections) == 1
        assert len(ax.collections[0].get_paths()) == len(shapely.get_parts(land))
    finally:
        plt.close(fig)


def test_a_refined_route_map_draws_the_grid_track_too() -> None:
    from dataclasses import replace
    from pathlib import Path

    from pyroute_rel.plot import plot_route
    from pyroute_rel.scenario import load_scenario

    sc = load_scenario(Path(__file__).resolve().parents[1] / "examples" / "microtransat_control.toml")
    sc = sc.with_options(n_ranks=30, land=False)
    route = replace(sc, refine=1).route()
    fig = plot_route(route)
    try:
        lines = {ln.get_label(): ln for ln in fig.axes[0].get_lines()}
        before = [k for k in lines if "before refinement" in k]
        assert len(before) == 1 and f"{route.meta['refine']['grid_voyage_time_h']:.1f} h" in before[0]
        assert "route (refined): " + f"{route.voyage_time_h:.1f} h" in lines
        np.testing.assert_array_equal(lines[before[0]].get_xdata(), route.grid_track.lon_deg)
    finally:
        plt.close(fig)


def test_a_course_across_the_antimeridian_maps_continuously_and_splits_its_geojson(tmp_path) -> None:
    import json

    from pyroute_rel.cli import main
    from pyroute_rel.plot import plot_route
    from pyroute_rel.scenario import scenario_from_mapping

    sc = scenario_from_mapping(
        {
            "route": {"start": [170.0, 30.0], "finish": [-170.0, 32.0]},
            "grid": {"n_ranks": 20},
            "weather": {"kind": "uniform", "tws_kn": 15.0, "twd_deg": 0.0},
        }
    )
    route = sc.route()
    fig = plot_route(route)
    try:
        ax = fig.axes[0]
        (track,) = [ln for ln in ax.get_lines() if ln.get_label().startswith("route")]
        x = np.asarray(track.get_xdata())
        assert np.all(np.abs(np.diff(x)) < 5.0) and x[0] == 170.0 and x[-1] == 190.0  # no jump across the map
        lo, hi = ax.get_xlim()
        assert 160.0 < lo < 170.0 and 190.0 < hi < 200.0  # framed on the course, not the whole world
        assert ax.xaxis.get_major_formatter()(185.0, 0) == "-175"
    finally:
        plt.close(fig)
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
