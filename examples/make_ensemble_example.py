"""Write a small synthetic ensemble forecast laid out like an ERA5 ensemble NetCDF, for the ensemble example.

Dimensions ``number`` (the members), ``valid_time``, ``latitude`` (descending) and ``longitude``; variables
``u10``, ``v10`` [m s**-1], ``swh`` [m] and ``mwd`` [Degree true, from], packed in 16-bit integers (scale and
offset, as ERA5 NetCDF files are) and zlib-compressed.

The weather is synthetic: westerlies north of about 40°N, north-east trades south of about 30°N, and a low crossing
the domain eastward. Members differ as a forecast ensemble does, more with lead time: the low's track is displaced by
a random walk (each member its own direction, growing by :data:`SPREAD_DEG_PER_DAY` a day), its strength and the
westerlies' by a random factor growing likewise. Waves are a fully developed wind sea from the local wind
(``Hs = 0.0246 U**2``, Pierson-Moskowitz) coming from the wind's direction.

Usage::

    python examples/make_ensemble_example.py [--members 20] [--out examples/data/ensemble_synthetic.nc]

The output is deterministic (fixed seed) and takes about a second.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import xarray as xr

DEFAULT_OUT = Path(__file__).resolve().parent / "data" / "ensemble_synthetic.nc"
START = np.datetime64("2018-06-01T00:00", "ns")

#: Growth of the members' displacement of the low [deg per day of lead time].
SPREAD_DEG_PER_DAY = 0.6
#: Growth of the members' relative strength spread [per day of lead time].
STRENGTH_SPREAD_PER_DAY = 0.03


def make_ensemble(
    n_members: int = 20,
    *,
    seed: int = 1,
    days: float = 12.0,
    step_h: float = 6.0,
    resolution_deg: float = 1.0,
    lon: tuple[float, float] = (-40.0, 0.0),
    lat: tuple[float, float] = (20.0, 55.0),
    spread: float = 1.0,
) -> xr.Dataset:
    """The synthetic ensemble as an :class:`xarray.Dataset` (see the module notes).

    ``spread = 0`` gives identical members; ``seed`` chooses the members' perturbations.
    """
    rng = np.random.default_rng(seed)
    lons = np.arange(lon[0], lon[1] + 1e-9, resolution_deg)
    lats = np.arange(lat[1], lat[0] - 1e-9, -resolution_deg)  # descending, as ERA5
    hours = np.arange(0.0, days * 24.0 + 1e-9, step_h)
    t_days = hours / 24.0
    direction = rng.uniform(0.0, 2.0 * np.pi, n_members)
    size = np.abs(rng.normal(1.0, 0.5, n_members))
    strength = rng.normal(0.0, 1.0, n_members)
    westerly = rng.normal(0.0, 1.0, n_members)
    grow = spread * t_days[None, :]  # (member, time)
    d_lon = SPREAD_DEG_PER_DAY * grow * size[:, None] * np.cos(direction)[:, None]
    d_lat = SPREAD_DEG_PER_DAY * grow * size[:, None] * np.sin(direction)[:, None]
    k_low = 1.0 + STRENGTH_SPREAD_PER_DAY * grow * strength[:, None]
    k_west = 1.0 + 0.5 * STRENGTH_SPREAD_PER_DAY * grow * westerly[:, None]
    # the low: from 37N 30W, east at 2.5 deg a day
    c_lon = (-30.0 + 2.5 * t_days)[None, :] + d_lon
    c_lat = (37.0 - 0.2 * t_days)[None, :] + d_lat
    la = lats[None, None, :, None]
    lo = lons[None, None, None, :]
    dx = (lo - c_lon[:, :, None, None]) * np.cos(np.radians(la))
    dy = la - c_lat[:, :, None, None]
    r = np.hypot(dx, dy) + 1e-6
    radius = 4.0  # [deg]
    vt = 18.0 * k_low[:, :, None, None] * (r / radius) * np.exp(0.5 * (1.0 - (r / radius) ** 2))  # [m/s]
    u_low, v_low = -vt * dy / r, vt * dx / r  # counter-clockwise
    north = 0.5 * (1.0 + np.tanh((la - 38.0) / 4.0))
    u_base = (9.0 * north * k_west[:, :, None, None]) - 7.0 * (1.0 - north)
    v_base = -3.5 * (1.0 - north) + 0.0 * la
    u = (u_base + u_low).astype(np.float32)
    v = np.broadcast_to(v_base + v_low, u.shape).astype(np.float32)
    speed = np.hypot(u, v)
    swh = (0.3 + 0.0246 * speed**2).clip(0.0, 14.0).astype(np.float32)
    mwd = (np.degrees(np.arctan2(-u, -v)) % 360.0).astype(np.float32)
    dims = ("number", "valid_time", "latitude", "longitude")
    attrs = {
        "u10": {"units": "m s**-1", "long_name": "10 metre U wind component", "standard_name": "eastward_wind"},
        "v10": {"units": "m s**-1", "long_name": "10 metre V wind component", "standard_name": "northward_wind"},
        "swh": {"units": "m", "long_name": "Significant height of combined wind waves and swell"},
        "mwd": {"units": "Degree true", "long_name": "Mean wave direction"},
    }
    values = {"u10": u, "v10": v, "swh": swh, "mwd": mwd}
    return xr.Dataset(
        {name: (dims, values[name], attrs[name]) for name in values},
        coords={
            "number": ("number", np.arange(n_members), {"long_name": "ensemble member numerical id"}),
            "valid_time": START + (hours * 3600.0).astype("timedelta64[s]").astype("timedelta64[ns]"),
            "latitude": ("latitude", lats, {"units": "degrees_north", "standard_name": "latitude"}),
            "longitude": ("longitude", lons, {"units": "degrees_east", "standard_name": "longitude"}),
        },
        attrs={"title": "synthetic ensemble forecast for pyroute_rel's ensemble example (not ECMWF data)"},
    )


def write_ensemble(path: str | Path, n_members: int = 20, **options: object) -> Path:
    """Write :func:`make_ensemble` to a NetCDF file (packed in 16-bit integers as ERA5's are, zlib, one member per
    storage chunk as a GRIB file holds one field per member: reading one member decompresses that member only) and
    return its path."""
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    ds = make_ensemble(n_members, **options)  # type: ignore[arg-type]
    scale = {"u10": 0.002, "v10": 0.002, "swh": 0.001, "mwd": 0.01}  # [unit per count]
    offset = {"u10": 0.0, "v10": 0.0, "swh": 16.0, "mwd": 180.0}
    encoding = {
        name: {
            "zlib": True,
            "complevel": 4,
            "dtype": "int16",
            "_FillValue": -32767,
            "scale_factor": scale[name],
            "add_offset": offset[name],
            "chunksizes": (1, *ds[name].shape[1:]),
        }
        for name in ds.data_vars
    }
    ds.to_netcdf(out, encoding=encoding)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--members", type=int, default=20, help="number of members (default 20)")
    ap.add_argument("--out", default=str(DEFAULT_OUT), help=f"output file (default {DEFAULT_OUT})")
    args = ap.parse_args()
    print(write_ensemble(args.out, args.members))


if __name__ == "__main__":
    main()
