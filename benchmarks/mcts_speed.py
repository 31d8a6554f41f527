"""MCTS-UCT iterations per second: the compiled lattice engine against the Python reference (issue 22).

Run: ``python benchmarks/mcts_speed.py [--pairs N] [--python-iterations N] [--lattice-iterations N]``.

Both engines run the first decision of the control course (apf 1, 40-rank grid) with the published settings (8
headings, 1 h steps, C_p = 1/sqrt(2), rollouts until arrival or TimeMax), interleaved (Python, lattice, Python, ...)
so a drift of the machine's speed hits both; each prints its iterations per second, the medians and their ratio
follow. The lattice engine's one-off costs (sampling the lattice, numba's compilation or cache load) are done
before the timed runs and reported apart. The first line times fixed workloads (``benchmarks/run.py``'s
calibration) so runs on different days can be compared. Target (issue 22): 15 000 iterations per 1 h decision
over the control course's whole voyage in minutes.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))

from run import calibrate  # noqa: E402

from pyroute_rel import load_scenario  # noqa: E402
from pyroute_rel._kernels.mcts import search  # noqa: E402
from pyroute_rel.planners.base import PlanningProblem  # noqa: E402
from pyroute_rel.planners.mcts import kernel_inputs, python_decision, time_limits  # noqa: E402
from pyroute_rel.planners.mcts_lattice import build_lattice  # noqa: E402
from pyroute_rel.planners.settings import MCTSSettings  # noqa: E402


def python_rate(problem: PlanningProblem, iterations: int, seed: int) -> float:
    """Iterations per second of the Python engine's search of the first decision."""
    t0 = time.perf_counter()
    python_decision(problem, MCTSSettings(iterations=iterations, engine="python"), seed)
    return iterations / (time.perf_counter() - t0)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pairs", type=int, default=3)
    ap.add_argument("--python-iterations", type=int, default=3)
    ap.add_argument("--lattice-iterations", type=int, default=3000)
    args = ap.parse_args(argv)
    machine = calibrate(quick=True)
    print("machine  " + ", ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}" for k, v in machine.items()))
    sc = load_scenario(ROOT / "examples" / "microtransat_control.toml").with_options(n_ranks=40, apf=1.0)
    problem = PlanningProblem.of(sc)
    s = MCTSSettings()
    t0 = time.perf_counter()
    _, _, t_max = time_limits(problem, s)
    lattice = build_lattice(
        problem, np.arange(s.headings) * 45.0, spacing_deg=s.lattice_deg, slice_h=s.lattice_h, until_h=t_max + 1.0
    )
    hdg, tables, params = kernel_inputs(problem, s, lattice)
    built = time.perf_counter() - t0
    root = np.array([*problem.start, 0.0])
    args_k = (hdg, lattice.weather, lattice.okh, lattice.open, tables, params)
    t0 = time.perf_counter()
    search(root, 2, *args_k, np.random.SeedSequence(0).generate_state(2, dtype=np.uint64))
    print(f"lattice engine set-up: lattice {built:.2f} s, compile or cache load {time.perf_counter() - t0:.2f} s")
    py, lat = [], []
    for k in range(args.pairs):
        py.append(python_rate(problem, args.python_iterations, k))
        rng = np.random.SeedSequence(k).generate_state(2, dtype=np.uint64)
        t0 = time.perf_counter()
        search(root, args.lattice_iterations, *args_k, rng)
        lat.append(args.lattice_iterations / (time.perf_counter() - t0))
        print(f"pair {k}: python {py[-1]:.3f} it/s, lattice {lat[-1]:.1f} it/s", flush=True)
    mp, ml = statistics.median(py), statistics.median(lat)
    print(f"median: python {mp:.3f} it/s, lattice {ml:.1f} it/s, ratio {ml / mp:.0f}x")
    print(f"15 000 iterations of the first decision: python {15000 / mp / 3600:.1f} h, lattice {15000 / ml:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
