"""Memory estimate vs measured peak. Run: ``python benchmarks/memory.py [--quick] [--only NAME ...] [--parts]``.

Each case routes a scenario in a fresh process: the child builds the grid and the routing problem, takes the
estimate of :func:`pyroute_rel.routing.solve.route_memory` (what :func:`~pyroute_rel.routing.solve.forward_dp` checks
against the budget), resets its high-water mark of resident memory (``/proc/self/clear_refs``: loading a gridded weather
file peaks before routing, and that peak is not the route's), routes, and reports; the parent reads the child's peak
resident memory from ``os.wait4``. The table shows estimate, measured peak and their ratio; the script exits 1 when a
ratio leaves [0.5, 2] (the estimate must be within 2x of the peak). The last columns leave out what the process held
when the estimate was made (interpreter, libraries, weather): the routing's own estimate and growth (memory freed
before, e.g. by loading weather, is reused without growing, so small growths understate). Memory is not timing: the
figures hardly depend on the machine's load.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
CONTROL = str(ROOT / "examples" / "microtransat_control.toml")
ERA5 = str(ROOT / "examples" / "microtransat_era5.toml")
REAL = str(ROOT / "examples" / "microtransat_real_course.toml")

#: name -> (scenario file, options of ``Scenario.with_options``)
CASES: dict[str, tuple[str, dict[str, Any]]] = {
    "square_80_s1": (CONTROL, {"layout": "square", "n_ranks": 80, "n_nodes": 80, "samples_per_arc": 1}),
    "square_80_s8": (CONTROL, {"layout": "square", "n_ranks": 80, "n_nodes": 80, "samples_per_arc": 8}),
    "square_80_s32": (CONTROL, {"layout": "square", "n_ranks": 80, "n_nodes": 80, "samples_per_arc": 32}),
    "square_160_s1": (CONTROL, {"layout": "square", "n_ranks": 160, "n_nodes": 160, "samples_per_arc": 1}),
    "square_160_s8": (CONTROL, {"layout": "square", "n_ranks": 160, "n_nodes": 160, "samples_per_arc": 8}),
    "square_240_s1": (CONTROL, {"layout": "square", "n_ranks": 240, "n_nodes": 240, "samples_per_arc": 1}),
    "square_240_s8_noland": (
        CONTROL,
        {"layout": "square", "n_ranks": 240, "n_nodes": 240, "samples_per_arc": 8, "land": False},
    ),
    "angular_default": (CONTROL, {}),
    "angular_default_noland": (CONTROL, {"land": False}),
    "angular_s8": (CONTROL, {"samples_per_arc": 8}),
    "angular_s32": (CONTROL, {"samples_per_arc": 32}),
    "angular_320_s8": (CONTROL, {"n_ranks": 320, "samples_per_arc": 8}),
    "time_expanded_wait": (CONTROL, {"time_step_h": 1.0, "max_wait_h": 12.0}),
    "era5_default": (ERA5, {}),
    "era5_square_160_s8": (ERA5, {"layout": "square", "n_ranks": 160, "n_nodes": 160, "samples_per_arc": 8}),
    "real_course_land_zone": (REAL, {}),
    "refine_3_apf05": (CONTROL, {"apf": 0.5, "refine": 3}),
    "square_160_s8_refine_3": (
        CONTROL,
        {"layout": "square", "n_ranks": 160, "n_nodes": 160, "samples_per_arc": 8, "refine": 3},
    ),
}
QUICK = ("square_80_s8", "angular_default", "era5_default")

CHILD = """
import json, sys
from pyroute_rel.scenario import load_scenario
from pyroute_rel.routing.solve import route_memory
path, options = sys.argv[1], json.loads(sys.argv[2])
sc = load_scenario(path).with_options(**options)
grid = sc.make_grid()
problem = sc.problem(grid=grid)
est = route_memory(grid, problem)
try:  # reset this process's high-water mark: VmHWM is then the peak of the routing alone
    with open("/proc/self/clear_refs", "w") as f:
        f.write("5")
    reset = True
except OSError:
    reset = False
route = sc.route(grids=[grid])
with open("/proc/self/status") as f:  # the high-water mark of this process's resident memory [KiB]
    hwm = next(int(line.split()[1]) * 1024 for line in f if line.startswith("VmHWM:"))
print(json.dumps({"estimate": est.total_bytes, "parts": est.parts, "what": est.what,
                  "voyage_h": route.voyage_time_h, "hwm": hwm, "reset": reset}))
"""


def measure(name: str) -> dict[str, Any]:
    """Route one case in a fresh process: its estimate and measured peak [bytes] (``os.wait4`` gives the child's own
    peak resident memory)."""
    path, options = CASES[name]
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    r, w = os.pipe()
    pid = os.fork()
    if pid == 0:  # child: run the case with stdout on the pipe
        os.close(r)
        os.dup2(w, 1)
        os.execve(sys.executable, [sys.executable, "-c", CHILD, path, json.dumps(options)], env)
    os.close(w)
    with os.fdopen(r) as f:
        out = f.read()
    _, status, usage = os.wait4(pid, 0)
    if status != 0:
        raise SystemExit(f"{name}: child exited with status {status}")
    result = json.loads(out)
    result["peak"] = usage.ru_maxrss * 1024  # [KiB] on Linux
    return result


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help=f"only {', '.join(QUICK)}")
    ap.add_argument("--only", nargs="+", choices=sorted(CASES), help="these cases")
    ap.add_argument("--parts", action="store_true", help="also print the estimate's parts [MiB]")
    args = ap.parse_args(argv)
    names = args.only or (list(QUICK) if args.quick else list(CASES))
    print(
        f"{'case':26s} {'grid':36s} {'estimate MiB':>12s} {'peak MiB':>9s} {'peak/est':>8s}   "
        f"{'routing est':>11s} {'routing peak':>12s} {'ratio':>6s}"
    )
    bad = 0
    for name in names:
        res = measure(name)
        ratio = res["peak"] / res["estimate"]
        ok = 0.5 <= ratio <= 2.0
        # the routing alone: the estimate less what the process held when it was made, and the peak less that
        added = res["estimate"] - res["parts"]["process"]
        grown = (res["hwm"] if res["reset"] else res["peak"]) - res["parts"]["process"]
        bad += not ok
        print(
            f"{name:26s} {res['what']:36s} {res['estimate'] / 2**20:12.0f} {res['peak'] / 2**20:9.0f} "
            f"{ratio:8.2f}   {added / 2**20:11.0f} {grown / 2**20:12.0f} {grown / added:6.2f}"
            f"{'' if ok else '  OUT OF [0.5, 2]'}",
            flush=True,
        )
        if args.parts:
            print("    " + ", ".join(f"{k} {v / 2**20:.0f}" for k, v in res["parts"].items()))
    return 1 if bad else 0


if __name__ == "__main__":
    raise SystemExit(main())
