"""What would make a route (issue 35, item 1): every relaxation, applied, routes, and is the least one.

References: brute force -- the course routed (without relaxation) at every value of the failure table, at every
departure of the window, with the polar's empty column filled -- and the grid's own arcs and the evaluator for the
partial route.
"""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
from test_track_waits import storm_scenario

from pyroute_rel import scenario_from_mapping
from pyroute_rel.analysis.evaluate import evaluate_track
from pyroute_rel.cli import main
from pyroute_rel.errors import NoFeasibleRouteError
from pyroute_rel.routing.relax import apf_text

#: A short course in steady wind with 4.5 m waves everywhere: WH fires on every arc.
ROUGH = {
    "route": {"start": [-12.0, 45.0], "finish": [-14.0, 43.0], "departure": "2018-06-01T00:00:00Z"},
    "grid": {"layout": "square", "n_ranks": 5, "n_nodes": 7, "samples_per_arc": 4},
    "weather": {"kind": "uniform", "tws_kn": 15.0, "twd_deg": 0.0, "hs_m": 4.5},
    "avoid": {"land": False},
}


def _no_route(sc, **kw) -> NoFeasibleRouteError:
    with pytest.raises(NoFeasibleRouteError) as info:
        sc.route(**kw)
    return info.value


def _routes(sc) -> bool:
    try:
        sc.route(relax=False)
    except NoFeasibleRouteError:
        return False
    return True


@pytest.mark.parametrize(("model", "apf"), [("dickson2018", 0.5), ("wind_wave_multistate", 0.02)])
def test_the_smallest_apf_is_the_first_table_value_that_routes(model, apf):
    """Brute force over every value of the failure table above the apf: the first that routes is the relaxation's
    (dickson2018: three values, tried in turn; wind_wave_multistate: 350, a binary search), and its voyage time is
    the route's at that apf."""
    sc = scenario_from_mapping({**ROUGH, "failure": {"model": model, "apf": apf}})
    rel = _no_route(sc).relaxation
    table = np.unique(sc.load_failure().p_flat)
    first = next(float(v) for v in [*table[table > apf], 1.0] if _routes(sc.with_options(apf=float(v))))
    assert rel.apf == first
    assert sc.with_options(apf=first).route().voyage_time_h == rel.apf_voyage_time_h
    written = apf_text(first)  # rounded up: never below the level, so that applying it routes
    assert (
        float(written) >= first and f"it routes with --apf {written} ({rel.apf_voyage_time_h:.2f} h)" in rel.message()
    )
    assert sc.with_options(apf=float(written)).route().voyage_time_h == rel.apf_voyage_time_h


def test_the_earliest_departure_of_the_window_routes_and_none_before_it():
    """6 m waves everywhere until 20 h forbid every arc at apf 0.5: leaving at 0 h there is no route; the window
    0-36 h every 3 h finds the first departure that routes, which brute force confirms."""
    sc = replace(storm_scenario(), time_step_h=None, max_wait_h=0.0)  # no waiting: the departure must move
    window = [sc.departure + np.timedelta64(3 * i, "h") for i in range(13)]
    rel = _no_route(sc, departures=window).relaxation
    expected = next(t for t in window if _routes(sc.with_options(departure=t)))
    assert rel.departure == expected and rel.departure > sc.departure
    assert sc.with_options(departure=rel.departure).route().voyage_time_h == rel.departure_voyage_time_h
    assert rel.window == (str(window[0]) + "Z", str(window[-1]) + "Z", 13)


def test_an_empty_polar_column_is_named_with_the_wind_met_and_filling_it_routes(tmp_path):
    """A polar whose top column (28 kn) has no speed, in 30 kn of wind: the message names the column, the wind met
    and that winds above it use it; the same polar with the column filled routes."""
    speeds = {0: (0, 0, 0), 45: (2.0, 3.5, 4.2), 90: (3.0, 4.8, 5.5), 180: (2.5, 4.0, 5.0)}

    def polar(top: dict[int, float]) -> str:
        rows = ["TWA\\TWS\t6\t12\t20\t28"]
        rows += ["\t".join(str(v) for v in (twa, *row, top[twa])) for twa, row in speeds.items()]
        return "\n".join(rows) + "\n"

    (tmp_path / "empty.pol").write_text(polar(dict.fromkeys(speeds, 0)), encoding="utf-8")
    (tmp_path / "filled.pol").write_text(polar({0: 0, 45: 4.4, 90: 5.7, 180: 5.2}), encoding="utf-8")
    table = {**ROUGH, "weather": {"kind": "uniform", "tws_kn": 30.0, "twd_deg": 0.0, "hs_m": 1.0}}
    sc = scenario_from_mapping({**table, "boat": {"polar": str(tmp_path / "empty.pol")}})
    message = str(_no_route(sc))
    assert "no boat speed in the polar" in message and "wind there TWS 30.0-30.0 kn" in message
    assert "has no speed in its TWS 28 kn column, and winds above 28 kn use that column" in message
    assert _routes(scenario_from_mapping({**table, "boat": {"polar": str(tmp_path / "filled.pol")}}))


