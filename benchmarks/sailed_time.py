"""Sailed time (issue 32): what the product reports against an independent continuous march.

Run: ``python benchmarks/sailed_time.py [--quick] [--json FILE]``.

Each row is a voyage as the product reports it (``evaluate`` or a route) next to the same track sailed continuously
by the tests' reference march (``tests/_march.py``: steps of at most 100 m and 0.05 h, the route's waits kept), on
the fields of ``tests/test_sailed_time.py``: the veering leg, the fronts, the ERA5 example (its data are made by
``examples/make_era5_example.py`` when missing) and the drifting storm at apf 0.5. The tests' tolerances are the
limits: 1 % on the veering leg, 0.2 % on routes; a row over its limit says so in its notes. The storm's notes give the
route's reported largest p_f, the largest p_f met along the marched track at the craft's times and how much of the
track [km] is above apf. ``--quick``: the veering leg, the fronts at 40 ranks and the ERA5 example at 40 ranks.
The first line names the machine and the versions; route runtimes are machine-dependent (the first route of the
process also loads the compiled kernels).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path

import numba
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
# The reference march and the tests' fields live in tests/, which is not a package: put it on the path so that the
# benchmark measures against the very march and fields that tests/test_sailed_time.py checks.
sys.path.insert(0, str(ROOT / "tests"))

from _march import march_track, route_leave_h  # noqa: E402
from test_sailed_time import (  # noqa: E402
    FRONTS_FINISH,
    FRONTS_START,
    STORM_FINISH,
    STORM_START,
    era5_scenario,
    fronts_weather,
    p_f_along,
    sailor,
    scenario,
    storm_weather,
    veering_weather,
)

from pyroute_rel import geodesy  # noqa: E402
from pyroute_rel.analysis.evaluate import evaluate_track  # noqa: E402
from pyroute_rel.reliability.failure import load_failure_model  # noqa: E402

ROUTE_LIMIT_PCT, VEERING_LIMIT_PCT = 0.2, 1.0


def row(case: str, reported, marched, limit_pct: float, notes: list[str], **extra) -> dict:
    """A table row: the voyage reported and marched [h], their difference [%] and the worst point's gap [h]."""
    reported, marched = np.asarray(reported, float), np.asarray(marched, float)
    diff = float(100.0 * (reported[-1] / marched[-1] - 1.0))
    worst = float(np.max(np.abs(reported - marched)))
    over = bool(abs(diff) > limit_pct)
    notes = ([f"**over {limit_pct:g} %**"] if over else []) + notes + [f"worst point {worst:.3f} h"]
    return {
        "case": case, "reported_h": float(reported[-1]), "marched_h": float(marched[-1]), "difference_pct": diff,
        "limit_pct": limit_pct, "over_limit": over, "worst_point_h": worst, "notes": "; ".join(notes), **extra,
    }  # fmt: skip


def routed(sc, *, record: bool = False):
    """Route ``sc`` (timed) and march its track continuously, leaving each node when the route does."""
    t0 = time.perf_counter()
    route = sc.route()
    runtime = time.perf_counter() - t0
    marched = march_track(
        sailor(sc), route.lon_deg, route.lat_deg, leave_h=route_leave_h(route), guess_h=route.elapsed_h, record=record
    )
    return route, marched, runtime


def veering() -> list[dict]:
    sc = scenario(veering_weather(), (0.0, 0.0), (-1.0, 0.0), n_ranks=4, half_width_km=30.0)
    marched = march_track(sailor(sc), [0.0, -1.0], [0.0, 0.0])
    ev = evaluate_track(sc, np.array([[0.0, 0.0], [-1.0, 0.0]]))
    route, times, runtime = routed(sc)
    return [
        row("veering leg: evaluate", ev.elapsed_h, marched, VEERING_LIMIT_PCT, []),
        row("veering leg: route, 4 ranks", route.elapsed_h, times, VEERING_LIMIT_PCT, [f"route {runtime:.2f} s"]),
    ]


