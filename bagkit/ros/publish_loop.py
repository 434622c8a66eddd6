"""One pass of a replay: publish each message when the monotonic clock reaches its time.

Replay controls (pause, resume, step, a rate change) belong between two messages: they
re-anchor :attr:`PassPublisher.timeline` (``Timeline(bag_now, wall_now, new_rate)``) so that
the next deadline follows from the new anchor; nothing else in the loop keeps timing state.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator

from bagkit.bag import BagMessage
from bagkit.ros.clock import clock_message
from bagkit.ros.playback_report import PlayProgress
from bagkit.ros.publishers import TopicOutput
from bagkit.ros.timing import LATE_THRESHOLD_NS, LatenessSamples, Timeline, wait_until

# Progress is reported only when the next message is at least this far away (or when it is
# overdue by PROGRESS_FORCE_S), so reporting never delays a message.
PROGRESS_SLACK_NS = 3_000_000
PROGRESS_FORCE_S = 2.0


class PassPublisher:
    """Publishes one pass over the replayed window, and keeps its timing state.

    Args:
        outputs: recorded topic -> its publisher.
        clock: the ``/clock`` publisher, or None.
        rate: playback speed factor.
        clock_hz: ``/clock`` rate (with ``clock``).
        lateness: where each message's lateness goes (shared by the passes).
        on_progress: called with a :class:`PlayProgress` about every ``progress_period_ns``.
        loop: the number of this pass (0 first), for progress.
    """

    def __init__(
        self,
        outputs: dict[str, TopicOutput],
        clock: TopicOutput | None,
        *,
        rate: float,
        clock_hz: float | None,
        lateness: LatenessSamples,
        on_progress: Callable[[PlayProgress], None] | None,
        progress_period_ns: int,
        loop: int,
    ) -> None:
        self.outputs = outputs
        self.clock = clock
        self.rate = rate
        self.tick_ns = int(1e9 / clock_hz) if clock_hz else 0
        self.lateness = lateness
        self.on_progress = on_progress
        self.progress_period_ns = progress_period_ns
        self.loop = loop
        self.timeline = Timeline(0, 0, rate)
        self.messages = 0
        self.late = 0
        self._window_start = 0
        self._last_log_time = 0
        self._next_tick = 0
        self._next_progress = 0

    def run(self, messages: Iterator[BagMessage], window_start: int) -> int:
        """Publish ``messages`` on schedule from now; return the bag time they covered (ns)."""
        self.timeline = Timeline(window_start, time.monotonic_ns(), self.rate)
        self._window_start = self._last_log_time = window_start
        self._next_tick = self.timeline.wall_start_ns + self.tick_ns
        self._next_progress = self.timeline.wall_start_ns + self.progress_period_ns
        clock = self.clock
        if clock is not None:
            clock.publish(clock_message(window_start))
        outputs = self.outputs
        lateness = self.lateness
        on_progress = self.on_progress
        for message in messages:
            log_time = message.log_time
            deadline = self.timeline.deadline(log_time)
            if clock is not None:
                self._tick_clock_until(deadline)
            if on_progress is not None:
                self._maybe_report_progress(deadline)
            now = wait_until(deadline)
            if clock is not None:
                clock.publish(clock_message(log_time))
            output = outputs[message.topic]
            output.publish(message.data)
            output.count += 1
            delay_ns = now - deadline
            lateness.add(delay_ns)
            self.messages += 1
            if delay_ns > LATE_THRESHOLD_NS:
                self.late += 1
            self._last_log_time = log_time
        if on_progress is not None:
            self._report_progress(time.monotonic_ns())
        return self._last_log_time - window_start

    def _tick_clock_until(self, deadline: int) -> None:
        """Publish ``/clock`` at ``clock_hz`` up to ``deadline``."""
        assert self.clock is not None
        while self._next_tick < deadline:
            wait_until(self._next_tick)
            self.clock.publish(clock_message(self.timeline.bag_time(self._next_tick)))
            # After a stall, resume ticking from now instead of bursting the backlog.
            self._next_tick = max(self._next_tick + self.tick_ns, time.monotonic_ns())

    def _maybe_report_progress(self, deadline: int) -> None:
        now = time.monotonic_ns()
        if now >= self._next_progress and (
            deadline - now > PROGRESS_SLACK_NS or now - self._next_progress > PROGRESS_FORCE_S * 1e9
        ):
            self._report_progress(now)
            self._next_progress = now + self.progress_period_ns

    def _report_progress(self, now: int) -> None:
        assert self.on_progress is not None
        bag_s = (self._last_log_time - self._window_start) / 1e9
        wall_s = (now - self.timeline.wall_start_ns) / 1e9
        self.on_progress(
            PlayProgress(
                bag_time_s=bag_s,
                wall_time_s=wall_s,
                effective_rate=bag_s / wall_s if wall_s > 0 else 0.0,
                messages=self.messages,
                late=self.late,
                loop=self.loop,
            )
        )
