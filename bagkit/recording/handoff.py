"""The hand-off between the recorder's take thread and its writer thread.

A FIFO bounded in message bytes, and the stop signal both threads watch. No rclpy import.
"""

from __future__ import annotations

import threading
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Literal, Protocol

from bagkit.bag import TopicInfo
from bagkit.recording.report import TopicRecord

# How long the take thread waits for room in a full write queue before dropping a batch.
QUEUE_WAIT_S = 1.0


class TakenTopic(Protocol):
    """A subscribed topic as the writer sees it
    (:class:`bagkit.ros.record.recorded_topic.RecordedTopic`)."""

    record: TopicRecord

    def count_gaps(self, sequences: list[int]) -> None:
        """Count the sequence gaps up to the messages just taken (``sequences``)."""


@dataclass(slots=True)
class TakenMessages:
    """Messages taken from one subscription, oldest first, one list per field."""

    payloads: list[bytes]
    received: list[int]
    """Receive times (ns), stamped by the middleware."""
    sources: list[int]
    """Source timestamps (ns), stamped by the publisher's middleware."""
    sequences: list[int]
    """Publication sequence numbers (0 where the middleware has none)."""
    nbytes: int
    """Sum of the payload sizes."""

    def __len__(self) -> int:
        return len(self.payloads)


@dataclass(frozen=True, slots=True)
class NewTopic:
    """What the writer needs to add a topic to the bag before its first message."""

    topic: TakenTopic
    info: TopicInfo
    definition: str


# One topic's messages of a batch.
BatchPart = tuple[TakenTopic, TakenMessages]
# What the writer receives: a batch to write ("batch"), a batch dropped on a full queue
# ("dropped"), a new topic to add to the bag ("topic"), the end of the recording ("end"), a
# nudge to look at its state now ("wake": a resume).
ItemKind = Literal["batch", "dropped", "topic", "end", "wake"]


@dataclass(frozen=True, slots=True)
class Batch:
    """Messages taken in a few rounds; with sim time, the clock when they were taken."""

    parts: list[BatchPart]
    sim_time: int | None = None


class HandoffQueue:
    """FIFO between the threads, bounded in message bytes.

    ``put_batch`` waits up to ``QUEUE_WAIT_S`` for room, so that a writer hiccup turns into
    back-pressure (reliable topics are subscribed keep-all: the middleware holds the messages
    and slows keep-all publishers) rather than loss; after that the batch is dropped and
    counted. Control items (new topics, dropped-batch markers, the end) are always accepted,
    so that the writer sees them in order with the messages.
    """

    def __init__(self, max_bytes: int) -> None:
        self._items: deque[tuple[ItemKind, Any, int]] = deque()
        self._bytes = 0
        self._max_bytes = max_bytes
        self._lock = threading.Lock()
        self._not_empty = threading.Condition(self._lock)
        self._not_full = threading.Condition(self._lock)

    def put_batch(self, batch: Batch, nbytes: int) -> bool:
        """Queue ``batch`` (``nbytes`` of payload); False if it was dropped on a full queue."""
        with self._lock:
            # An oversized batch still goes into an empty queue.
            accepted = self._not_full.wait_for(
                lambda: not self._bytes or self._bytes + nbytes <= self._max_bytes,
                QUEUE_WAIT_S,
            )
            if accepted:
                self._items.append(("batch", batch, nbytes))
                self._bytes += nbytes
            else:
                self._items.append(("dropped", batch, 0))
            self._not_empty.notify()
            return accepted

    def put_control(self, kind: ItemKind, payload: Any = None) -> None:
        """Queue a control item; never waits."""
        with self._lock:
            self._items.append((kind, payload, 0))
            self._not_empty.notify()

    def get(self, timeout: float) -> tuple[ItemKind, Any] | None:
        """The oldest item, or None when none came within ``timeout`` seconds."""
        with self._lock:
            if not self._items and not self._not_empty.wait(timeout):
                return None
            if not self._items:
                return None
            kind, payload, nbytes = self._items.popleft()
            if nbytes:
                self._bytes -= nbytes
                self._not_full.notify()
            return kind, payload


@dataclass(slots=True)
class StopSignal:
    """Why and whether the recording stops; set by ``stop()`` or by a failing thread.

    ``wake`` interrupts the take thread's wait (a guard condition's trigger).
    """

    wake: Callable[[], None] = lambda: None
    errors: list[str] = field(default_factory=list)
    # The exit status the first error calls for: 1 a failed run, 2 bad input found late.
    exit_code: int = 1
    event: threading.Event = field(default_factory=threading.Event)

    def is_set(self) -> bool:
        """Whether the recording is stopping."""
        return self.event.is_set()

    def set(self) -> None:
        """Stop the recording without an error."""
        self.event.set()
        self.wake()

    def fail(self, message: str, exit_code: int = 1) -> None:
        """Stop the recording because of ``message`` (the first one is the report's error,
        ``exit_code`` its exit status)."""
        if not self.errors:
            self.exit_code = exit_code
        self.errors.append(message)
        self.set()
