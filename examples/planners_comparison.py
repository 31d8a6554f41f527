"""MCTS-UCT, tabular Q-learning and a DQN against the DP on the paper's control course at apf 0.5 (issue 22).

Run: ``python examples/planners_comparison.py [--out DIR | --figures]`` (about ten minutes, most of it the DQN's
training). Writes ``planners_control.png`` (a map of every track, labelled with the evaluator's voyage times) and
``planners_control.json`` (the table's rows). The full comparison on four courses is ``python benchmarks/planners.py``.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from output_options import add_output_options, output_folder

from pyroute_rel import load_scenario
from pyroute_rel.planners.compare import compare_planners
from pyroute_rel.planners.settings import parse_planner
from pyroute_rel.viz.planners import planners_map

HERE = Path(__file__).resolve().parent

#: Each planner's settings: those of the README's table (benchmarks/planners.py), except MCTS, cut down.
RUNS = [
    ("mcts", "mcts", {"mcts": {"iterations": 10, "step_h": 24.0, "rollout_h": 48.0}}),
    ("qlearning (graph)", "qlearning", {"qlearning": {"episodes": 100_000, "gamma": 1.0}}),
    ("qlearning (cells, published)", "qlearning", {"qlearning": {"space": "cells"}}),
    (
        "qlearning (60 nm cells)",
        "qlearning",
        {"qlearning": {"space": "cells", "cell_nm": 60.0, "cells_across": 21, "gamma": 1.0, "episodes": 100_000}},
    ),
    ("dqn", "dqn", {"dqn": {"episodes": 100, "step_h": 12.0}}),
]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_output_options(ap)
    args = ap.parse_args()
    out = output_folder(ap, args)
    sc = load_scenario(HERE / "microtransat_control.toml").with_options(n_ranks=40, apf=0.5)
    runs = [(label, kind, parse_planner(table)) for label, kind, table in RUNS]
    comp = compare_planners(sc, name="control course, apf 0.5", runs=runs, refine=2)
    for row in comp.rows():
        v = row["voyage_time_h"]
        print(f"{row['planner']:<18} {'did not arrive' if v is None else f'{v:8.2f} h'}  feasible {row['feasible']}")
    planners_map([comp], columns=1).savefig(out / "planners_control.png", dpi=110)
    (out / "planners_control.json").write_text(json.dumps(comp.rows(), indent=1))
    print(f"wrote {out / 'planners_control.png'}")


if __name__ == "__main__":
    main()
