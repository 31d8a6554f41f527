"""Write a synthetic ensemble weather file (ERA5 layout with an ensemble dimension ``number``) and a scenario using it.

Used by the sweep benchmark (``benchmarks/sweep.py``) and the sweep tests. The weather is synthetic, not ECMWF
data: the veering trade wind of ``benchmarks/cases_gridded_weather.py`` with a member-dependent wind perturbation
and a storm of high waves (up to 5.5 m: beyond the 4 m of ``dickson2018``'s wave criterion) crossing the course
westward at a member-dependent time, so that members, departures and apf give different routes, and a strict apf
can leave no route. The output is deterministic.

Usage::

    python benchmarks/make_ensemble.py OUT_DIR [--members 10] [--step-deg 1.0] [--step-h 6] [--days 40]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

START = np.datetime64("2018-06-01T00:00", "ns")

SCENARIO = """# Microtransat East -> West over a synthetic ensemble (benchmarks/make_ensemble.py)
[route]
start = [-12.0, 45.0]
finish = [-60.0, 17.5]
departure = "2018-06-01T00:00:00Z"

[grid]
n_ranks = {n_ranks}

[boat]
polar = "maribot_vane"

[weather]
kind = "file"
paths = ["ensemble.nc"]
member = 0

[avoid]
land = false

[failure]
model = "dickson2018"
apf = 1.0
"""


def ensemble_dataset(*, members: int = 10, step_deg: float = 1.0, step_h: int = 6, days: int = 40) -> object:
    """The ensemble as an :class:`xarray.Dataset`: ``u10``, ``v10`` [m s**-1], ``swh`` [m], ``mwd`` [deg, from] on
    (number, time, latitude, longitude) over lon -70..0, lat 5..55 [deg]."""
    import xarray as xr

    lon = np.arange(-70.0, 0.0 + 1e-9, step_deg)
    lat = np.arange(5.0, 55.0 + 1e-9, step_deg)
    n_t = int(days * 24 // step_h) + 1
    time_ = START + np.arange(n_t) * np.timedelta64(step_h, "h")
    rng = np.random.default_rng(20181)
    phase = rng.uniform(0.0, 2.0 * np.pi, size=(members, 2))
    t = (np.arange(n_t, dtype=np.float64) * step_h)[None, :, None, None]  # [h]
    la = lat[None, None, :, None]
    lo = lon[None, None, None, :]
    p0 = phase[:, 0][:, None, None, None]
    p1 = phase[:, 1][:, None, None, None]
    speed = 6.0 + 2.0 * np.sin(t / 50.0) + 0.05 * (la - 5.0) + 1.5 * np.sin(t / 30.0 + p0 + lo / 20.0)  # [m/s]
    frm = np.radians(20.0 + 40.0 * np.sin(t / 120.0 + lo / 30.0 + p1))
    # a storm crossing westward along 33N, over the course at a member-dependent time
    centre = -10.0 - (t - 48.0 * p0) * 0.15  # [deg lon]
    storm = 4.5 * np.exp(-(((lo - centre) / 6.0) ** 2 + ((la - 33.0) / 5.0) ** 2))
    swh = 1.0 + 0.5 * speed / 6.0 + storm
    u10 = -speed * np.sin(frm)
    v10 = -speed * np.cos(frm)
    mwd = np.degrees(frm) % 360.0
    dims = ("number", "time", "latitude", "longitude")
    f32 = np.float32
    return xr.Dataset(
        {
            "u10": (dims, u10.astype(f32), {"units": "m s**-1"}),
            "v10": (dims, v10.astype(f32), {"units": "m s**-1"}),
            "swh": (dims, np.broadcast_to(swh, u10.shape).astype(f32), {"units": "m"}),
            "mwd": (dims, np.broadcast_to(mwd, u10.shape).astype(f32), {"units": "Degree true"}),
        },
        coords={"number": np.arange(members), "time": time_, "latitude": lat, "longitude": lon},
    )


def write_ensemble(out_dir: str | Path, *, n_ranks: int = 160, **kwargs: object) -> Path:
    """Write ``ensemble.nc`` and ``ensemble.toml`` (the scenario, ``[grid] n_ranks``) into ``out_dir``; returns
    the scenario's path."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    ds = ensemble_dataset(**kwargs)  # type: ignore[arg-type]
    enc = {v: {"zlib": True, "complevel": 1} for v in ds.data_vars}  # type: ignore[attr-defined]
    ds.to_netcdf(out / "ensemble.nc", encoding=enc)  # type: ignore[attr-defined]
    (out / "ensemble.toml").write_text(SCENARIO.format(n_ranks=n_ranks), encoding="utf-8")
    return out / "ensemble.toml"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out_dir")
    ap.add_argument("--members", type=int, default=10)
    ap.add_argument("--step-deg", type=float, default=1.0)
    ap.add_argument("--step-h", type=int, default=6)
    ap.add_argument("--days", type=int, default=40)
    a = ap.parse_args()
    print(write_ensemble(a.out_dir, members=a.members, step_deg=a.step_deg, step_h=a.step_h, days=a.days))


if __name__ == "__main__":
    main()
