"""Write a small synthetic weather file laid out like an ERA5 NetCDF download, for the Microtransat example.

The file imitates what the Copernicus Climate Data Store returns for ERA5 single levels (NetCDF):
dimensions ``valid_time`` (seconds since 1970), ``latitude`` (descending, 55 -> 5) and ``longitude``
(-70 -> 0), a scalar ensemble coordinate ``number``, variables ``u10``, ``v10`` [m s**-1], ``swh`` [m],
``mwd`` [Degree true, from] and ``pp1d`` [s] with ERA5's ``units``/``long_name`` and CF ``standard_name``,
float32, zlib-compressed, waves NaN over (crudely drawn) land as in the ERA5 wave model.

The weather is synthetic, not ECMWF data: north-east trades south of ~30°N, westerlies further north,
an Azores high drifting about 35°N 35°W, a low every five days crossing the North Atlantic eastward and
easterly waves moving west in the trades, so the best route depends on the departure time. Waves are
a wind sea grown from the local wind plus a north-westerly swell in the north.

Usage::

    python examples/make_era5_example.py [--out examples/data/era5_synthetic.nc]

The output is deterministic (fixed random seed) and takes a few seconds.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import shapely
import xarray as xr

DEFAULT_OUT = Path(__file__).resolve().parent / "data" / "era5_synthetic.nc"
START = np.datetime64("2018-06-01T00:00", "ns")

#: Crude coastlines [deg] (lon, lat): enough to put NaN waves on land, not for navigation.
LAND = {
    "iberia_france": [(-9.5, 36.0), (-8.9, 39.0), (-9.3, 43.0), (-8.0, 43.8), (-1.5, 43.4), (-1.2, 46.0),
                      (-2.5, 47.3), (-4.7, 48.4), (-1.5, 48.8), (1.5, 50.9), (3.0, 51.0), (3.0, 36.0)],
    "great_britain": [(-5.7, 50.0), (1.8, 51.0), (1.8, 53.0), (-0.5, 55.5), (-5.0, 55.5), (-5.2, 52.0),
                      (-3.0, 51.3)],
    "ireland": [(-10.5, 51.5), (-6.0, 52.0), (-6.0, 55.3), (-10.0, 55.3)],
    "africa": [(-5.9, 35.8), (-9.8, 32.0), (-9.8, 29.5), (-13.2, 27.7), (-17.0, 21.0), (-16.5, 19.5),
               (-17.5, 14.7), (-16.8, 12.5), (-15.0, 11.0), (-13.0, 9.0), (-10.5, 6.5), (-7.5, 4.5),
               (0.5, 4.5), (0.5, 36.0)],
    "south_america": [(-70.5, 11.8), (-68.0, 10.5), (-64.0, 10.6), (-61.9, 10.7), (-60.0, 8.5),
                      (-57.0, 6.0), (-52.0, 4.5), (-70.5, 4.5)],
    "hispaniola": [(-70.5, 18.2), (-68.3, 18.5), (-69.0, 19.9), (-70.5, 19.9)],
    "puerto_rico": [(-67.3, 18.0), (-65.6, 18.0), (-65.6, 18.5), (-67.3, 18.5)],
}  # fmt: skip

ATTRS = {
    "u10": {"units": "m s**-1", "long_name": "10 metre U wind component", "standard_name": "eastward_wind",
            "GRIB_paramId": 165},
    "v10": {"units": "m s**-1", "long_name": "10 metre V wind component", "standard_name": "northward_wind",
            "GRIB_paramId": 166},
    "swh": {"units": "m", "long_name": "Significant height of combined wind waves and swell",
            "standard_name": "sea_surface_wave_significant_height", "GRIB_paramId": 140229},
    "mwd": {"units": "Degree true", "long_name": "Mean wave direction",
            "standard_name": "sea_surface_wave_from_direction", "GRIB_paramId": 140230},
    "pp1d": {"units": "s", "long_name": "Peak wave period",
             "standard_name": "sea_surface_wave_period_at_variance_spectral_density_maximum",
             "GRIB_paramId": 140231},
}  # fmt: skip


def _vortex(lon, lat, lon0, lat0, vmax, radius, sign):
    """Wind (u, v) [m/s] of a vortex: sign +1 cyclonic (anticlockwise in the north), -1 anticyclonic."""
    dx = (lon - lon0) * np.cos(np.deg2rad(lat))
    dy = lat - lat0
    r = np.hypot(dx, dy) + 1e-9
    speed = vmax * (r / radius) * np.exp(0.5 * (1.0 - (r / radius) ** 2))
    return -sign * speed * dy / r, sign * speed * dx / r


def make_dataset(*, resolution_deg: float = 0.5, step_h: int = 3, days: int = 46, seed: int = 2018) -> xr.Dataset:
    """The synthetic ERA5-layout dataset (see the module docstring)."""
    rng = np.random.default_rng(seed)
    lon = np.arange(-70.0, 0.0 + resolution_deg / 2, resolution_deg)
    lat = np.arange(55.0, 5.0 - resolution_deg / 2, -resolution_deg)
    hours = np.arange(0, days * 24 + 1, step_h, dtype=float)
    t, y, x = np.meshgrid(hours, lat, lon, indexing="ij")
    day = t / 24.0
    # background: trades (easterly, with a northerly part) south, westerlies north
    trade = 1.0 + 0.15 * np.sin(2 * np.pi * day / 5.0)
    u = 7.0 * np.tanh((y - 31.0) / 7.0) * np.where(y < 31.0, trade, 1.0)
    v = -3.5 * np.exp(-(((y - 17.0) / 9.0) ** 2)) * trade
    # Azores high, drifting slowly
    du, dv = _vortex(x, y, -35.0 + 5.0 * np.sin(2 * np.pi * day / 20.0), 35.0 + 2.0 * np.cos(2 * np.pi * day / 20.0),
                     6.0, 8.0, -1)  # fmt: skip
    u += du
    v += dv
    # North Atlantic lows: one every 5 days from off Nova Scotia, travelling ENE for 6 days
    for k in range(days // 5 + 1):
        born, lat0, speed = 5.0 * k + rng.uniform(0, 2), rng.uniform(38.0, 46.0), rng.uniform(8.0, 11.0)
        alive = (hours / 24.0 >= born) & (hours / 24.0 <= born + 6.0)
        if not alive.any():
            continue
        age = day[alive] - born
        du, dv = _vortex(x[alive], y[alive], -68.0 + speed * age, lat0 + 1.2 * age,
                         17.0 * np.sin(np.pi * age / 6.0), 4.5, +1)  # fmt: skip
        u[alive] += du
        v[alive] += dv
    # easterly waves in the trades, moving west at ~7 deg/day
    waves = np.zeros((hours.size, lon.size))  # separable: sum over waves in (time, lon), then x lat profile
    for k in range(days // 4 + 1):
        crest = 5.0 - 7.0 * (hours[:, None] / 24.0 - 4.0 * k - rng.uniform(0, 1))
        waves += np.exp(-(((lon - crest) / 4.0) ** 2)) * np.sin(np.deg2rad(lon - crest) * 45)
    v += 3.0 * waves[:, None, :] * np.exp(-(((lat - 14.0) / 6.0) ** 2))[None, :, None]
    wind = np.hypot(u, v)
    # waves: local wind sea plus a north-westerly swell in the north
    sea = 0.3 + 0.02 * wind**2
    swell = np.clip((y - 5.0) / 50.0, 0.0, 1.0) * 1.2
    swh = np.hypot(sea, swell)
    wind_from = np.arctan2(-u, -v)
    east = sea**2 * np.sin(wind_from) + swell**2 * np.sin(np.deg2rad(300.0))
    north = sea**2 * np.cos(wind_from) + swell**2 * np.cos(np.deg2rad(300.0))
    mwd = np.degrees(np.arctan2(east, north)) % 360.0
    pp1d = np.where(swell > sea, 11.0, np.maximum(3.0, 0.75 * wind))
    land = np.zeros((lat.size, lon.size), dtype=bool)
    glon, glat = np.meshgrid(lon, lat)
    for ring in LAND.values():
        land |= shapely.contains_xy(shapely.Polygon(ring), glon, glat)
    data = {}
    # rounded to binary fractions (0.0625 m/s, 0.03125 m, 0.5 deg, 0.0625 s): the zero low bits compress well
    for name, values, quantum in (("u10", u, 16), ("v10", v, 16), ("swh", swh, 32), ("mwd", mwd, 2),
                                  ("pp1d", pp1d, 16)):  # fmt: skip
        q = (np.round(values * quantum) / quantum).astype(np.float32)
        if name in ("swh", "mwd", "pp1d"):
            q[:, land] = np.nan
        data[name] = (("valid_time", "latitude", "longitude"), q, ATTRS[name])
    time = START + (hours * 3600).astype("timedelta64[s]")
    ds = xr.Dataset(
        data,
        coords={
            "number": ((), 0, {"long_name": "ensemble member numerical id", "units": "1"}),
            "valid_time": ("valid_time", time, {"long_name": "time", "standard_name": "time"}),
            "latitude": (
                "latitude",
                lat,
                {
                    "units": "degrees_north",
                    "standard_name": "latitude",
                    "long_name": "latitude",
                    "stored_direction": "decreasing",
                },
            ),
            "longitude": (
                "longitude",
                lon,
                {"units": "degrees_east", "standard_name": "longitude", "long_name": "longitude"},
            ),
        },  # fmt: skip
        attrs={
            "Conventions": "CF-1.7",
            "institution": "synthetic data in the layout of ERA5 (not ECMWF data); pyroute_rel example",
            "history": "examples/make_era5_example.py",
        },
    )
    return ds


def write(out: Path = DEFAULT_OUT, **options) -> Path:
    """Write the dataset to ``out`` (NetCDF4, float32, zlib + shuffle); returns the path."""
    ds = make_dataset(**options)
    out.parent.mkdir(parents=True, exist_ok=True)
    encoding = {name: {"zlib": True, "complevel": 4, "shuffle": True, "_FillValue": np.float32(np.nan)}
                for name in ds.data_vars}  # fmt: skip
    encoding["valid_time"] = {"units": "seconds since 1970-01-01", "dtype": "int64"}
    ds.to_netcdf(out, engine="netcdf4", encoding=encoding)
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help=f"output file (default {DEFAULT_OUT})")
    args = parser.parse_args(argv)
    path = write(args.out)
    print(f"wrote {path} ({path.stat().st_size / 1e6:.1f} MB)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
