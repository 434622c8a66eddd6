"""Moments against pandas, batch by batch, with NaN, inf and a large mean."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from bagkit.stats import value_stats
from bagkit.stats.moments import Moments


def _batches(values: np.ndarray, rng: np.random.Generator) -> list[np.ndarray]:
    cuts = np.sort(rng.choice(np.arange(1, len(values)), size=20, replace=False))
    return np.split(values, cuts)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_streamed_figures_equal_pandas(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = 5000
    values = np.column_stack(
        [
            rng.normal(1.7e9, 3.0, n),  # Unix time in seconds: a large mean, a small spread
            rng.normal(0.0, 1.0, n),
            np.where(rng.random(n) < 0.2, np.nan, rng.normal(5.0, 2.0, n)),
            np.full(n, np.nan),  # no value at all
            np.where(np.arange(n) == 17, np.inf, rng.normal(size=n)),
            np.where(np.arange(n) % 1000 == 3, -np.inf, 1.0),
            rng.integers(0, 2, n).astype(float),
        ]
    )
    values[[10, 4000], 5] = np.inf  # both signs of infinity in one column
    moments = Moments(values.shape[1])
    for batch in _batches(values, rng):
        moments.add(batch)
    frame = pd.DataFrame(values)
    with np.errstate(invalid="ignore"):  # pandas' own inf - inf
        mean, std = frame.mean().to_numpy(), frame.std().to_numpy()
    np.testing.assert_array_equal(moments.count, frame.count().to_numpy())
    np.testing.assert_array_equal(moments.nan_count, frame.isna().sum().to_numpy())
    np.testing.assert_array_equal(moments.min, frame.min().to_numpy())
    np.testing.assert_array_equal(moments.max, frame.max().to_numpy())
    np.testing.assert_allclose(moments.mean, mean, rtol=1e-12)
    np.testing.assert_allclose(moments.std(), std, rtol=1e-9)


def test_one_value_has_no_std() -> None:
    moments = Moments(1)
    moments.add(np.array([[3.0]]))
    moments.add(np.empty((0, 1)))
    assert moments.count[0] == 1 and moments.mean[0] == 3.0 and np.isnan(moments.std()[0])


def test_value_stats_equal_numpy_and_say_none_without_values() -> None:
    values = np.random.default_rng(3).normal(0.004, 0.001, 57)
    got = value_stats("latency_s", np.append(values, np.nan))
    assert (got.field, got.count, got.nan_count) == ("latency_s", 57, 1)
    assert (got.min, got.max) == (values.min(), values.max())
    assert got.mean == pytest.approx(values.mean(), rel=1e-12)
    assert got.std == pytest.approx(values.std(ddof=1), rel=1e-12)
    one = value_stats("x", np.array([2.5]))
    assert (one.count, one.mean, one.std) == (1, 2.5, None)
    assert value_stats("x", np.array([])).min is None
