"""One pass of a replay: publish each message when the monotonic clock reaches its time.

The timeline is the :class:`~bagkit.playback.controls.PlayControls`' own: a pause, resume, step
or rate change re-anchors it between two messages, and the loop waits on the controls (woken by
any change) instead of sleeping; nothing else in the loop keeps timing state. A seek leaves the
wait, publishes ``/clock`` at the new time and the latched state there, and goes on from there
on a timeline anchored anew (the jump is no lateness); a stop ends the pass.
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Callable, Iterator, Mapping
from typing import Protocol

from bagkit.bag import BagMessage
from bagkit.bag.clock import clock_message
from bagkit.playback.controls import PlayControls
from bagkit.playback.lateness import LatenessSamples
from bagkit.playback.pass_reader import PassReader
from bagkit.playback.report import PlayProgress
from bagkit.playback.timing import (
    LATE_THRESHOLD_NS,
    SPIN_WINDOW_NS,
    Timeline,
    effective_rate,
    wait_until,
)

# Lateness samples are handed to LatenessSamples in blocks, when the next message is at least
# LATENESS_SLACK_NS away (well above what a block costs), or at the latest at
# LATENESS_BLOCK_MAX: a list append per message is all the publishing loop pays otherwise.
LATENESS_BLOCK = 4096
LATENESS_BLOCK_MAX = 8 * LATENESS_BLOCK
LATENESS_SLACK_NS = 1_000_000
# Progress is reported only when the next message is at least this far away (or when it is
# overdue by PROGRESS_FORCE_S), so reporting never delays a message.
PROGRESS_SLACK_NS = 3_000_000
PROGRESS_FORCE_S = 2.0


class Output(Protocol):
    """Where a topic's messages go (a publisher, :class:`bagkit.ros.replay.publishers.TopicOutput`),
    and how many went."""

    count: int

    @property
    def publish(self) -> Callable[[bytes], None]:
        """Publish one serialized message."""


def _send(output: Output, data: bytes) -> None:
    """Publish ``data`` on ``output`` and count it.

    Counted also when Ctrl-C interrupts: Python raises a signal's KeyboardInterrupt as a call
    into C returns (the message went out), and the interrupted replay's report counts what went
    out.
    """
    try:
        output.publish(data)
    finally:
        output.count += 1


class PassPublisher:
    """Publishes one pass over the replayed window, and keeps its timing state.

    Args:
        outputs: recorded topic -> its publisher.
        clock: the ``/clock`` publisher, or None.
        clock_hz: ``/clock`` rate (with ``clock``).
        lateness: where each message's lateness goes (shared by the passes).
        on_progress: called with a :class:`PlayProgress` about every ``progress_period_ns``.
        loop: the number of this pass (0 first), for progress.
        controls: pause, step, rate, seek and stop (and the timeline they anchor).
        reader: where a seek reads from, and the latched state.
    """

    def __init__(
        self,
        outputs: Mapping[str, Output],
        clock: Output | None,
        *,
        controls: PlayControls,
        clock_hz: float | None,
        lateness: LatenessSamples,
        on_progress: Callable[[PlayProgress], None] | None,
        progress_period_ns: int,
        loop: int,
        reader: PassReader,
    ) -> None:
        self.outputs = outputs
        self.clock = clock
        self.tick_ns = int(1e9 / clock_hz) if clock_hz else 0
        self.lateness = lateness
        self.on_progress = on_progress
        self.progress_period_ns = progress_period_ns
        self.loop = loop
        self.controls = controls
        self.reader = reader
        self.latched = 0
        """Messages published as latched state (not timed) in this pass."""
        self._covered_ns = 0  # bag time published before the last seek
        self._segment_start = 0  # where the pass started or the last seek went
        self._wall_start = 0  # when the pass started or the last seek was taken
        self._pass_wall_start = 0
        self._delays: list[int] = []  # lateness samples not yet handed to ``lateness``
        self._window_start = 0
        self._next_tick = 0
        self._next_progress = 0
        self._counted_before = (0, 0)  # lateness count and late messages before this pass
        self.last_log_time = 0
        """Log time of the last message published in this pass."""

    def run(self, messages: Iterator[BagMessage], window_start: int) -> int:
        """Publish the latched state, then ``messages`` on schedule from now (seeks move the
        pass within the window); return the bag time published (ns)."""
        self._window_start = self._segment_start = self.last_log_time = window_start
        self._pass_wall_start = time.monotonic_ns()
        self._next_progress = self._pass_wall_start + self.progress_period_ns
        self._counted_before = (self.lateness.count, self.lateness.late)
        messages = self._jump_to(window_start, messages)
        delays = self._delays
        try:
            while True:
                if self._publish_until_interrupted(messages):
                    break
                target = self.controls.take_seek()
                if self.controls.stopped or target is None:
                    break
                self._covered_ns += self.last_log_time - self._segment_start
                self._segment_start = self.last_log_time = target
                messages = self._jump_to(target, self.reader.messages_from(target))
        finally:
            # Also on Ctrl-C: what was published is timed and counted (issue 27, item 6).
            self.lateness.add_many(delays)
            delays.clear()
        if self.on_progress is not None:
            self._report_progress(time.monotonic_ns())
        return self.covered_ns

    @property
    def covered_ns(self) -> int:
        """Bag time published so far in this pass (what an interrupted pass covered)."""
        return self._covered_ns + self.last_log_time - self._segment_start

    def _jump_to(self, bag_ns: int, messages: Iterator[BagMessage]) -> Iterator[BagMessage]:
        """Start ``messages`` at ``bag_ns``: ``/clock`` there, the latched state, the timeline.

        The first message is read before the timeline is anchored, so that reading its chunk
        is not counted as lateness; returns the messages, that one included.
        """
        if self.clock is not None:
            self.clock.publish(clock_message(bag_ns))
        outputs = self.outputs
        counted = sum(output.count for output in outputs.values())
        try:
            for message in self.reader.latched_before(bag_ns):
                _send(outputs[message.topic], message.data)
        finally:  # what _send counted, a message that went out as Ctrl-C came included
            self.latched += sum(output.count for output in outputs.values()) - counted
        first = next(messages, None)
        self._wall_start = time.monotonic_ns()
        self.controls.start(bag_ns, self._wall_start)
        self._next_tick = self._wall_start + self.tick_ns
        return itertools.chain([] if first is None else [first], messages)

    def _publish_until_interrupted(self, messages: Iterator[BagMessage]) -> bool:
        """Publish ``messages`` on schedule; True at their end, False on a seek or a stop."""
        delays = self._delays
        controls = self.controls
        clock = self.clock
        outputs = self.outputs
        on_progress = self.on_progress
        for message in messages:
            log_time = message.log_time
            deadline = controls.timeline.deadline(log_time)
            if clock is not None:
                self._tick_clock_until(deadline)
            if on_progress is not None:
                self._maybe_report_progress(deadline)
            if len(delays) >= LATENESS_BLOCK and (
                deadline - time.monotonic_ns() > LATENESS_SLACK_NS
                or len(delays) >= LATENESS_BLOCK_MAX
            ):
                self.lateness.add_many(delays)
                delays.clear()
            waited = self._wait_controlled(log_time)
            if waited is None:
                return False
            now, deadline = waited
            if clock is not None:
                clock.publish(clock_message(log_time))
            _send(outputs[message.topic], message.data)
            delays.append(now - deadline)
            self.last_log_time = log_time
        return True

    def _wait_controlled(self, log_time: int) -> tuple[int, int] | None:
        """Wait until the message logged at ``log_time`` is due, paused while the controls hold.

        Returns:
            The time of return and the deadline met (a stepped message's is its step's time);
            None when a seek or a stop interrupts the wait.
        """
        controls = self.controls
        while True:
            generation = controls.generation
            if controls.interrupting:
                return None
            if controls.holding:
                if controls.take_step(log_time):
                    now = time.monotonic_ns()
                    return now, now
                if self.on_progress is None:
                    controls.wait_for_change(generation)
                    continue
                # Paused: the progress line keeps saying so.
                controls.wait_for_change(generation, self.progress_period_ns / 1e9)
                now = time.monotonic_ns()
                if now >= self._next_progress:
                    self._report_progress(now)
                    self._next_progress = now + self.progress_period_ns
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
        while self._next_tick < deadline and not self.controls.interrupting:
            wait_until(self._next_tick)
            self.clock.publish(clock_message(self.controls.timeline.bag_time(self._next_tick)))
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
        """Report this pass so far (the samples not yet handed to ``lateness`` included)."""
        assert self.on_progress is not None
        count_before, late_before = self._counted_before
        delays = self._delays
        position = self.last_log_time
        span = self.reader.end_ns - self._window_start
        segment = Timeline(self._segment_start, self._wall_start, self.controls.rate)
        self.on_progress(
            PlayProgress(
                bag_time_s=(position - self._window_start) / 1e9,
                wall_time_s=(now - self._pass_wall_start) / 1e9,
                effective_rate=effective_rate(position, now, self.controls.timeline, since=segment),
                messages=self.lateness.count - count_before + len(delays),
                late=self.lateness.late
                - late_before
                + sum(1 for delay in delays if delay > LATE_THRESHOLD_NS),
                loop=self.loop,
                bag_ns=position,
                fraction=min(1.0, (position - self._window_start) / span) if span > 0 else 1.0,
                rate=self.controls.rate,
                paused=self.controls.holding,
            )
        )
