"""Throughput of sweeps (issue 18): 4 departures x 10 members x 3 apf x 2 grids = 240 routes over a gridded ensemble.

Run: ``python benchmarks/sweep.py [--quick] [--members N] [--skip-dask] [--data DIR]``.

The ensemble is synthetic (``benchmarks/make_ensemble.py``: 10 members, 1 deg, 6-hourly, 40 days, written once into
``--data``, default ``benchmarks/.data/ensemble``); the scenario is the Microtransat course with the dickson2018
model, no land. The two grids are the default angular grid (160 ranks) and 80 ranks. Measured:

- ``default``: ``run_sweep`` with its default engine (``"auto"``: on 2 or more CPUs a local pool of one process
  per CPU), wall time (starting the pool, importing and reading the weather once per member in a worker,
  building the grids, routing), CPU time [s] per route (user + sys of this process and its workers), the weather
  files each worker read (counted in the workers: the table's metadata) and how many members were read by more
  than one worker; target under 120 s.
- ``overhead``: the runs of the first two members routed in this process (``engine="inline"``), the share of their
  route time spent outside the DPs (``forward_dp``, timed by wrapping it): reading the scenario, weather (cached:
  read once per member, as in the whole sweep), grids (cached), building the route's legs and its row; target
  under 30 %.
- ``dask_1`` / ``dask_2``: a ``LocalCluster`` of 1 and 2 worker processes (one thread each, the sweep's
  ``WORKER_ENV``), started and warmed (imports) before the clock starts; wall time of ``run_sweep(...,
  scheduler=...)``, the workers' CPU time per route and the weather files each worker read (one per member when
  each member's tasks stay on one worker); target ``dask_1 / dask_2`` >= 1.7 (with an idle core each).

``--quick`` runs 2 departures x 3 members x 2 apf x 2 grids (24 routes), a smoke run whose targets are not judged;
``--members N`` routes the first N members only (24 routes each; targets not judged below 10). Timings depend on the
machine and its load: the first line is ``benchmarks/run.py``'s machine calibration, and the load average (1 min)
is printed before and after.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
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


def _spec_runs(scenario: Path, quick: bool, members: int | None):
    from pyroute_rel.batch.sweep import sweep_from_mapping

    table = {
        "sweep": {
            "scenario": str(scenario),
            "departures": {"start": "2018-06-01T00:00Z", "end": f"2018-06-0{2 if quick else 4}T00:00Z", "step_h": 24},
            "members": [0, 1, 2] if quick else ("all" if members is None else list(range(members))),
            "apf": [1.0, 0.02] if quick else [1.0, 0.2, 0.02],
            "grids": [{"n_ranks": 160}, {"n_ranks": 80}],
        }
    }
    return sweep_from_mapping(table, base_dir=scenario.parent).runs


def _cpu_s(who: int) -> float:
    import resource

    r = resource.getrusage(who)
    return r.ru_utime + r.ru_stime


class _TreeCpu:
    """CPU time [s] (user + sys) of this process and every process started under it (the pool's workers are
    children of the forkserver, which is never waited for, so RUSAGE_CHILDREN misses them): the descendants are
    polled every 0.2 s and each one's last reading summed (a worker's last 0.2 s before it exits may be missed)."""

    def __init__(self) -> None:
        import threading

        import psutil

        self.me, self.seen, self.stop = psutil.Process(), {}, threading.Event()
        self.thread = threading.Thread(target=self._poll, daemon=True)

    def _poll(self) -> None:
        import psutil

        while not self.stop.wait(0.2):
            for p in self.me.children(recursive=True):
                try:
                    t = p.cpu_times()
                    self.seen[p.pid] = t.user + t.system
                except psutil.Error:
                    pass

    def __enter__(self) -> _TreeCpu:
        self.start = self.me.cpu_times()
        self.before = {p.pid for p in self.me.children(recursive=True)}
        self.thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self.stop.set()
        self.thread.join()
        end = self.me.cpu_times()
        mine = (end.user + end.system) - (self.start.user + self.start.system)
        self.cpu_s = mine + sum(v for pid, v in self.seen.items() if pid not in self.before)


def _default(runs) -> dict:
    from pyroute_rel.batch.sweep import auto_engine, run_sweep

    with _TreeCpu() as tree:
        t0 = time.perf_counter()
        table = run_sweep(runs)
        wall = time.perf_counter() - t0
    cpu = tree.cpu_s
    rows = table.to_pylist()
    engine, workers = auto_engine(len(runs))
    return {
        "engine": engine,
        "workers": workers,
        "runs": len(rows),
        "ok": sum(r["status"] == "ok" for r in rows),
        "no_route": sum(r["status"] == "no_route" for r in rows),
        "wall_s": wall,
        "cpu_s_per_route": cpu / len(rows),
        **_reads(table),
        "table": _comparable(rows),
    }


def _reads(table) -> dict:
    """The weather files each worker process read (the table's metadata, counted in the workers), sorted, and how
    many members more than one worker read."""
    from pyroute_rel.batch.sweep import READS_METADATA

    reads = json.loads((table.schema.metadata or {}).get(READS_METADATA.encode(), b"[]"))
    per_worker, readers = {}, {}
    for r in reads:
        per_worker[r["worker"]] = per_worker.get(r["worker"], 0) + r["reads"]
        if r["reads"]:
            readers.setdefault((r["scenario"], r["member"]), set()).add(r["worker"])
    shared = sum(len(w) > 1 for w in readers.values())
    return {"weather_reads": sorted(per_worker.values()), "members_read_twice": shared}


def _inline(runs) -> dict:
    import pyroute_rel.routing.route as route_module
    from pyroute_rel.batch.sweep import run_sweep

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
        table = run_sweep(runs, engine="inline")
        wall = time.perf_counter() - t0
    finally:
        route_module.forward_dp = real
    rows = table.to_pylist()
    route_s = sum(r["runtime_s"] for r in rows)
    return {
        "runs": len(rows),
        "wall_s": wall,
        "route_s": route_s,
        "dp_s": dp_s[0],
        "overhead": 1.0 - dp_s[0] / route_s,
        "table": _comparable(rows),
    }


def _comparable(rows) -> list:
    return sorted((r["key"], r["status"], r["voyage_time_h"]) for r in rows)


def _warm() -> str:
    """Run on each dask worker before the clock starts: the imports. Returns a string (a module cannot be sent
    back: cloudpickle refuses the package's module object)."""
    import pyroute_rel.batch.sweep

    return pyroute_rel.batch.sweep.__name__


def _worker_cpu_s() -> float:
    import resource

    return _cpu_s(resource.RUSAGE_SELF)


def _weather_reads() -> int:
    """Run on each dask worker after the sweep: how many weather files it read (the weather cache's misses)."""
    from pyroute_rel.weather import cache

    return int(cache.stats()["misses"])


def _dask(runs, workers: int) -> dict:
    from distributed import Client, LocalCluster

    from pyroute_rel.batch.sweep import WORKER_ENV, run_sweep

    with LocalCluster(
        n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None, env=dict(WORKER_ENV)
    ) as cluster, Client(cluster) as client:  # fmt: skip
        client.run(_warm)  # imports outside the timing, as a warm cluster
        cpu0 = sum(client.run(_worker_cpu_s).values())
        t0 = time.perf_counter()
        table = run_sweep(runs, engine="dask", scheduler=cluster.scheduler_address)
        wall = time.perf_counter() - t0
        cpu = sum(client.run(_worker_cpu_s).values()) - cpu0
        reads = sorted(client.run(_weather_reads).values())
    rows = table.to_pylist()
    return {
        "workers": workers,
        "wall_s": wall,
        "cpu_s_per_route": cpu / len(rows),
        "weather_reads": reads,
        "table": _comparable(rows),
    }


def _show(name: str, report: dict) -> None:
    shown = {k: round(v, 3) if isinstance(v, float) else v for k, v in report.items() if k != "table"}
    print(f"{name:<9}" + json.dumps(shown), flush=True)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="24 routes instead of 240; targets not judged")
    ap.add_argument("--members", type=int, help="only the first N members (24 routes each); targets not judged")
    ap.add_argument("--skip-dask", action="store_true", help="only the default engine and the overhead")
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
    runs = _spec_runs(scenario, args.quick, args.members)
    judged = not args.quick and args.members is None
    print(f"load     {os.getloadavg()[0]:.2f} (1 min average, {os.cpu_count()} cores)", flush=True)
    default = _default(runs)
    _show("default", default)
    subset = [r for r in runs if r.member in (0, 1)]
    inline = _inline(subset)
    _show("overhead", inline)
    same = sorted(set(inline["table"]) - set(default["table"])) == []
    ok = same
    if judged:
        ok &= default["wall_s"] < 120.0 and inline["overhead"] < 0.30
    if not args.skip_dask:
        one, two = _dask(runs, 1), _dask(runs, 2)
        same &= one["table"] == two["table"] == default["table"]
        speedup = one["wall_s"] / two["wall_s"]
        _show("dask_1", one)
        _show("dask_2", two)
        print(f"dask     1 worker {one['wall_s']:.1f} s, 2 workers {two['wall_s']:.1f} s: {speedup:.2f}x", flush=True)
        ok &= same and (not judged or speedup >= 1.7)
    print(f"load     {os.getloadavg()[0]:.2f}; same table from every engine: {same}")
    print("PASS" if ok else "FAIL" if judged else "(targets not judged)")
    return 0 if ok or not judged else 1


if __name__ == "__main__":
    sys.exit(main())
