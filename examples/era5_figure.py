"""Route the time-varying ERA5-layout example and draw it over the wind field.

Run: ``python examples/era5_figure.py`` (generates ``examples/data/era5_synthetic.nc`` first when it is missing).
Writes ``era5_route.png`` into ``examples/output/`` (or ``--out FOLDER``; ``--figures`` refreshes the README's figure
in ``examples/figures/``): true wind speed (colour) and direction (arrows, blowing *to*) at
mid-voyage, the routes at apf 1.0 and 0.5, and the date every five days along the apf 1.0 route.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

import numpy as np
from output_options import add_output_options, output_folder

from pyroute_rel.scenario import load_scenario

HERE = Path(__file__).resolve().parent


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_output_options(ap)
    args = ap.parse_args()
    out = output_folder(ap, args)
    data = HERE / "data" / "era5_synthetic.nc"
    if not data.exists():
        subprocess.run([sys.executable, str(HERE / "make_era5_example.py")], check=True)
    base = load_scenario(HERE / "microtransat_era5.toml")
    routes = {apf: base.with_options(apf=apf).route() for apf in (1.0, 0.5)}
    for apf, r in routes.items():
        print(f"apf {apf:g}: {r.voyage_time_h:.1f} h, max leg p_f {r.max_failure_probability:.2f}")

    from pyroute_rel.viz.maps import new_figure  # matplotlib's object API on an Agg canvas (no pyplot)

    r1 = routes[1.0]
    t_mid = r1.departure + np.timedelta64(int(r1.voyage_time_h * 1800), "s")
    lon = np.linspace(-68.0, -2.0, 133)
    lat = np.linspace(8.0, 52.0, 89)
    glon, glat = np.meshgrid(lon, lat)
    cond = base.weather.sample(glon, glat, np.datetime64(t_mid, "ms"))
    fig = new_figure(figsize=(10, 6.5), dpi=110)
    ax = fig.add_subplot()
    pc = ax.pcolormesh(glon, glat, cond.tws_kn, cmap="viridis", shading="auto")
    fig.colorbar(pc, ax=ax, shrink=0.75, label=f"true wind speed [kn] at {str(t_mid)[:13]} UTC")
    step = 6
    to = np.radians(cond.twd_deg[::step, ::step] + 180.0)  # arrows point where the wind blows to
    ax.quiver(glon[::step, ::step], glat[::step, ::step], np.sin(to), np.cos(to), color="w", alpha=0.7, scale=40)
    colours = {1.0: "tab:red", 0.5: "tab:orange"}
    for apf, r in routes.items():
        ax.plot(r.lon_deg, r.lat_deg, color=colours[apf], lw=2.0, label=f"apf {apf:g}: {r.voyage_time_h:.1f} h")
    times = r1.time
    for day in range(0, int(r1.voyage_time_h // 24) + 1, 5):
        i = int(np.argmin(np.abs(r1.elapsed_h - 24.0 * day)))
        ax.plot(r1.lon_deg[i], r1.lat_deg[i], "o", color="tab:red", ms=4)
        ax.annotate(
            str(times[i])[5:10],
            (r1.lon_deg[i], r1.lat_deg[i]),
            xytext=(4, 4),
            textcoords="offset points",
            color="w",
            fontsize=8,
        )
    ax.plot(*r1.grid.start, "w^", ms=8)
    ax.plot(*r1.grid.finish, "ws", ms=8)
    ax.set_xlabel("longitude [deg]")
    ax.set_ylabel("latitude [deg]")
    ax.set_aspect(1.0 / np.cos(np.radians(30.0)))
    ax.set_title("Synthetic ERA5-layout weather (time-varying): routes and the wind at mid-voyage")
    ax.legend(loc="lower left", fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "era5_route.png")
    print(f"wrote {out / 'era5_route.png'}")


if __name__ == "__main__":
    main()
