"""Exact streaming moments: per-batch two-pass statistics merged with Chan et al.'s formula.

Each batch's mean and sum of squared deviations (M2) are computed in float64 with numpy (two
passes over data already in memory), then merged into the running figures:
``M2 = M2_a + M2_b + delta**2 * n_a * n_b / n``. Values are shifted by a per-column reference
(the first finite value seen) before anything is summed, so that a large mean (a timestamp in
seconds, an altitude in mm) does not round away the digits of a small spread: without the
shift, the batch means' rounding alone costs about 1e-8 relative in std on Unix-time stamps.

As pandas does: NaN values are counted apart and left out of every other figure; infinite
values count, show in min/max, make the mean infinite (NaN when both signs occur) and the
standard deviation NaN.
"""

from __future__ import annotations

import numpy as np


class Moments:
    """Running count, NaN count, min, max, mean and variance of ``width`` columns at once."""

    __slots__ = (
        "finite_count",
        "m2",
        "max",
        "min",
        "nan_count",
        "negative_inf",
        "positive_inf",
        "shift",
        "shifted_mean",
    )

    def __init__(self, width: int) -> None:
        self.finite_count = np.zeros(width, np.int64)
        self.nan_count = np.zeros(width, np.int64)
        self.positive_inf = np.zeros(width, np.int64)
        self.negative_inf = np.zeros(width, np.int64)
        self.shift = np.zeros(width)
        self.shifted_mean = np.zeros(width)
        self.m2 = np.zeros(width)
        self.min = np.full(width, np.nan)
        self.max = np.full(width, np.nan)

    def add(self, values: np.ndarray) -> None:
        """Add the rows of ``values`` (shape ``(n, width)``, any numeric dtype)."""
        # Bytes from a bag can hold any float: a signalling NaN warns when cast, values near
        # 1e308 overflow to inf when summed; both end as NaN/inf figures, without a warning.
        with np.errstate(invalid="ignore", over="ignore"):
            self._add(np.asarray(values, dtype=np.float64))

    def _add(self, x: np.ndarray) -> None:
        n = x.shape[0]
        if not n:
            return
        unset = self.finite_count == 0
        if unset.any():
            finite = np.isfinite(x)
            candidates = x[finite.argmax(axis=0), np.arange(x.shape[1])]
            self.shift = np.where(unset & finite.any(axis=0), candidates, self.shift)
        with np.errstate(invalid="ignore"):  # inf - inf in a column: handled below
            y = x - self.shift
            total = y.sum(axis=0)
        if np.isfinite(total).all():
            # No NaN or inf anywhere (either would have made its column's sum non-finite).
            count = np.full(x.shape[1], n, dtype=np.int64)
            mean = total / n
            y -= mean  # y is a fresh array: square the deviations in place
            m2 = np.square(y, out=y).sum(axis=0)
        else:
            finite = np.isfinite(x)
            count = finite.sum(axis=0)
            with np.errstate(invalid="ignore", divide="ignore"):
                mean = np.where(finite, y, 0.0).sum(axis=0) / count
            mean = np.where(count > 0, mean, 0.0)
            with np.errstate(invalid="ignore"):
                m2 = (np.where(finite, y - mean, 0.0) ** 2).sum(axis=0)
            self.nan_count += np.isnan(x).sum(axis=0)
            self.positive_inf += (x == np.inf).sum(axis=0)
            self.negative_inf += (x == -np.inf).sum(axis=0)
        self._merge(count, mean, m2)
        # fmin/fmax skip NaN (all-NaN columns stay NaN) without a RuntimeWarning.
        self.min = np.fmin(self.min, np.fmin.reduce(x, axis=0))
        self.max = np.fmax(self.max, np.fmax.reduce(x, axis=0))

    def merge(self, other: Moments) -> None:
        """Add the values summarized by ``other`` (another bag's moments, bagkit.fleet).

        ``other``'s mean is re-expressed around this shift before Chan's formula: the two shifts
        are values of the same field, so their difference loses nothing that matters.
        """
        self.shift = np.where(self.finite_count == 0, other.shift, self.shift)
        self._merge(other.finite_count, other.shifted_mean + (other.shift - self.shift), other.m2)
        self.nan_count = self.nan_count + other.nan_count
        self.positive_inf = self.positive_inf + other.positive_inf
        self.negative_inf = self.negative_inf + other.negative_inf
        self.min = np.fmin(self.min, other.min)
        self.max = np.fmax(self.max, other.max)

    def _merge(self, count: np.ndarray, mean: np.ndarray, m2: np.ndarray) -> None:
        n_a = self.finite_count.astype(np.float64)
        n = n_a + count
        with np.errstate(invalid="ignore", divide="ignore"):
            weight = np.where(n > 0, count / n, 0.0)
        delta = mean - self.shifted_mean
        self.shifted_mean = np.where(
            count == 0, self.shifted_mean, self.shifted_mean + delta * weight
        )
        self.m2 = np.where(count == 0, self.m2, self.m2 + m2 + delta * delta * n_a * weight)
        self.finite_count = self.finite_count + count

    @property
    def count(self) -> np.ndarray:
        """Values that are not NaN."""
        return self.finite_count + self.positive_inf + self.negative_inf

    @property
    def mean(self) -> np.ndarray:
        """Mean of the values (NaN where there are none)."""
        finite = np.where(self.finite_count > 0, self.shift + self.shifted_mean, np.nan)
        positive, negative = self.positive_inf > 0, self.negative_inf > 0
        return np.where(
            positive & negative,
            np.nan,
            np.where(positive, np.inf, np.where(negative, -np.inf, finite)),
        )

    def std(self, ddof: int = 1) -> np.ndarray:
        """Standard deviation, of the sample (``ddof=1``, as pandas) or of the population
        (``ddof=0``, as numpy); NaN up to ``ddof`` values or with inf."""
        count = self.count
        with np.errstate(invalid="ignore", divide="ignore"):
            std = np.sqrt(self.m2 / (count - ddof))
        infinite = (self.positive_inf + self.negative_inf) > 0
        return np.where((count > ddof) & ~infinite, std, np.nan)
