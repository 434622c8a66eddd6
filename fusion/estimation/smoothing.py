"""Moving-average filter for noisy scalar inputs."""

from __future__ import annotations

import math
from collections import deque


class MovingAverage:
    """Mean of the last ``window`` samples (a window of 1 passes samples through)."""

    def __init__(self, window: int) -> None:
        if window < 1:
            raise ValueError(f"moving-average window must be >= 1, got {window}")
        self.window = window
        self._samples: deque[float] = deque(maxlen=window)

    @property
    def count(self) -> int:
        """Number of samples in the current mean."""
        return len(self._samples)

    def __call__(self, value: float) -> float:
        """Add ``value`` and return the current mean."""
        self._samples.append(value)
        return math.fsum(self._samples) / len(self._samples)