def fronts(n_ranks: int) -> list[dict]:
    sc = scenario(fronts_weather(), FRONTS_START, FRONTS_FINISH, n_ranks=n_ranks, half_width_km=120.0)
    route, times, runtime = routed(sc)
    notes = [f"route {runtime:.2f} s"]
    return [row(f"fronts: route, {n_ranks} ranks", route.elapsed_h, times, ROUTE_LIMIT_PCT, notes, runtime_s=runtime)]


def era5(n_ranks: int, samples: int | None = None) -> list[dict]:
    sc = era5_scenario().with_options(n_ranks=n_ranks, samples_per_arc=samples)  # None: the default spacing
    route, times, runtime = routed(sc)
    k = route.problem.samples
    case = f"ERA5: route, {n_ranks} ranks" + (f", {samples} samples/arc" if samples else "")
    notes = [f"route {runtime:.2f} s", f"{k} samples/arc"]
    return [row(case, route.elapsed_h, times, ROUTE_LIMIT_PCT, notes, runtime_s=runtime, samples_per_arc=k)]


def storm() -> list[dict]:
    """The drifting storm at apf 0.5 (20 ranks): p_f met at every step of the marched track, at the marched times."""
    failure = {"model": "dickson2018", "apf": 0.5}
    sc = scenario(storm_weather(), STORM_START, STORM_FINISH, failure=failure, n_ranks=20, half_width_km=200.0)
    route, (times, path), runtime = routed(sc, record=True)
    p = p_f_along(sc, load_failure_model("dickson2018"), path, 0.0)
    same_leg = path.lane[1:] == path.lane[:-1]  # the path is leg by leg, each in time: a step is two points of a leg
    km = geodesy.distance_km(path.lon_deg[:-1], path.lat_deg[:-1], path.lon_deg[1:], path.lat_deg[1:])
    above_km = float(np.sum(km[same_leg & (p[:-1] > sc.apf)]))  # steps that start above apf
    reported, met = float(route.max_failure_probability), float(p.max())
    notes = [f"route {runtime:.2f} s", f"p_f reported {reported:.3g} / met {met:.3g}", f"{above_km:.2f} km > apf"]
    extra = {"runtime_s": runtime, "max_p_f_reported": reported, "max_p_f_met": met, "km_above_apf": above_km}
    return [row("storm: route, 20 ranks, apf 0.5", route.elapsed_h, times, ROUTE_LIMIT_PCT, notes, **extra)]


def machine() -> dict:
    return {
        "platform": platform.platform(), "python": platform.python_version(), "cores": os.cpu_count(),
        "numpy": np.__version__, "numba": numba.__version__,
    }  # fmt: skip


def table(rows: list[dict]) -> str:
    lines = ["| case | reported [h] | sailed continuously [h] | difference [%] | notes |", "|---|---:|---:|---:|---|"]
    for r in rows:
        figures = f"{r['reported_h']:.3f} | {r['marched_h']:.3f} | {r['difference_pct']:+.3f}"
        lines.append(f"| {r['case']} | {figures} | {r['notes']} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="the veering leg, fronts and ERA5 at 40 ranks only")
    ap.add_argument("--json", help="write the machine, the rows and the total runtime to this JSON file")
    args = ap.parse_args(argv)
    info = machine()
    print("machine  " + ", ".join(f"{k}={v}" for k, v in info.items()), flush=True)
    t0 = time.perf_counter()
    cases = [veering, lambda: fronts(40), lambda: era5(40)]
    if not args.quick:
        cases[2:2] = [lambda: fronts(80)]
        cases += [lambda: era5(80), lambda: era5(160), lambda: era5(80, 8), lambda: era5(80, 16), storm]
    rows = []
    for case in cases:
        rows += case()
        print(f"  {rows[-1]['case']}: done at {time.perf_counter() - t0:.0f} s", file=sys.stderr, flush=True)
    total = time.perf_counter() - t0
    print(table(rows))
    print(f"\ntotal {total:.1f} s")
    if args.json:
        Path(args.json).write_text(json.dumps({"machine": info, "rows": rows, "total_s": total}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
