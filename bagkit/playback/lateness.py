"""Per-message lateness of a replay in bounded memory (numpy, no rclpy).

A replay that loops for days must not keep one number per published message: the percentiles
come from every sample up to ``LATENESS_SAMPLES``, then from a uniform random sample of that
many (reservoir sampling, vectorized over the blocks the player hands over, so that a hand-over
between two messages does not delay the next). The count, the maximum and the number of late
messages stay exact.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from bagkit.playback.timing import LATE_THRESHOLD_NS, LatenessSummary

LATENESS_SAMPLES = 100_000


class LatenessSamples:
    """Lateness (ns, < 0: early) of every published message, summarized in bounded memory.

    Args:
        capacity: samples kept (default ``LATENESS_SAMPLES``); seeded, so that the same
            replay gives the same summary.
    """

    def __init__(self, capacity: int | None = None) -> None:
        self.capacity = LATENESS_SAMPLES if capacity is None else capacity
        self.count = 0
        self.late = 0
        self.max_ns = 0
        self._kept = np.empty(self.capacity, dtype=np.int64)
        self._filled = 0
        self._rng = np.random.default_rng(0)

    @property
    def samples(self) -> npt.NDArray[np.int64]:
        """The samples kept (at most ``capacity``)."""
        return self._kept[: self._filled]

    def add(self, lateness_ns: int) -> None:
        """Account for one message published ``lateness_ns`` after its time."""
        self.add_many([lateness_ns])

    def add_many(self, lateness_ns: list[int]) -> None:
        """Account for several messages at once (the player hands them over in blocks)."""
        if not lateness_ns:
            return
        block = np.asarray(lateness_ns, dtype=np.int64)
        self.late += int(np.count_nonzero(block > LATE_THRESHOLD_NS))
        self.max_ns = max(self.max_ns, int(block.max()))
        take = min(self.capacity - self._filled, len(block))
        if take > 0:
            self._kept[self._filled : self._filled + take] = block[:take]
            self._filled += take
            self.count += take
            block = block[take:]
        if not len(block):
            return
        # Algorithm R: the i-th sample (1-based) replaces a slot drawn from [0, i) if < capacity.
        numbers = np.arange(self.count + 1, self.count + len(block) + 1, dtype=np.float64)
        slots = (self._rng.random(len(block)) * numbers).astype(np.int64)
        keep = slots < self.capacity
        self._kept[slots[keep]] = block[keep]
        self.count += len(block)

    def summary(self) -> LatenessSummary:
        """Percentiles from the samples kept; maximum and late count over every message."""
        if not self.count:
            return LatenessSummary.from_samples([])
        sampled = LatenessSummary.from_samples(self.samples.tolist())
        return LatenessSummary(
            p50_ms=sampled.p50_ms, p99_ms=sampled.p99_ms, max_ms=self.max_ns / 1e6, late=self.late
        )
