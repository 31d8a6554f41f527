"""Unit conversions and physical constants, each defined once.

Every other module imports these names; none writes the numbers again.

>>> round(10.0 * KN_PER_MS, 6)  # 10 m/s in knots
19.438445
"""

from __future__ import annotations

__all__ = ["KN_PER_MS", "KM_PER_NM", "EARTH_RADIUS_KM", "S_PER_H"]

#: Knots per metre per second: 1 kn = 1852 m / 3600 s, exact by the definition of the international nautical mile.
KN_PER_MS = 3600.0 / 1852.0
#: Kilometres per international nautical mile [km], exact by definition.
KM_PER_NM = 1.852
#: Mean Earth radius R1 of GRS80 / WGS84 [km] (Moritz 2000, Geodetic Reference System 1980).
EARTH_RADIUS_KM = 6371.0088
#: Seconds per hour [s].
S_PER_H = 3600.0
