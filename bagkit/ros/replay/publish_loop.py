"""One pass of a replay: publish each message when the monotonic clock reaches its time.

The timeline is the :class:`~bagkit.playback.controls.PlayControls`' own: a pause, resume, step
or rate change re-anchors it between two messages, and the loop waits on the controls (woken by
any change) instead of sleeping; nothing else in the loop keeps timing state.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator

from bagkit.bag import BagMessage
from bagkit.playback.controls import PlayControls
from bagkit.playback.lateness import LatenessSamples
from bagkit.playback.report import PlayProgress
from bagkit.playback.timing import LATE_THRESHOLD_NS, SPIN_WINDOW_NS, wait_until
from bagkit.ros.clock import clock_message
from bagkit.ros.replay.publishers import TopicOutput

# Lateness samples are handed to LatenessSamples in blocks, when the next message is at least
# LATENESS_SLACK_NS away (a block of 4096 takes about 0.1 ms), or at the latest at
# LATENESS_BLOCK_MAX: a list append per message is all the publishing loop pays otherwise.
LATENESS_BLOCK = 4096
LATENESS_BLOCK_MAX = 8 * LATENESS_BLOCK
LATENESS_SLACK_NS = 1_000_000
# Progress is reported only when the next message is at least this far away (or when it is
# overdue by PROGRESS_FORCE_S), so reporting never delays a message.
PROGRESS_SLACK_NS = 3_000_000
PROGRESS_FORCE_S = 2.0


class PassPublisher:
    """Publishes one pass over the replayed window, and keeps its timing state.

    Args:
        outputs: recorded topic -> its publisher.
        clock: the ``/clock`` publisher, or None.
        clock_hz: ``/clock`` rate (with ``clock``).
        lateness: where each message's lateness goes (shared by the passes).
        on_progress: called with a :class:`PlayProgress` about every ``progress_period_ns``.
        loop: the number of this pass (0 first), for progress.
        controls: pause, step and rate (and the timeline they anchor).
    """

    def __init__(
        self,
        outputs: dict[str, TopicOutput],
        clock: TopicOutput | None,
        *,
        controls: PlayControls,
        clock_hz: float | None,
        lateness: LatenessSamples,
        on_progress: Callable[[PlayProgress], None] | None,
        progress_period_ns: int,
        loop: int,
    ) -> None:
        self.outputs = outputs
        self.clock = clock
        self.tick_ns = int(1e9 / clock_hz) if clock_hz else 0
        self.lateness = lateness
        self.on_progress = on_progress
        self.progress_period_ns = progress_period_ns
        self.loop = loop
        self.controls = controls
        self._wall_start = 0
        self._window_start = 0
        self._next_tick = 0
        self._next_progress = 0
        self._counted_before = (0, 0)  # lateness count and late messages before this pass
        self.last_log_time = 0
        """Log time of the last message published in this pass."""

    def run(self, messages: Iterator[BagMessage], window_start: int) -> int:
        """Publish ``messages`` on schedule from now; return the bag time they covered (ns)."""
        controls = self.controls
        self._wall_start = time.monotonic_ns()
        controls.start(window_start, self._wall_start)
        self._window_start = last_log_time = self.last_log_time = window_start
        self._next_tick = self._wall_start + self.tick_ns
        self._next_progress = self._wall_start + self.progress_period_ns
        self._counted_before = (self.lateness.count, self.lateness.late)
        clock = self.clock
        if clock is not None:
            clock.publish(clock_message(window_start))
        outputs = self.outputs
        on_progress = self.on_progress
        delays: list[int] = []
        try:
            for message in messages:
                log_time = message.log_time
                deadline = controls.timeline.deadline(log_time)
                if clock is not None:
                    self._tick_clock_until(deadline)
                if on_progress is not None:
                    self._maybe_report_progress(deadline, last_log_time, delays)
                if len(delays) >= LATENESS_BLOCK and (
                    deadline - time.monotonic_ns() > LATENESS_SLACK_NS
                    or len(delays) >= LATENESS_BLOCK_MAX
                ):
                    self.lateness.add_many(delays)
                    delays = []
                now, deadline = self._wait_controlled(log_time)
                if clock is not None:
                    clock.publish(clock_message(log_time))
                output = outputs[message.topic]
                output.publish(message.data)
                output.count += 1
                delays.append(now - deadline)
                last_log_time = self.last_log_time = log_time
        finally:
            # Also on Ctrl-C: what was published is timed and counted (issue 27, item 6).
            self.lateness.add_many(delays)
        if on_progress is not None:
            self._report_progress(time.monotonic_ns(), last_log_time, [])
        return last_log_time - window_start

    @property
    def covered_ns(self) -> int:
        """Bag time published so far in this pass (what an interrupted pass covered)."""
        return self.last_log_time - self._window_start

    def _wait_controlled(self, log_time: int) -> tuple[int, int]:
        """Wait until the message logged at ``log_time`` is due, paused while the controls hold.

        Returns:
            The time of return and the deadline met (a stepped message's is its step's time).
        """
        controls = self.controls
        while True:
            generation = controls.generation
            if controls.holding:
                if controls.take_step(log_time):
                    now = time.monotonic_ns()
                    return now, now
                controls.wait_for_change(generation)
                continue
            deadline = controls.timeline.deadline(log_time)
            remaining = deadline - time.monotonic_ns()
            if remaining > SPIN_WINDOW_NS:
                controls.wait_for_change(generation, (remaining - SPIN_WINDOW_NS) / 1e9)
                continue
            return wait_until(deadline), deadline

    def _tick_clock_until(self, deadline: int) -> None:
        """Publish ``/clock`` at ``clock_hz`` up to ``deadline``."""
        assert self.clock is not None
        while self._next_tick < deadline:
            wait_until(self._next_tick)
            self.clock.publish(clock_message(self.controls.timeline.bag_time(self._next_tick)))
            # After a stall, resume ticking from now instead of bursting the backlog.
            self._next_tick = max(self._next_tick + self.tick_ns, time.monotonic_ns())

    def _maybe_report_progress(self, deadline: int, last_log_time: int, delays: list[int]) -> None:
        now = time.monotonic_ns()
        if now >= self._next_progress and (
            deadline - now > PROGRESS_SLACK_NS or now - self._next_progress > PROGRESS_FORCE_S * 1e9
        ):
            self._report_progress(now, last_log_time, delays)
            self._next_progress = now + self.progress_period_ns

    def _report_progress(self, now: int, last_log_time: int, delays: list[int]) -> None:
        """Report this pass so far; ``delays`` are the samples not yet handed to ``lateness``."""
        assert self.on_progress is not None
        count_before, late_before = self._counted_before
        bag_s = (last_log_time - self._window_start) / 1e9
        wall_s = (now - self._wall_start) / 1e9
        self.on_progress(
            PlayProgress(
                bag_time_s=bag_s,
                wall_time_s=wall_s,
                effective_rate=bag_s / wall_s if wall_s > 0 else 0.0,
                messages=self.lateness.count - count_before + len(delays),
                late=self.lateness.late
                - late_before
                + sum(1 for delay in delays if delay > LATE_THRESHOLD_NS),
                loop=self.loop,
            )
        )
