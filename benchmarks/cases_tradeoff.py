"""Benchmarks of the trade-off fronts (issue 20).

Claims under test, on the control course (``examples/microtransat_control.toml``, apf 1, default angular grid):

- the bottleneck front in under 5x one route;
- the voyage front in under 10x one route, with its labels per node.

"One route" is the scenario's route on a fresh grid, first in its process after loading (arc geometry computed); each
front is computed on another fresh grid of the same size, so neither profits from the other's cache. The voyage
cases record a refusal at the label cap (``LabelLimitError``) as a failed target, with the rank it stopped at and the
time it took to get there: the default grid needs 711 labels at one node, within the default cap of 1024
(``MAX_LABELS``); ``*_512`` shows the refusal at commercial routers' 512 (it passes when refused). ``*_40`` repeats
both fronts on 40 ranks.
"""

from __future__ import annotations

from pathlib import Path

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "microtransat_control.toml"

_CODE = """
from pyroute_rel.errors import LabelLimitError
from pyroute_rel.routing.route import route_on_grid
from pyroute_rel.routing.tradeoff import bottleneck_front, voyage_front
sc = load_scenario({path!r}).with_options(apf=1.0{extra})
sc.route()  # warm: the failure table, the land geometry
def one_route():
    g = sc.make_grid()
    return route_on_grid(g, sc.problem(grid=g))
def front():
    g = sc.make_grid()
    return {kind}_front(g, sc.problem(grid=g){kw})
t_route, _ = best_of(one_route, n=3)
out = {{"route_s": t_route}}
t0 = time.perf_counter()
try:  # once: a front takes several routes' time
    f = front()
    out.update(seconds=time.perf_counter() - t0, points=len(f.points), runs=f.runs, labels_mean=f.labels_mean,
               labels_max=f.labels_max)
except LabelLimitError as exc:
    out.update(seconds=time.perf_counter() - t0, refused=str(exc))
out["ratio"] = out["seconds"] / t_route
out["target_ratio"] = {target}
# a case that shows the refusal at a cap too small passes when it is refused
out["pass_ratio"] = ("refused" in out) if {refuse} else ("refused" not in out and out["ratio"] <= {target})
out["peak_rss_mb"] = rss_mb()
print(json.dumps(out))
"""

CASES = {
    "tradeoff_bottleneck_control": (
        _CODE.format(path=str(EXAMPLE), extra="", kind="bottleneck", kw="", target=5.0, refuse=False),
        None,
        "bottleneck front of the control course, default grid (issue 20: under 5x one route)",
    ),
    "tradeoff_voyage_control": (
        _CODE.format(path=str(EXAMPLE), extra="", kind="voyage", kw="", target=10.0, refuse=False),
        None,
        "voyage front of the control course, default grid, default label cap (issue 20: under 10x one route)",
    ),
    "tradeoff_voyage_control_512": (
        _CODE.format(path=str(EXAMPLE), extra="", kind="voyage", kw=", max_labels=512", target=10.0, refuse=True),
        None,
        "voyage front of the control course, default grid, 512 labels per node: passes when refused (it needs 711)",
    ),
    "tradeoff_bottleneck_control_40": (
        _CODE.format(path=str(EXAMPLE), extra=", n_ranks=40", kind="bottleneck", kw="", target=5.0, refuse=False),
        None,
        "bottleneck front of the control course on 40 ranks (5x one route)",
    ),
    "tradeoff_voyage_control_40": (
        _CODE.format(path=str(EXAMPLE), extra=", n_ranks=40", kind="voyage", kw="", target=10.0, refuse=False),
        None,
        "voyage front of the control course on 40 ranks (10x one route)",
    ),
}
