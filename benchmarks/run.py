"""Benchmarks of pyroute_rel's hot paths. Run: ``python benchmarks/run.py [--quick] [--only NAME ...]``.

``--quick`` runs only :data:`QUICK_CASES` (four cases of a few seconds each, 10-20 s in all) and times
each workload once instead of the best of 3 (7 interleaved pairs: 3): a smoke run and a rough figure, noisier than
a full run.

Each case runs in a fresh subprocess so that its peak memory (max RSS) is its own. Targets come from the
issues; a case prints PASS/FAIL against its target, and the script exits non-zero if any target is missed
(timings are machine-dependent: this is a benchmark, not a unit test, and CI does not run it). The first line
times fixed workloads (``machine ...``), so runs on days when the machine is faster or slower can be compared.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "microtransat_control.toml"

CASES: dict[str, tuple[str, float | None, str]] = {}


def case(name: str, target_s: float | None, what: str):
    def deco(code: str) -> str:
        CASES[name] = (textwrap.dedent(code), target_s, what)
        return code

    return deco


#: The cases ``--quick`` runs: each a few seconds, together the DP, a default route and the obstacle checks.
QUICK_CASES = ("dp_all_to_all_80", "dp_all_to_all_160", "default_route_apf1", "obstacles_angular_160_land")

#: Runs before every case (``QUICK`` is set in front of it: True with ``--quick``).
PRELUDE = """
import json, resource, time, sys
import numpy as np
from pyroute_rel.scenario import load_scenario
from pyroute_rel.routing.solve import forward_dp
def rss_mb():
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
def repeats(n):
    return 1 if QUICK else n
def best_of(fn, n=3):
    n = repeats(n)
    ts = []
    for _ in range(n):
        t0 = time.perf_counter(); out = fn(); ts.append(time.perf_counter() - t0)
    return min(ts), out
"""

for n in (80, 160, 320):
    case(
        f"dp_all_to_all_{n}",
        1.0 if n == 160 else None,
        f"paper's square all-to-all grid {n}x{n}, apf 1, DP + arc costs (issue 2: 160x160 under 1 s)",
    )(f"""
sc = load_scenario({str(EXAMPLE)!r}).with_options(layout="square", n_nodes={n}, n_ranks={n}, failure_model="none",
                                                  land=False, samples_per_arc=1)
grid = sc.make_grid(); problem = sc.problem()
t0 = time.perf_counter(); forward_dp(grid, problem); cold = time.perf_counter() - t0  # + arc geometry, cached
t, res = best_of(lambda: forward_dp(grid, problem), n=3 if {n} <= 160 else 1)
print(json.dumps({{"seconds": t, "cold_seconds": cold, "arcs": res.arcs_evaluated, "arcs_per_s": res.arcs_evaluated / t,
                  "peak_rss_mb": rss_mb(), "voyage_h": res.finish_h}}))
""")

case(
    "dp_failure_model_160",
    None,
    "160x160 with the dickson2018 failure model at apf 0.5 (issue 3: at most 1.5x the time without)",
)(f"""
sc0 = load_scenario({str(EXAMPLE)!r}).with_options(layout="square", failure_model="none", land=False, samples_per_arc=1)
sc1 = load_scenario({str(EXAMPLE)!r}).with_options(layout="square", apf=0.5, land=False, samples_per_arc=1)
g = sc0.make_grid(); p0 = sc0.problem(); p1 = sc1.problem()
forward_dp(g, p0); forward_dp(g, p1)  # warm: arc geometry and the compiled table are cached
a, b = [], []
for _ in range(3 if QUICK else 7):  # interleaved, so that a slow spell of the machine hits both sides alike
    t_ = time.perf_counter(); r0 = forward_dp(g, p0); a.append(time.perf_counter() - t_)
    t_ = time.perf_counter(); r1 = forward_dp(g, p1); b.append(time.perf_counter() - t_)
