"""Obstacles: what a route may not cross, and the per-grid mask the solver asks.

=======================  ===============================================================================
module                   holds
=======================  ===============================================================================
``obstacles.areas``      the vectorised arc-versus-area test (does a great-circle arc touch a geometry?)
``obstacles.land``       GSHHG land and coastal margins
``obstacles.zones``      user exclusion zones (GeoJSON polygons with optional time windows)
``obstacles.strips``     whole rank pairs tested at once against an area (rank-pair shadows)
``obstacles.mask``       :class:`Avoid` (what to avoid) and the per-grid :class:`ObstacleMask`
=======================  ===============================================================================
"""

from __future__ import annotations

from pyroute_rel.obstacles.areas import arcs_blocked
from pyroute_rel.obstacles.land import RESOLUTIONS, arcs_on_land, land_geometry, land_within, points_on_land
from pyroute_rel.obstacles.mask import Avoid, ObstacleMask, check_points, obstacle_mask
from pyroute_rel.obstacles.zones import Zone, load_zones

__all__ = [
    "RESOLUTIONS",
    "arcs_blocked",
    "arcs_on_land",
    "land_geometry",
    "land_within",
    "points_on_land",
    "Avoid",
    "ObstacleMask",
    "check_points",
    "obstacle_mask",
    "Zone",
    "load_zones",
]
