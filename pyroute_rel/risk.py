"""What a route map shades: the failure model's probability and fired criteria over an area.

The maps of :mod:`pyroute_rel.plot` only draw; the physics they show (weather sampled on a mesh, the quantities the
failure model reads, its probability) is computed here, from the same functions the router costs arcs with
(:func:`~pyroute_rel.cost.arc_quantities`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from . import geodesy
from .cost import arc_quantities

if TYPE_CHECKING:
    from .failure import FailureModel
    from .grid import Grid
    from .weather import WeatherSource

__all__ = ["failure_field", "continuous_lon_deg"]

FloatArray = npt.NDArray[np.float64]


def continuous_lon_deg(lon_deg: npt.ArrayLike, ref_deg: float) -> FloatArray:
    """Longitudes [deg] moved by whole turns to within 180 deg of ``ref_deg`` [deg], so a course across the
    antimeridian is continuous (values may run past +-180; whole turns only, so longitudes in view stay exact).

    Examples
    --------
    >>> continuous_lon_deg([179.0, -179.0], 179.0).tolist()
    [179.0, 181.0]
    """
    x = np.asarray(lon_deg, dtype=float)
    return x + 360.0 * np.round((ref_deg - x) / 360.0)


def failure_field(
    grid: Grid, weather: WeatherSource, failure: FailureModel, *, time: Any = None, n: int = 200
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Failure probability and fired-criteria count on a lon/lat mesh covering the grid.

    Parameters
    ----------
    grid : The grid whose extent the mesh covers.
    weather : The weather sampled at the mesh points.
    failure : The failure model.
    time : When the weather is sampled (UTC); default 2000-01-01 (any time, for steady weather).
    n : Mesh points along each axis.

    Returns
    -------
    ``(lon [deg], lat [deg], p_f, n_fired)`` 2-D arrays of shape (n, n); the heading at each point is the
    great-circle course towards the finish. Longitudes are continuous across the antimeridian
    (:func:`continuous_lon_deg` around the start).
    """
    view = continuous_lon_deg(grid.lon_deg, grid.start[0])
    lon = np.linspace(view.min(), view.max(), n)
    lat = np.linspace(grid.lat_deg.min(), grid.lat_deg.max(), n)
    glon, glat = np.meshgrid(lon, lat)  # longitudes may run past +-180 (a course across the antimeridian)
    heading = geodesy.initial_bearing_deg(glon, glat, grid.finish[0], grid.finish[1])
    t = np.datetime64("2000-01-01") if time is None else time
    cond = weather.sample((glon + 180.0) % 360.0 - 180.0, glat, t)
    q = arc_quantities(cond, heading)
    need = {k: q[k] for k in failure.quantities}
    p = np.asarray(failure.p_fail(need), dtype=float)
    fired = np.asarray(failure.fired(need)).sum(axis=0)
    return glon, glat, p, fired
