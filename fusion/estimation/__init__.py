"""Altitude estimation: ISA barometry, local ENU coordinates, the vertical Kalman filter."""

from __future__ import annotations

from fusion.estimation.geodesy import GeodeticOrigin
from fusion.estimation.isa import (
    SEA_LEVEL_PRESSURE,
    altitude_per_pascal,
    pressure_altitude,
    pressure_at_altitude,
)
from fusion.estimation.kalman import VerticalFilterConfig, VerticalKalmanFilter
from fusion.estimation.smoothing import MovingAverage

__all__ = [
    "SEA_LEVEL_PRESSURE",
    "GeodeticOrigin",
    "MovingAverage",
    "VerticalFilterConfig",
    "VerticalKalmanFilter",
    "altitude_per_pascal",
    "pressure_altitude",
    "pressure_at_altitude",
]
