"""ISA barometric altitude and local ENU coordinates against reference values."""

from __future__ import annotations

import pytest

from fusion.estimation import (
    GeodeticOrigin,
    altitude_per_pascal,
    pressure_altitude,
    pressure_at_altitude,
)


def test_isa_reference_values_both_ways() -> None:
    # ICAO standard atmosphere: 1000 m is 898.746 hPa.
    assert pressure_at_altitude(1000.0) == pytest.approx(89874.6, abs=0.1)
    assert pressure_altitude(89874.6) == pytest.approx(1000.0, abs=0.02)
    assert pressure_altitude(101325.0) == 0.0
    # 500 m: 954.61 hPa (ICAO table).
    assert pressure_at_altitude(500.0) == pytest.approx(95461.0, abs=5.0)


def test_qnh_shifts_the_zero() -> None:
    assert pressure_altitude(100000.0, p0=100000.0) == 0.0
    lower_qnh = pressure_altitude(95000.0, p0=100000.0)
    assert lower_qnh < pressure_altitude(95000.0)
    assert pressure_at_altitude(lower_qnh, p0=100000.0) == pytest.approx(95000.0)


def test_altitude_per_pascal_is_the_derivative() -> None:
    # About 8.3 cm per Pa near sea level.
    assert altitude_per_pascal(101325.0) == pytest.approx(-0.0832, abs=0.0005)
    p = 95000.0
    numeric = (pressure_altitude(p + 0.5) - pressure_altitude(p - 0.5)) / 1.0
    assert altitude_per_pascal(p) == pytest.approx(numeric, rel=1e-6)


def test_enu_round_trip_and_scale() -> None:
    origin = GeodeticOrigin(47.397742, 8.545594)
    lat, lon = origin.to_geodetic(120.0, -80.0)
    east, north = origin.to_enu(lat, lon)
    assert east == pytest.approx(120.0, abs=1e-6)
    assert north == pytest.approx(-80.0, abs=1e-6)
    # One arc-second of latitude is about 30.9 m at 47 deg.
    _, north_1s = origin.to_enu(origin.latitude + 1 / 3600, origin.longitude)
    assert north_1s == pytest.approx(30.88, abs=0.05)