t0, t1 = min(a), min(b)
pair = sorted(y / x for x, y in zip(a, b))[len(a) // 2]
print(json.dumps({{"seconds": t1, "without_model_s": t0, "ratio": t1 / t0, "median_pair_ratio": pair,
                  "arcs_per_s": r1.arcs_evaluated / t1, "peak_rss_mb": rss_mb(), "voyage_h": r1.finish_h,
                  "target_ratio": 1.5, "pass_ratio": t1 / t0 <= 1.5}}))
""")

for _apf in (1.0, 0.95, 0.5):
    case(
        f"default_route_apf{_apf:g}",
        2.0,
        f"default route of the example at apf {_apf:g} (angular grid, land on, failure model): load + route, "
        "first in the process (issue 8: under 2 s each)",
    )(f"""
t0 = time.perf_counter()
sc = load_scenario({str(EXAMPLE)!r}).with_options(apf={_apf})
route = sc.route()
cold = time.perf_counter() - t0
grid = route.grid
problem = sc.problem(grid=grid)
t, res = best_of(lambda: forward_dp(grid, problem))
print(json.dumps({{"seconds": cold, "warm_dp_seconds": t, "arcs": res.arcs_evaluated,
                  "arcs_per_s": res.arcs_evaluated / t, "voyage_h": route.voyage_time_h, "peak_rss_mb": rss_mb()}}))
""")

case(
    "no_clipping_square_81_apf0.95",
    None,
    "issue 16 item 2: the paper's square 81 x 81 grid at apf 0.95, arcs judged on every piece they cross (route "
    "time, and the voyage against the independent reference router's 778.852 h)",
)(f"""
sc = load_scenario({str(EXAMPLE)!r}).with_options(apf=0.95, layout="square", n_ranks=81, n_nodes=81)
t, route = best_of(lambda: sc.route())
print(json.dumps({{"seconds": t, "voyage_h": route.voyage_time_h, "reference_h": 778.852,
                  "error_pct": 100 * (route.voyage_time_h / 778.852 - 1), "peak_rss_mb": rss_mb()}}))
""")

case(
    "refine_default_route",
    None,
    "default route of the example at apf 1 refined in five corridors (--refine 5): extra time and voyage gain",
)(f"""
from dataclasses import replace
sc = load_scenario({str(EXAMPLE)!r}).with_options(apf=1.0)
sc.route()  # warm: failure table, land
t_plain, plain = best_of(lambda: sc.route())
ref = replace(sc, refine=5)
t_ref, refined = best_of(lambda: ref.route())
lv = refined.meta["refine"]["levels"]
print(json.dumps({{"seconds": t_ref, "plain_s": t_plain, "extra_s": t_ref - t_plain,
                  "per_level_s": (t_ref - t_plain) / len(lv), "arcs_refine": sum(x["arcs_evaluated"] for x in lv),
                  "voyage_h_grid": plain.voyage_time_h, "voyage_h_refined": refined.voyage_time_h,
                  "peak_rss_mb": rss_mb()}}))
""")

case(
    "gci_study_square_five_grids",
    30.0,
    "the paper's five-grid square GCI study (41, 57, 81, 115, 161 nodes), apf 1, no land (issue: under 30 s)",
)(f"""
from pyroute_rel.gci.study import run_study, square_levels
sc = load_scenario({str(EXAMPLE)!r}).with_options(apf=1.0, land=False)
t0 = time.perf_counter()
st = run_study(sc, square_levels([41, 57, 81, 115, 161]))
dt = time.perf_counter() - t0
print(json.dumps({{"seconds": dt, "grids": len(st.rows), "convergence": st.study.finest.convergence,
                  "peak_rss_mb": rss_mb()}}))
""")

case("bbn_table_vs_pgmpy", None, "compiled failure table vs one pgmpy VariableElimination query per arc")("""
from pyroute_rel.reliability.failure import load_failure_model
m = load_failure_model("dickson2018")
rng = np.random.default_rng(0)
q = {"hs_m": rng.uniform(0, 6, 1_000_000), "awd_deg": rng.uniform(0, 180, 1_000_000)}
t_gather, _ = best_of(lambda: m.p_fail(q))
from pgmpy.inference import VariableElimination
from pyroute_rel.reliability.failure import build_network
net = build_network(m)
ve = VariableElimination(net)
nodes = [c.node for c in m.criteria]
t0 = time.perf_counter(); nq = 200
for i in range(nq):
    ev = {c.node: c.states[i % len(c.states)] for c in m.criteria}
    ve.query([m.target], evidence=ev, show_progress=False)
t_query = (time.perf_counter() - t0) / nq
per_arc = t_gather / 1_000_000
print(json.dumps({"seconds": t_gather, "per_arc_gather_s": per_arc, "per_query_pgmpy_s": t_query,
                  "speedup": t_query / per_arc, "pass_ratio": t_query / per_arc >= 1000, "peak_rss_mb": rss_mb()}))
""")


def _load_case_files() -> None:
    """Cases also live in ``benchmarks/cases_*.py``: each defines ``CASES = {name: (code, target_s, what)}``
    (``code`` runs after :data:`PRELUDE` in a fresh interpreter and prints one JSON object whose ``seconds`` is
    compared with ``target_s``; an optional boolean ``pass_ratio`` must also hold)."""
    import importlib.util

    for path in sorted(Path(__file__).parent.glob("cases_*.py")):
        spec = importlib.util.spec_from_file_location(path.stem, path)
        assert spec is not None and spec.loader is not None
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
        for name, (code, target, what) in mod.CASES.items():
            CASES[name] = (textwrap.dedent(code), target, what)


def run_case(name: str, *, quick: bool = False) -> dict:
    """Run one case in a fresh interpreter (``quick``: each workload timed once); its JSON result with ``pass``."""
    code, target, what = CASES[name]
    program = f"QUICK = {quick}\n" + PRELUDE + code
    proc = subprocess.run([sys.executable, "-c", program], capture_output=True, text=True, cwd=ROOT)
    if proc.returncode != 0:
        return {"name": name, "error": proc.stderr.strip().splitlines()[-1] if proc.stderr else "failed"}
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    out["name"], out["what"], out["target_s"] = name, what, target
    ok = out.get("pass_ratio", True)
    if target is not None:
        ok = ok and out["seconds"] <= target
    out["pass"] = bool(ok)
    return out


_CALIBRATION = """
import json, os, time
import numpy as np, shapely
def best(fn, n=5):
    n = 2 if QUICK else n
    ts = []
    for _ in range(n):
        t0 = time.perf_counter(); fn(); ts.append(time.perf_counter() - t0)
    return min(ts)
x = np.random.default_rng(0).random(2_000_000)
a = np.linspace(0, 2 * np.pi, 40_000)
r = 1 + 0.05 * np.sin(997 * a)
wiggly = shapely.Polygon(np.column_stack([np.cos(a) * r, np.sin(a) * r]))
print(json.dumps({"cores": os.cpu_count(),
                  "numpy_sort_s": best(lambda: np.sort(x)),
                  "python_loop_s": best(lambda: sum(i * i for i in range(1_000_000))),
                  "geos_buffer_s": best(lambda: shapely.buffer(wiggly, 0.002, quad_segs=8))}))
"""


def calibrate(*, quick: bool = False) -> dict:
    """Time fixed workloads (numpy sort of 2 M floats, a 1 M-step Python loop, a GEOS buffer of a wiggly 40,000-vertex
    ring), so figures from different days of this machine, whose speed drifts, can be compared (best of 5; 2 with
    ``quick``)."""
    program = f"QUICK = {quick}\n" + _CALIBRATION
    proc = subprocess.run([sys.executable, "-c", program], capture_output=True, text=True, cwd=ROOT)
    if proc.returncode != 0:
        return {"error": proc.stderr.strip().splitlines()[-1] if proc.stderr else "failed"}
    return json.loads(proc.stdout.strip().splitlines()[-1])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--only", nargs="*", help="case names (default: all; with --quick: the quick cases)")
    ap.add_argument(
        "--quick",
        action="store_true",
        help=f"a smoke run: only {', '.join(QUICK_CASES)} (unless --only), each workload timed once",
    )
    ap.add_argument("--json", action="store_true", help="print one JSON list")
    args = ap.parse_args()
    _load_case_files()
    names = args.only or (list(QUICK_CASES) if args.quick else list(CASES))
    unknown = [n for n in names if n not in CASES]
    if unknown:
        print(f"benchmarks/run.py: unknown case {unknown[0]!r}; known: {', '.join(CASES)}", file=sys.stderr)
        return 2
    machine = calibrate(quick=args.quick)
    if not args.json:
        shown = (f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}" for k, v in machine.items())
        print("machine  " + ", ".join(shown))
    results = []
    for name in names:
        r = run_case(name, quick=args.quick)
        results.append(r)
        if not args.json:
            if "error" in r:
                print(f"{name:28s} ERROR {r['error']}")
                continue
            extra = ", ".join(
                f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}"
                for k, v in r.items()
                if k not in ("name", "what", "pass", "target_s")
            )
            verdict = "PASS" if r["pass"] else "FAIL"
            print(f"{name:28s} {verdict}  {extra}\n{'':28s} ({r['what']})")
    if args.json:
        print(json.dumps({"machine": machine, "cases": results}, indent=1))
    return 0 if all(r.get("pass", False) for r in results) else 1


if __name__ == "__main__":
    sys.exit(main())
