"""MCTS-UCT, tabular Q-learning and a DQN against the exact DP on five courses (issue 22).

Run: ``python benchmarks/planners.py [--quick] [--only WORD ...] [--planners WORD ...] [--json FILE]
[--figure FILE]``.

Courses: a 110 nm course in the control weather with a patch of 4.5 m waves on its great circle at apf 0.5, which
Jing et al.'s published 10 x 10 grid of 10 nm cells covers (a 10 x 11 DP grid), the paper's control course at apf 1
and at apf 0.5, the ERA5 example (time-varying gridded weather; its data are made by
``examples/make_era5_example.py`` when missing) and the real course with land, a coastal margin and a fishing zone
(``examples/microtransat_real_course.toml`` from its start line's middle to its finish, since the other planners
route point to point). Each planner's track is re-timed by the evaluator; the table gives the voyage time, the gap
to the DP on the scenario's grid and to the DP refined in two corridors, whether the track arrives and is feasible,
runtime and training time, work done (MCTS iterations, training voyages, arcs costed; for Q-learning the episode
from which its route stayed the final one and its own graph's optimum) and the track's mean and largest distance
from the DP's.

The settings (:data:`SETTINGS`) give each planner the budget it needs to arrive where it can (Q-learning: gamma = 1
and 100 000 episodes; a DQN trained on 100 voyages), plus Jing et al.'s published settings on cells; MCTS keeps
Barde's settings but the iterations per decision and the rollout horizon (15 000 iterations with rollouts to
arrival would take hours per course). A course takes about 5 to 15 minutes on a free core, most of it the DQN's
training and MCTS. ``--quick`` uses smaller settings. Timings are machine-dependent; the first line times fixed
workloads (``machine ...``, ``benchmarks/run.py``'s calibration) and the second gives the load average, so runs can
be compared.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
sys.path.insert(0, str(Path(__file__).resolve().parent))

from run import calibrate  # noqa: E402

from pyroute_rel import load_scenario, scenario_from_mapping  # noqa: E402
from pyroute_rel.planners.compare import compare_planners  # noqa: E402
from pyroute_rel.planners.settings import parse_planner  # noqa: E402

#: The planner runs of every course: (label, kind, [planner] table). "published" rows use the published settings
#: (Jing et al.'s 10 x 10 nm cells, 10 across, alpha 0.6, gamma 0.9, epsilon 0.2, 3000 iterations); the others have
#: the budget each needs to arrive (gamma = 1, many more episodes; a DQN trained on 100 voyages).
SETTINGS = {
    "full": [
        ("mcts (1000 it./decision, rollout 24 h)", "mcts", {"mcts": {"iterations": 1000, "rollout_h": 24.0}}),
        ("qlearning (graph, gamma 1, 100k episodes)", "qlearning", {"qlearning": {"episodes": 100_000, "gamma": 1.0}}),
        ("qlearning (cells, published)", "qlearning", {"qlearning": {"space": "cells"}}),
        (
            "qlearning (60 nm cells x 21, gamma 1, 100k episodes)",
            "qlearning",
            {"qlearning": {"space": "cells", "cell_nm": 60.0, "cells_across": 21, "gamma": 1.0, "episodes": 100_000}},
        ),
        ("dqn (100 voyages, 12 h steps)", "dqn", {"dqn": {"episodes": 100, "step_h": 12.0}}),
    ],
    "quick": [
        ("mcts", "mcts", {"mcts": {"iterations": 10, "step_h": 24.0, "rollout_h": 48.0}}),
        ("qlearning (graph)", "qlearning", {"qlearning": {"episodes": 500, "gamma": 1.0}}),
        (
            "qlearning (cells)",
            "qlearning",
            {"qlearning": {"space": "cells", "cell_nm": 120.0, "cells_across": 11, "episodes": 1000, "gamma": 1.0}},
        ),
        ("dqn", "dqn", {"dqn": {"episodes": 5, "step_h": 24.0, "hidden": [32]}}),
    ],
}

#: The DP grid of every course: 40 ranks (Q-learning on the graph learns on this grid).
N_RANKS = 40


def courses() -> dict[str, object]:
    """The four courses' scenarios (40-rank grids)."""
    control = load_scenario(EXAMPLES / "microtransat_control.toml").with_options(n_ranks=N_RANKS)
    era5_data = EXAMPLES / "data" / "era5_synthetic.nc"
    if not era5_data.exists():
        subprocess.run([sys.executable, str(EXAMPLES / "make_era5_example.py")], check=True)
    real_path = EXAMPLES / "microtransat_real_course.toml"
    real = tomllib.loads(real_path.read_text())
    (a, b) = real["route"].pop("start_line")
    real["route"].pop("finish_line")
    real["route"]["start"] = [(a[0] + b[0]) / 2.0, (a[1] + b[1]) / 2.0]
    real["grid"] = {"n_ranks": N_RANKS}
    jing = {  # 110 nm: Jing et al.'s 10 x 10 grid of 10 nm cells covers it; a 4.5 m wave patch on the great circle
        "route": {"start": [-12.0, 45.0], "finish": [-13.7916, 43.6903], "departure": "2018-06-01T00:00:00Z"},
        "grid": {"layout": "square", "n_ranks": 10, "n_nodes": 11},
        "weather": {
            "kind": "uniform",
            "tws_kn": 15.0,
            "twd_deg": 0.0,
            "hs_m": 1.0,
            "patch": [{"lon": [-13.15, -12.65], "lat": [44.15, 44.55], "hs_m": 4.5}],
        },
        "failure": {"model": "dickson2018", "apf": 0.5},
        "avoid": {"land": False},
    }
    return {
        "published grid: 110 nm, 10 x 10 cells of 10 nm": scenario_from_mapping(jing, source="benchmarks/planners.py"),
        "control course, apf 1": control.with_options(apf=1.0),
        "control course, apf 0.5": control.with_options(apf=0.5),
        "ERA5 example": load_scenario(EXAMPLES / "microtransat_era5.toml").with_options(n_ranks=N_RANKS),
        "real course with land and a zone": scenario_from_mapping(real, base_dir=EXAMPLES, source=str(real_path)),
    }


