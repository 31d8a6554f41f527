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

from pyroute_rel.plot import plot_routes
from pyroute_rel.scenario import load_scenario

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
    # no failure shading: it is drawn for the heading towards the grid's finish, which misleads south of it
    fig = plot_routes(
        routes,
        labels=labels,
        weather=race.weather,
        zones=race.avoid.zones,
        title=f"Microtransat East->West: land + {race.avoid.margin_km:g} km margin, exclusion zone "
        f"({g.n_ranks} ranks x {g.n_nodes} nodes)",
    )
    ax = fig.axes[0]
    from matplotlib.patches import Patch

    for (a, b), what in ((race.start_line, "start line"), (race.finish_line, "finish line")):
        ax.plot([a[0], b[0]], [a[1], b[1]], color="k", lw=2.5, solid_capstyle="butt", label=what)
    ax.plot(routes[0].lon_deg[0], routes[0].lat_deg[0], "o", color="tab:blue", ms=5, label="race start (on the line)")
    handles, names = ax.get_legend_handles_labels()
    names = [{"start": "grid start (line midpoint)", "finish": "grid finish (aim point)"}.get(n, n) for n in names]
    for zone in race.avoid.zones:
        handles.append(Patch(color="tab:purple", alpha=0.25, label=f"zone: {zone.name}"))
        names.append(f"zone: {zone.name}")
    ax.legend(handles, names, fontsize=7, loc="upper left", framealpha=0.9)
    ax.set_xlim(-68.0, -4.0)
    ax.set_ylim(8.0, 55.0)
    fig.tight_layout()
    fig.savefig(out / "real_course.png")
    print(f"wrote {out / 'real_course.png'}")


if __name__ == "__main__":
    main()
