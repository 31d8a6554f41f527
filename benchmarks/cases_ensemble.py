"""Benchmarks of issue 19: ensemble routing and Monte-Carlo evaluation.

``ensemble_51_members_default_grid``: a synthetic 51-member ensemble file (``examples/make_ensemble_example.py``: ERA5
ensemble layout, 1 deg, 6-hourly, 16 days, written to a temporary folder, excluded), then ``route_ensemble`` on the
default grid (160 ranks, angular) with the dickson2018 model: every member and the ensemble mean routed on 2 worker
processes, and the 52 candidates sailed in the 51 members. Target (issue 19): under 30 s on 2 cores.

``monte_carlo_1000_runs_160_legs``: 1000 Monte-Carlo runs of a 160-leg track over a time-varying gridded field (one
member of the same file; loading excluded). Target: under 1 s.
"""

MAKE = """
import importlib.util, tempfile
from pathlib import Path
spec = importlib.util.spec_from_file_location("make_ens", "examples/make_ensemble_example.py")
make = importlib.util.module_from_spec(spec); spec.loader.exec_module(make)
folder = Path(tempfile.mkdtemp())
make.write_ensemble(folder / "ens.nc", 51, days=16.0, lon=(-45.0, 0.0), lat=(12.0, 50.0))
(folder / "ens.toml").write_text('[route]\\nstart = [-14.0, 31.0]\\nfinish = [-26.0, 22.0]\\n'
    'departure = "2018-06-01T00:00:00Z"\\n[weather]\\nkind = "file"\\npaths = ["ens.nc"]\\n'
    '[failure]\\nmodel = "dickson2018"\\napf = 0.5\\n')
path = folder / "ens.toml"
"""

CASES = {
    "ensemble_51_members_default_grid": (
        MAKE
        + """
from pyroute_rel.ensemble import route_ensemble
t0 = time.perf_counter()
res = route_ensemble(path, workers=2, risk="cvar:0.9")
t = time.perf_counter() - t0
s = res.summary()
from pyroute_rel.members import member_scenario
grid = member_scenario(path, 0).make_grid()
print(json.dumps({"seconds": t, "members": len(res.members), "candidates": len(res.names),
                  "ranks": grid.n_ranks, "nodes": grid.n_nodes, "chosen": s["chosen"]["name"],
                  "peak_rss_mb": rss_mb()}))
""",
        30.0,
        "51 members + the ensemble mean routed on the default grid (2 processes) and the 52 x 51 re-evaluation "
        "(issue 19: under 30 s on 2 cores)",
    ),
    "monte_carlo_1000_runs_160_legs": (
        MAKE
        + """
from pyroute_rel.members import member_scenario
from pyroute_rel.monte_carlo import monte_carlo
sc = member_scenario(path, 0)
track = np.column_stack([np.linspace(-14.0, -26.0, 161), np.linspace(31.0, 22.0, 161)])
monte_carlo(sc, track, runs=10, seed=0)  # warm: the compiled kernels
t, res = best_of(lambda: monte_carlo(sc, track, runs=1000, seed=0), n=3)
print(json.dumps({"seconds": t, "runs": res.n_runs, "legs": 160, "mean_h": float(np.mean(res.voyage_time_h)),
                  "peak_rss_mb": rss_mb()}))
""",
        1.0,
        "1000 Monte-Carlo runs of a 160-leg track over a time-varying gridded member (issue 19: under 1 s)",
    ),
}
