"""Sensor error models: IMU, GNSS, barometer, thermometer."""

from __future__ import annotations

from fusion.sensors.models import (
    BarometerModel,
    GnssModel,
    GnssNoise,
    ImuModel,
    ImuNoise,
    ThermometerModel,
)

__all__ = [
    "BarometerModel",
    "GnssModel",
    "GnssNoise",
    "ImuModel",
    "ImuNoise",
    "ThermometerModel",
]
