"""Exact streaming moments: per-batch two-pass statistics merged with Chan et al.'s formula.

Each batch's mean and sum of squared deviations (M2) are computed in float64 with numpy (two
passes over data already in memory), then merged into the running figures:
``M2 = M2_a + M2_b + delta**2 * n_a * n_b / n``. Values are shifted by a per-column reference
(the first finite value seen) before anything is summed, so that a large mean (a timestamp in
seconds, an altitude in mm) does not round away the digits of a small spread: without the
shift, the batch means' rounding alone costs about 1e-8 relative in std on Unix-time stamps.
NaN values are counted apart and left out of every other figure, as pandas does.
"""

from __future__ import annotations

import numpy as np


class Moments:
    """Running count, NaN count, min, max, mean and variance of ``width`` columns at once."""

    __slots__ = ("count", "m2", "max", "min", "nan_count", "shift", "shifted_mean")

    def __init__(self, width: int) -> None:
        self.count = np.zeros(width, np.int64)
        self.nan_count = np.zeros(width, np.int64)
        self.shift = np.zeros(width)
        self.shifted_mean = np.zeros(width)
        self.m2 = np.zeros(width)
        self.min = np.full(width, np.nan)
        self.max = np.full(width, np.nan)

    def add(self, values: np.ndarray) -> None:
        """Add the rows of ``values`` (shape ``(n, width)``, any numeric dtype)."""
        x = np.asarray(values, dtype=np.float64)
        if not x.shape[0]:
            return
        nan = np.isnan(x)
        nan_count = nan.sum(axis=0)
        count = x.shape[0] - nan_count
        unset = self.count == 0
        if unset.any():
            finite = np.isfinite(x)
            first = finite.argmax(axis=0)
            candidates = x[first, np.arange(x.shape[1])]
            self.shift = np.where(unset & finite.any(axis=0), candidates, self.shift)
        with np.errstate(invalid="ignore", divide="ignore"):
            y = x - self.shift
            if nan_count.any():
                y = np.where(nan, 0.0, y)
                mean = y.sum(axis=0) / count
                m2 = (np.where(nan, 0.0, y - mean) ** 2).sum(axis=0)
            else:
                mean = y.sum(axis=0) / x.shape[0]
                m2 = ((y - mean) ** 2).sum(axis=0)
        has = count > 0
        mean = np.where(has, mean, 0.0)
        m2 = np.where(has, m2, 0.0)
        self._merge(count, mean, m2)
        self.nan_count += nan_count
        # fmin/fmax skip NaN (all-NaN columns stay NaN) without a RuntimeWarning.
        self.min = np.fmin(self.min, np.fmin.reduce(x, axis=0))
        self.max = np.fmax(self.max, np.fmax.reduce(x, axis=0))

    def _merge(self, count: np.ndarray, mean: np.ndarray, m2: np.ndarray) -> None:
        n_a = self.count.astype(np.float64)
        n = n_a + count
        with np.errstate(invalid="ignore", divide="ignore"):
            weight = np.where(n > 0, count / n, 0.0)
            delta = mean - self.shifted_mean
            merged_mean = self.shifted_mean + delta * weight
            merged_m2 = self.m2 + m2 + delta * delta * n_a * weight
        # A side without values contributes nothing (its placeholders may be inf or NaN).
        self.shifted_mean = np.where(count == 0, self.shifted_mean, merged_mean)
        self.m2 = np.where(count == 0, self.m2, merged_m2)
        self.count = self.count + count

    @property
    def mean(self) -> np.ndarray:
        """Mean of the values seen (NaN where there were none)."""
        return np.where(self.count > 0, self.shift + self.shifted_mean, np.nan)

    def std(self) -> np.ndarray:
        """Sample standard deviation (ddof=1, as pandas); NaN below two values."""
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(self.count > 1, np.sqrt(self.m2 / (self.count - 1)), np.nan)