def table(rows: list[dict]) -> str:
    """The rows as the README's Markdown table."""

    def f(v: object, fmt: str) -> str:
        return "-" if v is None else format(v, fmt)

    head = (
        "| course | planner | voyage [h] | gap to DP [h] | gap to refined DP [h] | arrives, feasible | runtime [s] | "
        "training [s] | work | mean / max from DP [nm] |"
    )
    lines = [head, "|" + "---|" * 10]
    for r in rows:
        lines.append(
            f"| {r['course']} | {r['planner']} | {f(r['voyage_time_h'], '.2f')} | {f(r['gap_to_dp_h'], '+.2f')} | "
            f"{f(r['gap_to_refined_dp_h'], '+.2f')} | {'yes' if r['reached'] else 'no'}, "
            f"{'yes' if r['feasible'] else 'no'} | {f(r['runtime_s'], '.1f')} | {f(r['training_s'], '.1f')} | "
            f"{_work(r)} | {f(r['mean_cross_track_nm'], '.0f')} / {f(r['max_cross_track_nm'], '.0f')} |"
        )
    return "\n".join(lines)


def _work(r: dict) -> str:
    """Arcs costed, iterations or episodes; for Q-learning, from which episode its route stayed the final one and
    its own graph's optimum (Dijkstra) on a static problem."""
    text = "-" if r["iterations"] is None else f"{r['iterations']}"
    if r.get("episodes_to_final") is not None:
        text += f" (final from {r['episodes_to_final']})"
    if r.get("pass_voyage_times_h"):
        text += "; passes " + " / ".join("-" if t is None else f"{t:.1f}" for t in r["pass_voyage_times_h"]) + " h"
    opt = r.get("own_optimum_h")
    if opt is not None:
        text += f"; own optimum {opt:.2f} h" if opt < float("inf") else "; no route on its grid"
    return text


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="smaller settings (SETTINGS['quick'])")
    ap.add_argument("--only", nargs="*", help="courses whose name contains one of these words")
    ap.add_argument("--planners", nargs="*", help="planner runs whose label starts with one of these words")
    ap.add_argument("--json", help="write the rows to this JSON file")
    ap.add_argument("--figure", help="write the map of every track to this PNG file")
    args = ap.parse_args(argv)
    machine = calibrate(quick=True)
    print("machine  " + ", ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}" for k, v in machine.items()))
    runs = [(label, kind, parse_planner(t)) for label, kind, t in SETTINGS["quick" if args.quick else "full"]]
    if args.planners:
        runs = [r for r in runs if any(r[0].startswith(w) for w in args.planners)]
    print(f"load     {' '.join(f'{x:.1f}' for x in os.getloadavg())} (1, 5, 15 min; {os.cpu_count()} cores)")
    todo = courses()
    if args.only:
        todo = {k: v for k, v in todo.items() if any(w in k for w in args.only)}
    comparisons, rows = [], []
    for name, sc in todo.items():
        comp = compare_planners(sc, name=name, runs=runs, refine=2)  # type: ignore[arg-type]
        comparisons.append(comp)
        rows += comp.rows()
        print(table(comp.rows()), flush=True)
    print()
    print(table(rows))
    if args.json:
        load = os.getloadavg()
        Path(args.json).write_text(json.dumps({"machine": machine, "load": load, "rows": rows}, indent=1))
    if args.figure:
        from pyroute_rel.viz.planners import planners_map

        planners_map(comparisons).savefig(args.figure, dpi=110)
    return 0


if __name__ == "__main__":
    sys.exit(main())
