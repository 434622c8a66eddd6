"""The logger's running statistics equal numpy's, NaN handling included."""

from __future__ import annotations

import math

import numpy as np
import pytest
from sensor_msgs.msg import Imu, NavSatFix

from fusion.processors.messages import numeric_fields
from fusion.stats import StreamMoments


def test_stream_moments_equal_numpy_with_nans_read_between_batches() -> None:
    rng = np.random.default_rng(7)
    values = rng.normal(1e5, 3.0, 5000)  # large mean: naive sum-of-squares would lose digits
    values[rng.choice(values.size, 50, replace=False)] = np.nan
    stream = StreamMoments()
    for i, v in enumerate(values):
        stream.add({"x": float(v), "twice": 2.0 * float(v)})
        if i == 1234:  # a summary mid-stream: the figures then are those of the rows so far
            ((_, early), _) = stream.fields()
            assert early.mean == pytest.approx(np.nanmean(values[:1235]), rel=1e-12)
    assert stream.messages == 5000
    (name, figures), (twice_name, twice) = stream.fields()
    assert (name, twice_name) == ("x", "twice")
    assert figures.count == 4950
    assert figures.nan_count == 50
    assert figures.min == np.nanmin(values)
    assert figures.max == np.nanmax(values)
    assert figures.mean == pytest.approx(np.nanmean(values), rel=1e-12)
    assert figures.std == pytest.approx(np.nanstd(values), rel=1e-9)
    assert twice.std == pytest.approx(np.nanstd(2.0 * values), rel=1e-9)


def test_empty_and_all_nan_stats_are_nan() -> None:
    stream = StreamMoments()
    assert list(stream.fields()) == []
    stream.add({"x": math.nan})
    ((_, figures),) = stream.fields()
    assert figures.count == 0 and figures.nan_count == 1
    assert math.isnan(figures.min) and math.isnan(figures.mean) and math.isnan(figures.std)
    stream.add({"x": 2.5})
    ((_, figures),) = stream.fields()
    assert (figures.min, figures.max, figures.mean, figures.std) == (2.5, 2.5, 2.5, 0.0)


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
    stream = StreamMoments()
    stream.add(numeric_fields(fix))
    assert dict(stream.fields())["latitude"].nan_count == 1
