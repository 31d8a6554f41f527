"""The failure model's judgements kept between DPs (:class:`pyroute_rel._kernels.dp.Judged`): cold and warm.

Run from the repository: ``python benchmarks/dp_judged.py [--n 160] [--apf 0.5] [--repeats 7]``. On the square grid
of ``dp_failure_model_160`` (``benchmarks/run.py``: the control example, no land, one sample per arc), after one DP
without a model (the arc geometry is then cached on the grid), it times, interleaved, ``--repeats`` times each:

- ``without_model_s``: the DP without a model (the yardstick);
- ``kept_nothing_s``: the DP with the model inside ``kept(False)``: every arc judged afresh, nothing kept;
- ``first_s``: the first DP with the model in a fresh store (``kept()``): judged afresh, the judgements kept;
- ``warm_s``: the next DP in that store, which takes them.

It prints one JSON object: the minimum and the median of each [s], and each over ``without_model_s`` (minima). The
store of a DP with the model is the process's only in ``warm_s`` (its first DP's fresh ``kept()`` block), so the
cold figures are first calls whatever ran before.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # this checkout's pyroute_rel, whatever copy is installed

from pyroute_rel.routing.solve import forward_dp  # noqa: E402
from pyroute_rel.scenario import load_scenario  # noqa: E402
from pyroute_rel.store import kept  # noqa: E402

EXAMPLE = ROOT / "examples" / "microtransat_control.toml"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=160, help="ranks and nodes of the square grid")
    ap.add_argument("--apf", type=float, default=0.5, help="acceptable probability of failure")
    ap.add_argument("--repeats", type=int, default=7, help="times each DP is timed (interleaved)")
    args = ap.parse_args()
    opts = dict(layout="square", n_ranks=args.n, n_nodes=args.n, land=False, samples_per_arc=1)
    grid = load_scenario(EXAMPLE).with_options(failure_model="none", **opts).make_grid()
    plain = load_scenario(EXAMPLE).with_options(failure_model="none", **opts).problem()
    model = load_scenario(EXAMPLE).with_options(apf=args.apf, **opts).problem()
    forward_dp(grid, plain)  # the arc geometry, cached on the grid, and the compiled kernels loaded
    with kept(False):
        forward_dp(grid, model)
    times: dict[str, list[float]] = {"without_model_s": [], "kept_nothing_s": [], "first_s": [], "warm_s": []}

    def timed(name: str, fn) -> None:  # type: ignore[no-untyped-def]
        t0 = time.perf_counter()
        fn()
        times[name].append(time.perf_counter() - t0)

    for _ in range(args.repeats):
        timed("without_model_s", lambda: forward_dp(grid, plain))
        with kept(False):
            timed("kept_nothing_s", lambda: forward_dp(grid, model))
        with kept():
            timed("first_s", lambda: forward_dp(grid, model))
            timed("warm_s", lambda: forward_dp(grid, model))
    base = min(times["without_model_s"])
    import pyroute_rel

    out: dict[str, float | int | str] = {"n": args.n, "apf": args.apf, "repeats": args.repeats}
    for name, ts in times.items():
        out[name] = min(ts)
        out[name.replace("_s", "_median_s")] = statistics.median(ts)
        if name != "without_model_s":
            out[name.replace("_s", "_ratio")] = min(ts) / base
    out["package"] = str(Path(pyroute_rel.__file__).parent)
    print(json.dumps(out))


if __name__ == "__main__":
    main()
