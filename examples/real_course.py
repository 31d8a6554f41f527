"""Route the Microtransat East->West race course with land, a coastal margin and an exclusion zone.

Routes ``microtransat_real_course.toml`` (start line 51N 16W - 45N 8W, finish on 60 W between 10 N and 25 N,
the paper's control weather and patches, ``dickson2018`` at apf 0.95, land with a 10 km margin, the sample
fishing-grounds zone) on its default grid. The race route stays north of the zone, so for comparison it also
routes the paper's verification course (45N 12W -> 17.5N 60W, whose great circle crosses the zone) with the same
land, margin and zone at apf 1, where the zone makes the route go round it. Draws both over the coast with the
zone, the start and finish lines and the weather patches.

Run: ``python examples/real_course.py [--out FOLDER | --figures]``; writes ``real_course.png`` into
``examples/output/`` (or ``--out``; ``--figures`` refreshes the README's figure in ``examples/figures/``) and prints
the voyage times.
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

from output_options import add_output_options, output_folder

from pyroute_rel.scenario import load_scenario
from pyroute_rel.viz.maps import plot_routes

HERE = Path(__file__).resolve().parent


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_output_options(ap)
    args = ap.parse_args()
    out = output_folder(ap, args)

    race = load_scenario(HERE / "microtransat_real_course.toml")
    paper = dataclasses.replace(
        race, start=(-12.0, 45.0), finish=(-60.0, 17.5), start_line=None, finish_line=None, apf=1.0
    )
    routes, labels = [], []
    for name, sc in ((f"race course, apf {race.apf:g}", race), ("45N 12W -> 17.5N 60W, apf 1", paper)):
        t0 = time.perf_counter()
        route = sc.route()
        print(
            f"{name}: {route.voyage_time_h:.1f} h, {route.distance_nm:.0f} nm, max leg p_f "
            f"{route.max_failure_probability:.2f}, {route.grid.n_ranks} x {route.grid.n_nodes} grid, "
            f"routed in {time.perf_counter() - t0:.1f} s"
        )
        routes.append(route)
        labels.append(name)

    g = routes[0].grid
    # the failure model's classes for the race route's headings and apf; the lines, the zone and the patches named
    fig = plot_routes(
        routes,
        labels=labels,
        weather=race.weather,
        zones=race.avoid.zones,
        title=f"Microtransat East->West: land + {race.avoid.margin_km:g} km margin, exclusion zone "
        f"({g.n_ranks} ranks x {g.n_nodes} nodes)",
    )
    fig.savefig(out / "real_course.png")
    print(f"wrote {out / 'real_course.png'}")


if __name__ == "__main__":
    main()
