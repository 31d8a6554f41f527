"""Benchmark of routing over gridded, time-varying weather (issue: real weather).

A synthetic ERA5-layout field at 0.25 deg, hourly, 40 days over lon -70..0, lat 5..55 (u10, v10, swh, mwd; a
veering trade wind so the weather really varies), built in memory (file opening excluded), then the forward DP on
the paper's square 160 x 160 grid and on the default angular grid with the dickson2018 model. Target: under 3 s for
the DP and sampling, the first route in the process ("seconds"). Excluded, as file opening is: building the field
(and loading the compiled sampler, which GriddedWeather does on construction) and the grid's arc geometry, which is
computed once per grid whatever the weather and reported as "grid_geometry_s" ("first_with_geometry_s" adds it).
"""

BUILD = """
import xarray as xr
from dataclasses import replace
from pyroute_rel.weather.io.readers import weather_from_dataset
from pyroute_rel.weather.io.readers import GriddedWeather
from pyroute_rel.routing.grid import plan_grid
lon = np.arange(-70.0, 0.0001, 0.25); lat = np.arange(5.0, 55.0001, 0.25)
time_ = np.datetime64("2018-06-01T00") + np.arange(40 * 24) * np.timedelta64(1, "h")
t = np.arange(time_.size, dtype=np.float32)[:, None, None]
la = lat.astype(np.float32)[None, :, None]; lo = lon.astype(np.float32)[None, None, :]
speed = (6.0 + 2.0 * np.sin(t / 50.0) + 0.05 * (la - 5.0)).astype(np.float32)       # m/s
frm = np.radians(20.0 + 40.0 * np.sin(t / 120.0 + lo / 30.0)).astype(np.float32)     # from NNE, veering
u10 = (-speed * np.sin(frm)).astype(np.float32); v10 = (-speed * np.cos(frm)).astype(np.float32)
swh = (1.0 + 0.5 * speed / 6.0).astype(np.float32) * np.ones_like(u10)
mwd = np.degrees(frm).astype(np.float32) * np.ones_like(u10)
dims = ("time", "latitude", "longitude")
ds = xr.Dataset({"u10": (dims, u10, {"units": "m s**-1"}), "v10": (dims, v10, {"units": "m s**-1"}),
                 "swh": (dims, swh, {"units": "m"}), "mwd": (dims, mwd, {"units": "Degree true"})},
                coords={"time": time_, "latitude": lat, "longitude": lon})
del u10, v10, swh, mwd
t0 = time.perf_counter()
weather = weather_from_dataset(ds, source="synthetic 0.25 deg hourly 40 days")
build_s = time.perf_counter() - t0
del ds
sc = load_scenario(%r).with_options(land=False)
sc = replace(sc, weather=weather)
"""

CASES = {}
for _name, _layout, _prune in (
    ("weather_file_square_160", "square", True),
    ("weather_file_default_grid", "angular", True),
    ("weather_file_square_160_every_arc", "square", False),
):
    CASES[_name] = (
        "from pathlib import Path\nEXAMPLE = str(Path('examples/microtransat_control.toml').resolve())\n"
        + BUILD % "examples/microtransat_control.toml"
        + f"""
sc = sc.with_options(layout="{_layout}", prune={_prune})
grid = sc.make_grid()
problem = sc.problem(grid=grid)
from pyroute_rel.routing.solve import grid_geometry
t0 = time.perf_counter()
for k in range(grid.n_ranks + 1):  # the grid's arc geometry: computed once per grid, whatever the weather
    grid_geometry(grid, k, problem.samples)
geometry_s = time.perf_counter() - t0
t0 = time.perf_counter(); res = forward_dp(grid, problem); first = time.perf_counter() - t0
t, res = best_of(lambda: forward_dp(grid, problem), n=3)
print(json.dumps({{"seconds": first, "warm_seconds": t, "grid_geometry_s": geometry_s,
                  "first_with_geometry_s": first + geometry_s, "arcs": res.arcs_evaluated,
                  "samples_per_arc": problem.samples, "arcs_per_s": res.arcs_evaluated / t, "voyage_h": res.finish_h,
                  "field_build_s": build_s, "weather_mb": weather.nbytes / 2**20, "peak_rss_mb": rss_mb()}}))
""",
        3.0,
        f"160-rank route ({_layout} grid{'' if _prune else ', prune = false: every arc costed'}) over a 0.25 deg "
        "hourly 40-day "
        "ERA5-layout field, dickson2018, DP + sampling (field build excluded; target under 3 s)",
    )
