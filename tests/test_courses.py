"""Courses: start lines, finish lines (the voyage ends at the first crossing) and waypoints."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pyroute_rel import geodesy
from pyroute_rel.errors import ScenarioError
from pyroute_rel.scenario import scenario_from_mapping

BASE = {
    "grid": {"n_ranks": 30, "aspect": 4.0, "half_width_km": 900.0},
    "weather": {"kind": "uniform", "tws_kn": 15.0, "twd_deg": 0.0},
}
FINISH_LINE = [[-60.0, 10.0], [-60.0, 25.0]]
START_LINE = [[-16.0, 51.0], [-8.0, 45.0]]


def scenario(route: dict, **grid):
    return scenario_from_mapping({**BASE, "grid": {**BASE["grid"], **grid}, "route": route})


def test_finish_line_ends_on_the_line_and_beats_any_point_on_it() -> None:
    with_line = scenario({"start": [-12.0, 45.0], "finish_line": FINISH_LINE}).route()
    lon, lat = with_line.lon_deg[-1], with_line.lat_deg[-1]
    # the last point is on the line (the meridian 60 W between 10 and 25 N) ...
    assert abs(float(geodesy.cross_track_km(-60.0, 10.0, -60.0, 25.0, lon, lat))) < 1e-6
    assert 10.0 <= lat <= 25.0
    # ... and no earlier point is past it (the voyage ends at the first crossing)
    assert np.all(with_line.lon_deg[:-1] > -60.0)
    # the grid aims at the line's point nearest the start (25 N here); on that same grid, finishing anywhere on
    # the line is at least as fast as finishing at the aim point
    assert with_line.grid.finish == pytest.approx((-60.0, 25.0))
    to_point = scenario({"start": [-12.0, 45.0], "finish": [-60.0, 25.0]}).route()
    assert with_line.voyage_time_h <= to_point.voyage_time_h + 1e-9
    # with the aim point given explicitly the line is still honoured
    mid = scenario({"start": [-12.0, 45.0], "finish": [-60.0, 17.5], "finish_line": FINISH_LINE}).route()
    assert abs(float(geodesy.cross_track_km(-60.0, 10.0, -60.0, 25.0, mid.lon_deg[-1], mid.lat_deg[-1]))) < 1e-6
    # the last leg's recomputed time is consistent with the voyage time
    assert with_line.elapsed_h[-1] == pytest.approx(with_line.dp.finish_h, rel=1e-9)


def test_start_line_starts_on_the_line_and_is_no_slower() -> None:
    line = scenario({"start_line": START_LINE, "finish": [-60.0, 17.5]}).route()
    lon, lat = line.lon_deg[0], line.lat_deg[0]
    assert abs(float(geodesy.cross_track_km(*START_LINE[0], *START_LINE[1], lon, lat))) < 1e-6
    mid = scenario(
        {
            "start": [float(v) for v in geodesy.intermediate_point(*START_LINE[0], *START_LINE[1], 0.5)],
            "finish": [-60.0, 17.5],
        }
    ).route()
    assert line.voyage_time_h <= mid.voyage_time_h + 1e-9


def test_waypoints_pass_the_marks_and_add_up() -> None:
    wp = [-30.0, 40.0]
    whole = scenario({"start": [-12.0, 45.0], "finish": [-60.0, 17.5], "waypoints": [wp]}, n_ranks=40)
    route = whole.route()
    hit = np.nonzero(np.isclose(route.lon_deg, wp[0]) & np.isclose(route.lat_deg, wp[1]))[0]
    assert hit.size == 1
    # legs solved on their own: the same grids, the second leg departing at the first one's arrival
    grids = whole.leg_grids()
    assert len(grids) == 2 and grids[0].finish == (-30.0, 40.0) and grids[1].start == (-30.0, 40.0)
    from pyroute_rel.routing.route import route_on_grid

    leg1 = route_on_grid(grids[0], whole.problem(grid=grids[0]))
    leg2 = route_on_grid(grids[1], whole.with_options(departure=str(leg1.arrival)).problem(grid=grids[1]))
    with pytest.raises(ValueError, match="another grid"):
        route_on_grid(grids[1], whole.problem(grid=grids[0]))
    assert route.voyage_time_h == pytest.approx(leg1.voyage_time_h + leg2.voyage_time_h, abs=1e-3)
    assert route.elapsed_h[hit[0]] == pytest.approx(leg1.voyage_time_h, rel=1e-9)
    # the summary's grid counts the ranks of both legs and describes each (it described the first leg only)
    grid = route.summary()["grid"]
    assert grid["n_ranks"] == grids[0].n_ranks + grids[1].n_ranks
    assert [g["n_ranks"] for g in grid["legs"]] == [grids[0].n_ranks, grids[1].n_ranks]


@pytest.mark.parametrize(
    "route,match",
    [
        ({"start": [-12.0, 45.0], "finish": [-50.0, 17.5], "finish_line": FINISH_LINE}, "must lie on"),
        ({"start": [-12.0, 45.0], "finish_line": [[-60.0, 10.0], [-60.0, 10.0]]}, "must differ"),
        ({"start": [-12.0, 45.0], "finish_line": [-60.0, 10.0]}, r"finish_line\[0\] must be \[lon, lat\]"),
        ({"start": [-12.0, 45.0], "finish": [-60.0, 17.5], "waypoints": [[-30.0, 95.0]]}, r"waypoints\[0\]"),
        # a start off its start line (QA: it was accepted and routed from the line's end, away from the finish)
        (
            {"start": [-10.0, 30.0], "start_line": [[-20.0, 39.0], [-20.0, 41.0]], "finish": [-30.0, 35.0]},
            r"\[route\]\.start \[-10\.0, 30\.0\] must lie on \[route\]\.start_line \(1355\.\d km off it\)",
        ),
        # beyond the end of the finish line, though on its great circle
        ({"start": [-12.0, 45.0], "finish": [-60.0, 30.0], "finish_line": FINISH_LINE}, "must lie on"),
        (
            {"start_line": [[-20.0, 35.0], [-20.0, 40.0]], "finish_line": [[-25.0, 37.0], [-15.0, 37.0]]},
            r"start_line crosses \[route\]\.finish_line",
        ),
        ({"start": [-180.0, 40.0], "finish": [180.0, 40.0]}, r"are the same point: consecutive marks"),
        ({"start": [-20.0, 40.0], "finish": [-20.0, 40.000001]}, r"are 0 m apart"),
        (
            {"start": [-20.0, 40.0], "finish": [-30.0, 35.0], "waypoints": [[-25.0, 38.0], [-25.0, 38.0]]},
            r"\[route\]\.waypoints\[0\] \[-25\.0, 38\.0\] and \[route\]\.waypoints\[1\] .* same point",
        ),
    ],
)
def test_bad_courses(route: dict, match: str) -> None:
    with pytest.raises(ScenarioError, match=match):
        scenario(route)


@pytest.mark.slow
@pytest.mark.parametrize("options", [{}, {"layout": "square", "n_nodes": 30, "n_ranks": 30}], ids=["angular", "square"])
def test_finish_line_crossings_prefilter_is_exact(options) -> None:
    # the solver tests only arcs with ends on both sides of the finish line's great circle; the full test of
    # every arc (geodesy.crossing_fraction) must give the same fractions, NaN for the same arcs
    from pyroute_rel import geodesy
    from pyroute_rel.routing.solve import _crossing
    from pyroute_rel.scenario import load_scenario

    sc = load_scenario(Path(__file__).resolve().parents[1] / "examples" / "microtransat_real_course.toml")
    grid = sc.with_options(**options).make_grid()
    (c_lon, c_lat), (d_lon, d_lat) = grid.finish_line
    crossings = 0
    for k in range(grid.n_ranks + 1):
        lon0, lat0, lon1, lat1, src, _ = grid.arcs(k)
        ref = np.broadcast_to(geodesy.crossing_fraction(lon0, lat0, lon1, lat1, c_lon, c_lat, d_lon, d_lat), src.shape)
        np.testing.assert_array_equal(_crossing(grid, k), ref, err_msg=f"rank {k}")
        crossings += int(np.isfinite(ref).sum())
    assert crossings > 100  # precondition: the grid reaches the line


def test_avoid_and_course_lines_validate_their_arguments() -> None:
    from pyroute_rel.errors import GridError
    from pyroute_rel.obstacles.mask import Avoid
    from pyroute_rel.routing.grid import make_grid

    for kw, match in [
        ({"land": "no"}, "Avoid.land must be True or False"),
        ({"margin_km": -1.0}, r"margin_km must be a number of km in \[0, 200\]"),
        ({"zones": "zones.geojson"}, "Avoid.zones must be a sequence of Zone"),
        ({"resolution": "ultra"}, "Avoid.resolution must be one of"),
    ]:
        with pytest.raises(ScenarioError, match=match):
            Avoid(**kw)
    with pytest.raises(GridError, match=r"finish_line must be two \(lon, lat\) end points"):
        make_grid((-12.0, 45.0), (-60.0, 17.5), n_ranks=3, n_nodes=3, finish_line=((0.0, 0.0),))


def test_whole_numbers_given_as_strings_are_refused_like_other_numbers() -> None:
    with pytest.raises(ScenarioError, match=r"\[grid\]\.n_ranks must be a whole number \(got '20'\)"):
        scenario({"start": [-12.0, 45.0], "finish": [-60.0, 17.5]}, n_ranks="20")
