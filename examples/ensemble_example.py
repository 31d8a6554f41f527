"""Route a synthetic 20-member ensemble forecast and choose a route by risk; draw the ensemble's figures.

Run: ``python examples/ensemble_example.py`` (writes ``examples/data/ensemble_synthetic.nc`` first when it is
missing, with ``make_ensemble_example.py``). Routes every member of ``examples/ensemble.toml`` and the ensemble mean,
sails every route in every member, chooses by CVaR at 0.9, and writes ``ensemble_spaghetti.png``,
``ensemble_arrival_cdf.png``, ``ensemble_regret.png`` and ``ensemble.json`` into ``examples/output/`` (or ``--out
FOLDER``; ``--figures`` refreshes the committed figures in ``examples/figures/``).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

from output_options import add_output_options, output_folder

from pyroute_rel.analysis.ensemble import route_ensemble
from pyroute_rel.viz.ensemble import arrival_cdf, regret_heatmap, spaghetti_map

HERE = Path(__file__).resolve().parent


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_output_options(ap)
    ap.add_argument("--workers", type=int, help="processes (default: the CPUs available)")
    args = ap.parse_args()
    out = output_folder(ap, args)
    if not (HERE / "data" / "ensemble_synthetic.nc").exists():
        subprocess.run([sys.executable, str(HERE / "make_ensemble_example.py")], check=True)
    result = route_ensemble(HERE / "ensemble.toml", risk="cvar:0.9", workers=args.workers, progress=True)
    summary = result.summary()
    spaghetti_map(result, path=out / "ensemble_spaghetti.png", title="20-member synthetic ensemble: routes")
    arrival_cdf(result, path=out / "ensemble_arrival_cdf.png")
    regret_heatmap(result, path=out / "ensemble_regret.png")
    if not args.figures:
        (out / "ensemble.json").write_text(json.dumps(summary, indent=1), encoding="utf-8")
    ch = summary["chosen"]

    def h(x: float | None) -> str:
        return "unbounded" if x is None else f"{x:.1f} h"

    print(
        f"chosen: {ch['name']} ({ch['risk']} {h(ch['value_h'])}, infeasible in {ch['infeasible_members']:.0%} of the "
        f"members); mean-field route: {h(ch['mean_field_value_h'])}, infeasible in "
        f"{ch['mean_field_infeasible_members']:.0%}"
    )
    print(f"figures in {out}")


if __name__ == "__main__":
    main()