def test_the_partial_route_is_a_sailable_path_to_the_reached_node_closest_to_the_finish():
    """The control course on a grid too narrow to pass the patches at apf 0.5: the partial route follows arcs of
    the grid from the start, the evaluator sails it within apf, and no node the DP reached is closer to the finish
    (brute force over every reached node)."""
    from pathlib import Path

    from pyroute_rel.scenario import load_scenario

    control = Path(__file__).resolve().parents[1] / "examples" / "microtransat_control.toml"
    sc = load_scenario(control).with_options(apf=0.5, half_width_km=100.0, n_ranks=40)
    error = _no_route(sc)
    rel, result = error.relaxation, error.result
    part = rel.partial
    grid = sc.make_grid()
    for k in range(1, part.rank + 1):  # each step is an arc of the grid: node j on rank k-1 to a node on rank k
        j0 = int(
            np.flatnonzero(
                np.isclose(grid.lon_deg[k - 1], part.lon_deg[k]) & np.isclose(grid.lat_deg[k - 1], part.lat_deg[k])
            )[0]
        )
        j1 = int(
            np.flatnonzero(
                np.isclose(grid.lon_deg[k], part.lon_deg[k + 1]) & np.isclose(grid.lat_deg[k], part.lat_deg[k + 1])
            )[0]
        )
        src, valid = grid.pattern(k)
        assert any(valid[j1, a] and src[j1, a] == j0 for a in range(src.shape[1]))
    ev = evaluate_track(sc, np.column_stack([part.lon_deg, part.lat_deg]))
    assert ev.feasible and ev.max_failure_probability <= 0.5
    ranks, nodes = np.nonzero(np.isfinite(result.arrival_h))
    closest = min(grid.distance_to_finish_nm(float(grid.lon_deg[k, j]), float(grid.lat_deg[k, j]))
                  for k, j in zip(ranks, nodes, strict=True))  # fmt: skip
    assert part.distance_to_finish_nm == closest
    assert f"the closest a route gets is {closest:.0f} nm from the finish" in str(error)


def test_a_course_names_the_leg_that_fails():
    """Through a waypoint, the second leg in 4.5 m waves at apf 0.5: the first leg routes, the message names leg 2
    of 2 and the apf that routes the whole course."""
    table = {
        **ROUGH,
        "route": {**ROUGH["route"], "finish": [-16.0, 45.0], "waypoints": [[-14.0, 45.0]]},
        "weather": {
            **ROUGH["weather"],
            "hs_m": 1.0,
            "patch": [{"lon": [-16.5, -14.2], "lat": [40.0, 50.0], "hs_m": 4.5}],
        },  # fmt: skip
        "failure": {"model": "dickson2018", "apf": 0.5},
    }
    sc = scenario_from_mapping(table)
    error = _no_route(sc)
    assert str(error).startswith("leg 2 of 2: no feasible route") and error.relaxation.leg == 1
    assert error.relaxation.apf == 0.9 and _routes(sc.with_options(apf=0.9))


def test_sweep_runs_route_json_and_tradeoff_carry_the_relaxation(tmp_path, capsys):
    path = tmp_path / "rough.toml"
    path.write_text(
        '[route]\nstart = [-12.0, 45.0]\nfinish = [-14.0, 43.0]\ndeparture = "2018-06-01T00:00:00Z"\n'
        '[grid]\nlayout = "square"\nn_ranks = 5\nn_nodes = 7\n'
        '[weather]\nkind = "uniform"\ntws_kn = 15.0\ntwd_deg = 0.0\nhs_m = 4.5\n'
        '[failure]\nmodel = "dickson2018"\napf = 0.5\n[avoid]\nland = false\n',
        encoding="utf-8",
    )
    assert main(["sweep", str(path), "--apf", "0.5,0.95", "--engine", "inline", "--quiet", "--json"]) == 0
    rows = {r["apf"]: r for r in json.loads(capsys.readouterr().out)["runs"]}
    assert rows[0.5]["status"] == "no_route" and "To route: it routes with --apf 0.9" in rows[0.5]["message"]
    assert rows[0.95]["status"] == "ok"
    assert main(["route", str(path), "--quiet", "--json"]) == 2
    printed = json.loads(capsys.readouterr().out)
    assert printed["feasible"] is False and printed["relaxation"]["apf"] == 0.9
    assert main(["tradeoff", str(path), "--quiet"]) == 2  # the fronts: the same relaxation
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert "To route: it routes with --apf 0.9" in line


def test_a_wider_grid_that_cannot_be_built_leaves_the_no_route_error(tmp_path):
    """The finish inside 4 m waves at apf 0.5 on a grid already 3000 km wide: doubling it is refused as a grid (too
    wide), which must not replace the no-route error (a review found the grid's error shown instead)."""
    from pathlib import Path

    from pyroute_rel.scenario import load_scenario

    control = Path(__file__).resolve().parents[1] / "examples" / "microtransat_control.toml"
    sc = replace(load_scenario(control), finish=(-40.0, 33.0)).with_options(apf=0.5, half_width_km=3000.0, n_ranks=40)
    error = _no_route(sc)
    # the front never reached the grid's edge, so no wider grid is tried; tried anyway, its grid error is not raised
    assert not error.relaxation.wider_tried
    tried = sc._wider(error.relaxation, sc.make_grid())
    assert tried.wider is None and tried.wider_tried
    assert "a grid twice as wide does not route it either" in tried.message()


def test_departure_options_that_do_not_go_together_are_refused(tmp_path, capsys):
    path = tmp_path / "rough.toml"
    path.write_text('[route]\nstart = [-12.0, 45.0]\nfinish = [-14.0, 43.0]\n[weather]\nkind = "uniform"\n'
                    "tws_kn = 15.0\ntwd_deg = 0.0\n[avoid]\nland = false\n", encoding="utf-8")  # fmt: skip
    for extra in (["--departure", "2018-06-03"], ["--departure-window", "2018-06-01,2018-06-02,6"]):
        assert main(["route", str(path), "--departures", "2018-06-01,2018-06-02", *extra]) == 2
        assert "do not go together" in capsys.readouterr().err
    assert main(["route", str(path), "--departure-window", "2018-06-01,2018-07-01,1e-5"]) == 2  # counted first
    assert "more than 1000: use a larger STEP_H" in capsys.readouterr().err
