"""Throughput of sweeps (issue 18): 4 departures x 10 members x 3 apf x 2 grids = 240 routes over a gridded ensemble.

Run: ``python benchmarks/sweep.py [--quick] [--skip-dask] [--data DIR]``.

The ensemble is synthetic (``benchmarks/make_ensemble.py``: 10 members, 1 deg, 6-hourly, 40 days, written once into
``--data``, default ``benchmarks/.data/ensemble``); the scenario is the Microtransat course with the dickson2018
model, no land. The two grids are the default angular grid (160 ranks) and 80 ranks. Measured:

- ``inline``: the default engine, one process, wall time of ``run_sweep`` (importing, reading the weather once per
  member and grid, building the grids once, routing); target under 120 s.
- ``dask_1`` / ``dask_2``: a ``LocalCluster`` of 1 and 2 worker processes (one thread each), wall time from
  submitting to the last row, cluster start excluded; target ``dask_1 / dask_2`` >= 1.7.
- ``overhead``: the share of the inline sweep's route time spent outside the DPs (``forward_dp``, timed by
  wrapping it): reading the scenario, weather (cached), grids (cached), building the route's legs and its row;
  target under 30 %.

``--quick`` runs 2 departures x 3 members x 2 apf x 2 grids (24 routes), a smoke run whose targets are not judged.
Timings depend on the machine and its load: the first line is ``benchmarks/run.py``'s machine calibration.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def _module(name: str):
    spec = importlib.util.spec_from_file_location(name, ROOT / "benchmarks" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _spec_runs(scenario: Path, quick: bool):
    from pyroute_rel.sweep import sweep_from_mapping

    table = {
        "sweep": {
            "scenario": str(scenario),
            "departures": {"start": "2018-06-01T00:00Z", "end": f"2018-06-0{2 if quick else 4}T00:00Z", "step_h": 24},
            "members": [0, 1, 2] if quick else "all",
            "apf": [1.0, 0.02] if quick else [1.0, 0.2, 0.02],
            "grids": [{"n_ranks": 160}, {"n_ranks": 80}],
        }
    }
    return sweep_from_mapping(table, base_dir=scenario.parent).runs


def _inline(runs) -> dict:
    import pyroute_rel.route as route_module
    from pyroute_rel.sweep import run_sweep

    dp_s = [0.0]
    real = route_module.forward_dp

    def timed(*a, **k):
        t0 = time.perf_counter()
        try:
            return real(*a, **k)
        finally:
            dp_s[0] += time.perf_counter() - t0

    route_module.forward_dp = timed
    try:
        t0 = time.perf_counter()
        table = run_sweep(runs)
        wall = time.perf_counter() - t0
    finally:
        route_module.forward_dp = real
    rows = table.to_pylist()
    route_s = sum(r["runtime_s"] for r in rows)
    return {
        "runs": len(rows),
        "ok": sum(r["status"] == "ok" for r in rows),
        "no_route": sum(r["status"] == "no_route" for r in rows),
        "wall_s": wall,
        "route_s": route_s,
        "dp_s": dp_s[0],
        "overhead": 1.0 - dp_s[0] / route_s,
        "table": _comparable(rows),
    }


def _comparable(rows) -> list:
    return sorted((r["key"], r["status"], r["voyage_time_h"]) for r in rows)


def _dask(runs, workers: int) -> dict:
    from distributed import Client, LocalCluster, as_completed

    from pyroute_rel.sweep import run_key, run_one

    with LocalCluster(
        n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None,
        env={"PYROUTE_REL_THREADS": "1"},
    ) as cluster, Client(cluster) as client:  # fmt: skip
        client.run(lambda: __import__("pyroute_rel.sweep"))  # imports outside the timing, as a warm cluster
        keyed = [(run_key(r), r) for r in runs]
        t0 = time.perf_counter()
        futures = [client.submit(run_one, r, k, pure=False) for k, r in keyed]
        rows = [f.result() for f in as_completed(futures)]
        wall = time.perf_counter() - t0
    return {"workers": workers, "wall_s": wall, "table": _comparable(rows)}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="24 routes instead of 240; targets not judged")
    ap.add_argument("--skip-dask", action="store_true", help="only the inline engine")
    ap.add_argument("--data", default=str(ROOT / "benchmarks" / ".data" / "ensemble"), help="ensemble folder")
    args = ap.parse_args()
    machine = _module("run").calibrate(quick=True)
    print("machine  " + ", ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}" for k, v in machine.items()))
    data = Path(args.data)
    scenario = data / "ensemble.toml"
    if not scenario.is_file() or not (data / "ensemble.nc").is_file():
        t0 = time.perf_counter()
        _module("make_ensemble").write_ensemble(data)
        print(f"wrote {data}/ensemble.nc in {time.perf_counter() - t0:.1f} s")
    runs = _spec_runs(scenario, args.quick)
    inline = _inline(runs)
    report = {k: v for k, v in inline.items() if k != "table"}
    print("inline   " + json.dumps({k: round(v, 3) if isinstance(v, float) else v for k, v in report.items()}))
    ok = True
    if not args.quick:
        ok &= inline["wall_s"] < 120.0 and inline["overhead"] < 0.30
    if not args.skip_dask:
        one, two = _dask(runs, 1), _dask(runs, 2)
        same = one["table"] == two["table"] == inline["table"]
        speedup = one["wall_s"] / two["wall_s"]
        print(
            f"dask     1 worker {one['wall_s']:.1f} s, 2 workers {two['wall_s']:.1f} s: {speedup:.2f}x "
            f"(same table as inline: {same})"
        )
        ok &= same and (args.quick or speedup >= 1.7)
    print("(quick: targets not judged)" if args.quick else ("PASS" if ok else "FAIL"))
    return 0 if ok or args.quick else 1


if __name__ == "__main__":
    sys.exit(main())
