"""Local tangent-plane (ENU) coordinates around an origin fix, WGS84 radii of curvature.

Accurate to centimetres within a few kilometres of the origin, which is the scale of a flight.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

_WGS84_A = 6378137.0
_WGS84_E2 = 6.69437999014e-3


@dataclass(frozen=True, slots=True)
class GeodeticOrigin:
    """The ENU origin: latitude and longitude in degrees."""

    latitude: float
    longitude: float

    @property
    def _radii(self) -> tuple[float, float]:
        lat = math.radians(self.latitude)
        w = math.sqrt(1.0 - _WGS84_E2 * math.sin(lat) ** 2)
        meridian = _WGS84_A * (1.0 - _WGS84_E2) / w**3
        normal = _WGS84_A / w
        return meridian, normal * math.cos(lat)

    def to_enu(self, latitude: float, longitude: float) -> tuple[float, float]:
        """East and north metres of a point from the origin."""
        meridian, parallel = self._radii
        return (
            math.radians(longitude - self.longitude) * parallel,
            math.radians(latitude - self.latitude) * meridian,
        )

    def to_geodetic(self, east: float, north: float) -> tuple[float, float]:
        """Latitude and longitude in degrees of a point ``east``/``north`` metres away."""
        meridian, parallel = self._radii
        return (
            self.latitude + math.degrees(north / meridian),
            self.longitude + math.degrees(east / parallel),
        )
