"""The recorder's take thread: wait for messages, take them in bursts, hand batches over.

The thread owns the node: it waits on a wait set and drains every ready subscription with
:func:`bagkit.ros.record.take.take_serialized` (an executor callback per message is far too
slow for a recorder), polls the graph every ``discovery_period_s`` and hands
the messages to the writer thread through the :class:`~bagkit.recording.handoff.HandoffQueue`.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field
from typing import Any

from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.subscription import Subscription

from bagkit.bag.clock import CLOCK_TOPIC, clock_ns
from bagkit.native import name_native_thread
from bagkit.recording.handoff import Batch, BatchPart, HandoffQueue, StopSignal, TakenMessages
from bagkit.ros.record.recorded_topic import RecordedTopic
from bagkit.ros.record.subscriptions import Subscriptions, never_called
from bagkit.ros.record.take import take_serialized

# Messages taken from one subscription before looking at the others, so that a flood on one
# topic does not starve the rest, and before handing a batch to the writer; a topic's burst
# also ends at TAKE_BURST_BYTES (four 1 MB images), so batches stay far below the queue bound.
TAKE_BURST = 256
TAKE_BURST_BYTES = 4 << 20
# How long taken messages may wait before they are handed to the writer.
BATCH_AGE_S = 0.005
# While messages flow, the take thread takes from every subscription in turn instead of waiting
# on the wait set (a wait costs far more CPU than an empty take, even when data is there), and
# after a round that found fewer than PAUSE_BELOW messages it first lets PAUSE_S pass: every
# wake-up has its cost, so a topic at a few kHz is better taken a few messages per wake-up than
# one (benchmarks/README.md, "Measurements behind the code"). The messages wait in the
# middleware with their receive times already stamped; the best-effort subscriptions' keep-last
# depth (RECORD_DEPTH) holds PAUSE_S of up to 500k messages/s.
PAUSE_BELOW = 16
PAUSE_S = 0.002
# How long a stop (or a re-subscription) keeps taking what the middleware already holds.
DRAIN_S = 1.0


class SimClock:
    """The latest ``/clock`` time, taken from a raw subscription (``--use-sim-time``)."""

    def __init__(self, subscription: Subscription) -> None:
        self.subscription = subscription
        self.now_ns = 0
        # Until the first /clock there is no time to stamp with: messages are left out.
        self.started = False

    @classmethod
    def subscribe(cls, node: Node) -> SimClock:
        """Subscribe ``node`` to ``/clock`` (best effort, raw: taken by :meth:`update`)."""
        from rosgraph_msgs.msg import Clock

        best_effort = QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT)
        return cls(
            node.create_subscription(Clock, CLOCK_TOPIC, never_called, best_effort, raw=True)
        )

    def update(self) -> None:
        """Take every waiting clock message; the last one is the time."""
        handle, msg_type = self.subscription.handle, self.subscription.msg_type
        while (taken := handle.take_message(msg_type, True)) is not None:
            self.now_ns = clock_ns(taken[0])
            self.started = True


@dataclass(slots=True)
class _PendingBatch:
    """Messages taken over a few rounds, not yet handed to the writer.

    A hand-over costs a lock, a notification and a thread switch, too much to pay per message
    when a round finds one; with sim time each round's messages carry the clock of that moment,
    so each round is handed over at once (``max_age_s`` 0).
    """

    max_age_s: float
    parts: list[BatchPart] = field(default_factory=list)
    nbytes: int = 0
    count: int = 0
    deadline: float = 0.0

    def add(self, topic: RecordedTopic, taken: TakenMessages) -> None:
        if not self.parts:
            self.deadline = time.monotonic() + self.max_age_s
        self.parts.append((topic, taken))
        self.nbytes += taken.nbytes
        self.count += len(taken)

    def due(self, now: float) -> bool:
        return bool(self.parts) and (
            now >= self.deadline or self.nbytes >= TAKE_BURST_BYTES or self.count >= TAKE_BURST
        )


class TakeLoop:
    """The take thread's work and its loop-carried state.

    Args:
        subscriptions: the recorder's subscriptions (discovered and re-adapted from here).
        queue: the hand-off to the writer thread.
        stop: set by ``stop()`` or a failure; ``wake`` is the guard condition that interrupts
            the wait.
        wake: the guard condition's handle.
        clock: the ``/clock`` source with ``use_sim_time``, else None.
        discovery_period_s: how often the graph is polled.
    """

    def __init__(
        self,
        subscriptions: Subscriptions,
        queue: HandoffQueue,
        stop: StopSignal,
        *,
        wake: Any,
        clock: SimClock | None,
        discovery_period_s: float,
    ) -> None:
        self.subscriptions = subscriptions
        self.queue = queue
        self.stop = stop
        self.clock = clock
        self.discovery_period_s = discovery_period_s
        self._wake = wake
        self._context = subscriptions.node.context.handle
        self._pending = _PendingBatch(0.0 if clock is not None else BATCH_AGE_S)
        # With sim time a message's log time is the clock when it is taken: no pause.
        self._pause_s = PAUSE_S if clock is None else 0.0
        self._generation = -1
        self._topics: list[RecordedTopic] = []
        self._by_pointer: dict[int, RecordedTopic] = {}
        self._handles: list[Any] = []
        self._wait_set: Any = None
        self._taken_last_round = 0
        self._full_last_round = False
        self._next_poll = 0.0

    def run(self, discovered: threading.Event) -> None:
        """The thread's body: first discovery (``discovered`` is set after it), then take."""
        name_native_thread("bagkit-take")
        try:
            try:
                self.subscriptions.discover(self.drain)
            finally:
                discovered.set()
            self._take_until_stopped()
        except Exception as exc:  # any failure must still finish the bag
            self.stop.fail(f"recording stopped: {exc}")
        finally:
            self.queue.put_control("end")

    def _take_until_stopped(self) -> None:
        self._next_poll = time.monotonic() + self.discovery_period_s
        while not self.stop.is_set():
            self._watch_new_subscriptions()
            ready = self._ready_topics()
            if self.clock is not None:
                self.clock.update()
            self._take_round(ready)
            now = time.monotonic()
            if self._pending.due(now):
                self._hand_over()
            if now >= self._next_poll:
                self.subscriptions.discover(self.drain)
                self._next_poll = time.monotonic() + self.discovery_period_s
        if self._pending.parts:
            self._hand_over()
        for topic in self.subscriptions.snapshot():
            self.drain(topic)

    def _watch_new_subscriptions(self) -> None:
        """Rebuild the wait set when a subscription was added or replaced."""
        subscriptions = self.subscriptions
        if self._generation == subscriptions.generation:
            return
        with subscriptions.lock:
            self._generation = subscriptions.generation
            self._topics = list(subscriptions.topics.values())
        self._by_pointer = {t.subscription.handle.pointer: t for t in self._topics}
        self._handles = [t.subscription.handle for t in self._topics]
        if self.clock is not None:
            self._handles.append(self.clock.subscription.handle)
        self._wait_set = _rclpy.WaitSet(len(self._handles), 1, 0, 0, 0, 0, self._context)

    def _ready_topics(self) -> list[RecordedTopic]:
        """The topics to take from this round: all while messages flow, else the wait set's."""
        if self._taken_last_round:
            # Messages are flowing: take from every topic without a wait set (an empty take
            # costs less than a wait), after a pause if the last round was small.
            if self._pause_s and not self._full_last_round and self._taken_last_round < PAUSE_BELOW:
                time.sleep(self._pause_s)
            return self._topics
        wait_set = self._wait_set
        wait_set.clear_entities()
        for handle in self._handles:
            wait_set.add_subscription(handle)
        wait_set.add_guard_condition(self._wake)
        pending = self._pending
        until = min(self._next_poll, pending.deadline) if pending.parts else self._next_poll
        wait_set.wait(int(max(0.0, until - time.monotonic()) * 1e9))
        by_pointer = self._by_pointer
        return [
            by_pointer[pointer]
            for pointer in wait_set.get_ready_entities("subscription")
            if pointer in by_pointer
        ]

    def _take_round(self, ready: list[RecordedTopic]) -> None:
        """Take one burst from each ready topic; the rest waits for the next round."""
        taken_total = 0
        full = False
        pending = self._pending
        for topic in ready:
            taken = take_serialized(
                topic.subscription, max_count=TAKE_BURST, max_bytes=TAKE_BURST_BYTES
            )
            if taken.payloads and not self._clock_started():
                # As rosbag2: nothing is written before the first /clock (it has no time).
                topic.record.before_clock += len(taken)
            elif taken.payloads:
                pending.add(topic, taken)
                taken_total += len(taken)
                full |= len(taken) == TAKE_BURST or taken.nbytes >= TAKE_BURST_BYTES
        self._taken_last_round = taken_total
        self._full_last_round = full

    def _clock_started(self) -> bool:
        return self.clock is None or self.clock.started

    def _sim_time(self) -> int | None:
        return self.clock.now_ns if self.clock is not None else None

    def _hand_over(self) -> None:
        pending = self._pending
        self.queue.put_batch(Batch(pending.parts, self._sim_time()), pending.nbytes)
        pending.parts = []
        pending.nbytes = pending.count = 0

    def drain(self, topic: RecordedTopic) -> None:
        """Queue what waits in ``topic``'s subscription, for ``DRAIN_S`` at most.

        A publisher flooding the topic must not hold up a stop.
        """
        deadline = time.monotonic() + DRAIN_S
        while time.monotonic() < deadline:
            taken = take_serialized(
                topic.subscription, max_count=TAKE_BURST, max_bytes=TAKE_BURST_BYTES
            )
            if not taken.payloads:
                return
            if not self._clock_started():
                topic.record.before_clock += len(taken)
                continue
            self.queue.put_batch(Batch([(topic, taken)], self._sim_time()), taken.nbytes)
