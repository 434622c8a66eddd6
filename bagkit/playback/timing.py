"""Replay timing without rclpy: bag time <-> monotonic deadlines, precise waits, lateness stats."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

# A sleeping thread wakes up late (Linux's default timer slack, more on a busy machine); the
# last stretch before a deadline is spun instead. Short: a thread that spins most of the time is,
# to the scheduler, a CPU hog that it preempts for whole time slices on a busy machine (a long
# spin window made a fast replay's p99 lateness worse than a plain sleeping loop's); the player
# lowers the publishing thread's timer slack (bagkit.native.precise_timers) so that a short
# spin covers the wake-up (benchmarks/README.md).
SPIN_WINDOW_NS = 50_000
# A message published more than this after its scheduled time counts as late.
LATE_THRESHOLD_NS = 1_000_000

# /clock rate of `--clock` given without a value (as `ros2 bag play --clock` in Jazzy).
DEFAULT_CLOCK_HZ = 40.0
# How long the player watches the graph for subscriptions that existed before it: Fast DDS
# announces a participant every 3 s, and a new participant is often found only at the next one.
DEFAULT_DISCOVERY_TIME_NS = 3_000_000_000


@dataclass(frozen=True, slots=True)
class Timeline:
    """Maps bag time onto the monotonic clock: ``wall = wall_start + (bag - bag_start) / rate``."""

    bag_start_ns: int
    wall_start_ns: int
    rate: float

    def deadline(self, bag_ns: int) -> int:
        """Monotonic time (ns) at which the message logged at ``bag_ns`` is due."""
        return self.wall_start_ns + int((bag_ns - self.bag_start_ns) / self.rate)

    def bag_time(self, wall_ns: int) -> int:
        """Bag time (ns) that corresponds to the monotonic time ``wall_ns``."""
        return self.bag_start_ns + int((wall_ns - self.wall_start_ns) * self.rate)


def effective_rate(position_ns: int, now_ns: int, timeline: Timeline, *, since: Timeline) -> float:
    """Bag time played over wall time since the later of ``timeline``'s anchor and ``since``.

    ``timeline`` is re-anchored by a resume, a seek or a rate change, so the rate shown is the
    one in force, not an average over a pause; ``since`` is where the pass or the last seek
    started (its rate is not used).
    """
    wall_ns = max(timeline.wall_start_ns, since.wall_start_ns)
    played_ns = position_ns - max(timeline.bag_start_ns, since.bag_start_ns)
    return max(0, played_ns) / (now_ns - wall_ns) if now_ns > wall_ns else 0.0


def wait_until(deadline_ns: int, *, spin_window_ns: int = SPIN_WINDOW_NS) -> int:
    """Block until ``time.monotonic_ns()`` reaches ``deadline_ns``; return the time it returned.

    Sleeps coarsely until ``spin_window_ns`` before the deadline, then spins.
    """
    now = time.monotonic_ns()
    remaining = deadline_ns - now
    if remaining > spin_window_ns:
        time.sleep((remaining - spin_window_ns) / 1e9)
        now = time.monotonic_ns()
    while now < deadline_ns:
        now = time.monotonic_ns()
    return now


@dataclass(frozen=True, slots=True)
class LatenessSummary:
    """How late messages were published relative to their schedule (milliseconds)."""

    p50_ms: float
    p99_ms: float
    max_ms: float
    late: int
    """Messages published more than ``LATE_THRESHOLD_NS`` after their scheduled time."""

    @classmethod
    def from_samples(cls, lateness_ns: list[int]) -> LatenessSummary:
        """Summarize per-message lateness samples (ns; early publications count as 0)."""
        if not lateness_ns:
            return cls(p50_ms=math.nan, p99_ms=math.nan, max_ms=math.nan, late=0)
        ordered = sorted(max(0, value) for value in lateness_ns)
        return cls(
            p50_ms=_percentile(ordered, 0.50) / 1e6,
            p99_ms=_percentile(ordered, 0.99) / 1e6,
            max_ms=ordered[-1] / 1e6,
            late=sum(1 for value in ordered if value > LATE_THRESHOLD_NS),
        )


def _percentile(ordered: list[int], fraction: float) -> float:
    """Linear-interpolated percentile of an already sorted, non-empty list."""
    position = (len(ordered) - 1) * fraction
    low = math.floor(position)
    high = min(low + 1, len(ordered) - 1)
    return ordered[low] + (ordered[high] - ordered[low]) * (position - low)
