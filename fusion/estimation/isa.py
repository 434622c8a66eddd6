"""The ISA troposphere: barometric altitude from static pressure and back."""

from __future__ import annotations

SEA_LEVEL_PRESSURE = 101325.0
_SCALE_HEIGHT = 44330.77
_EXPONENT = 0.190263


def pressure_altitude(pressure: float, *, p0: float = SEA_LEVEL_PRESSURE) -> float:
    """Altitude in metres above the ``p0`` level for a static pressure in Pa."""
    return _SCALE_HEIGHT * (1.0 - (pressure / p0) ** _EXPONENT)


def pressure_at_altitude(altitude: float, *, p0: float = SEA_LEVEL_PRESSURE) -> float:
    """Static pressure in Pa at ``altitude`` metres above the ``p0`` level."""
    return p0 * (1.0 - altitude / _SCALE_HEIGHT) ** (1.0 / _EXPONENT)


def altitude_per_pascal(pressure: float, *, p0: float = SEA_LEVEL_PRESSURE) -> float:
    """d(altitude)/d(pressure) in m/Pa at ``pressure`` (negative: altitude falls as p rises)."""
    return -_SCALE_HEIGHT * _EXPONENT / p0 * (pressure / p0) ** (_EXPONENT - 1.0)
