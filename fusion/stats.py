"""Running statistics per numeric field: count, min, max, mean, std (Welford, NaN-aware)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field


@dataclass(slots=True)
class RunningStats:
    """Statistics of a stream of floats, in O(1) memory.

    NaN samples are counted in ``nan_count`` and otherwise ignored, like numpy's ``nan*``
    functions; ``std`` is the population standard deviation (numpy's default ``ddof=0``).
    """

    count: int = 0
    nan_count: int = 0
    min: float = math.nan
    max: float = math.nan
    mean: float = math.nan
    _m2: float = 0.0

    def add(self, value: float) -> None:
        """Add one sample."""
        if math.isnan(value):
            self.nan_count += 1
            return
        count = self.count = self.count + 1
        if count == 1:
            self.min = self.max = self.mean = value
            return
        if value < self.min:
            self.min = value
        elif value > self.max:
            self.max = value
        delta = value - self.mean
        self.mean += delta / count
        self._m2 += delta * (value - self.mean)

    @property
    def variance(self) -> float:
        """Population variance (NaN before the first sample)."""
        return self._m2 / self.count if self.count else math.nan

    @property
    def std(self) -> float:
        """Population standard deviation (NaN before the first sample)."""
        return math.sqrt(self.variance) if self.count else math.nan


@dataclass(slots=True)
class FieldStats:
    """Running statistics of every field of one stream, in first-seen field order."""

    messages: int = 0
    fields: dict[str, RunningStats] = field(default_factory=dict)

    def add(self, values: dict[str, float]) -> None:
        """Add one message's numeric fields."""
        self.messages += 1
        fields = self.fields
        for name, value in values.items():
            stats = fields.get(name)
            if stats is None:
                stats = fields[name] = RunningStats()
            stats.add(value)
