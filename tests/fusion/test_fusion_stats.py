"""The logger's running statistics equal numpy's, NaN handling included."""

from __future__ import annotations

import math

import numpy as np
import pytest
from sensor_msgs.msg import Imu, NavSatFix

from fusion.processors.messages import numeric_fields
from fusion.stats import FieldStats, RunningStats


def test_running_stats_equal_numpy_with_nans() -> None:
    rng = np.random.default_rng(7)
    values = rng.normal(1e5, 3.0, 5000)  # large mean: naive sum-of-squares would lose digits
    values[rng.choice(values.size, 50, replace=False)] = np.nan
    stats = RunningStats()
    for v in values:
        stats.add(float(v))
    assert stats.count == 4950
    assert stats.nan_count == 50
    assert stats.min == np.nanmin(values)
    assert stats.max == np.nanmax(values)
    assert stats.mean == pytest.approx(np.nanmean(values), rel=1e-12)
    assert stats.std == pytest.approx(np.nanstd(values), rel=1e-9)


def test_empty_and_all_nan_stats_are_nan() -> None:
    stats = RunningStats()
    assert math.isnan(stats.mean) and math.isnan(stats.std)
    stats.add(math.nan)
    assert stats.count == 0 and stats.nan_count == 1 and math.isnan(stats.min)
    stats.add(2.5)
    assert (stats.min, stats.max, stats.mean, stats.std) == (2.5, 2.5, 2.5, 0.0)


def test_numeric_fields_of_messages() -> None:
    imu = Imu()
    imu.linear_acceleration.z = 9.81
    fields = numeric_fields(imu)
    assert fields["linear_acceleration.z"] == 9.81
    assert "orientation.w" in fields
    assert not any("covariance" in name or "header" in name for name in fields)
    fix = NavSatFix(latitude=math.nan)
    assert set(numeric_fields(fix)) == {
        "status.status",
        "status.service",
        "latitude",
        "longitude",
        "altitude",
    }
    table = FieldStats()
    table.add(numeric_fields(fix))
    assert table.fields["latitude"].nan_count == 1
