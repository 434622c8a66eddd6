"""Snapshot mode: the recorder's writer keeps messages in memory and writes a bag per trigger.

:class:`SnapshotSink` stands where the recorder's bag stands (the writer thread calls the same
``add_topic``, ``write_batch``, ``flush``, ``close``): it puts every message into one
:class:`~bagkit.recording.snapshot_buffer.SnapshotBuffer`, checks the ``--trigger``
conditions, and on each trigger opens a *window*: ``pre_ns`` before the trigger (default: all
that is buffered) to ``post_ns`` after it. A trigger inside an open window extends it. The
window's buffered part, the latched state before it and the messages taken until its end go to
the :class:`~bagkit.recording.snapshot_writer.SnapshotWriter` thread, which writes them as a
complete bag ``OUTPUT/snapshot_N``. Requests (the ``~/snapshot`` service, a key) come from
other threads: everything here is under one lock.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

from bagkit.bag import TopicInfo
from bagkit.recording.errors import TriggerError
from bagkit.recording.latched import LatchedState, latched_depth
from bagkit.recording.options import RecordOptions
from bagkit.recording.report import SnapshotRecord
from bagkit.recording.snapshot_buffer import MessageSlice, SnapshotBuffer
from bagkit.recording.snapshot_writer import (
    SnapshotEnd,
    SnapshotMessages,
    SnapshotStart,
    SnapshotTopic,
    SnapshotWriter,
)

# A window ends once messages this much newer than its end arrive (or the clock passes it):
# batches of slower topics are up to a few milliseconds old when they reach the writer.
CLOSE_GRACE_NS = 250_000_000


class SnapshotTriggers(Protocol):
    """The ``--trigger`` conditions, checked on the messages
    (:class:`bagkit.ros.record.triggers.DataTriggers`, which decodes them with rclpy)."""

    def add_topic(self, info: TopicInfo) -> None:
        """Check the conditions on ``info``'s topic against its type (TriggerError if not)."""

    def matching(
        self, topic: str, payloads: Sequence[bytes], log_times: Sequence[int]
    ) -> list[tuple[int, str]]:
        """(index, trigger text) of each message of ``topic`` that triggers."""

    def tick(self, now_ns: int) -> list[str]:
        """The texts of the conditions over time that ``now_ns`` makes trigger."""


@dataclass(slots=True)
class _Window:
    record: SnapshotRecord
    # Messages added to the buffer after this many batches were forwarded as they come.
    opened_at_batch: int


class SnapshotSink:
    """The recorder's bag in snapshot mode: a buffer, triggers, windows, snapshot bags.

    Args:
        path: the output directory (created here); snapshot N goes to ``path/snapshot_N``.
        options: the recording's options (bounds, pre/post, latched repeats).
        triggers: the options' ``--trigger`` conditions, ready to check.
        on_error: called with the error line and the exit status it calls for: 1 when a
            snapshot cannot be written, 2 for a trigger's field that a late topic lacks.
        now_ns: the current log time (the system clock; with sim time, the newest message's).
    """

    def __init__(
        self,
        path: Path,
        options: RecordOptions,
        triggers: SnapshotTriggers,
        on_error: Callable[[str, int], None],
        now_ns: Callable[[], int] = time.time_ns,
    ) -> None:
        self.path = path
        self.custom_data: dict[str, str] = dict(options.custom_data)
        self.snapshots: list[SnapshotRecord] = []
        self._options = options
        self._repeat: Mapping[str, int] = options.repeat_transient_local
        self._latched = LatchedState(self._repeat)
        snapshot = options.snapshot
        assert snapshot is not None, "a snapshot sink needs snapshot options"
        self._buffer = SnapshotBuffer(snapshot.max_bytes, snapshot.max_duration_ns, self._latched)
        self._pre_ns = snapshot.pre_ns
        self._post_ns = snapshot.post_ns
        self.triggers = triggers
        self._topics: dict[str, tuple[TopicInfo, str]] = {}
        self._window: _Window | None = None
        self._batches = 0
        self._now_ns = now_ns
        self._lock = threading.Lock()
        self._writer: SnapshotWriter | None = None
        self._on_error = on_error

    def open(self) -> SnapshotSink:
        """Create the output directory and start the writer thread; return self.

        Raises:
            FileExistsError, OSError: the directory exists or cannot be created.
        """
        self.path.mkdir(parents=True)
        self._writer = SnapshotWriter(
            self._options.files.compression, dict(self.custom_data), self._write_failed
        )
        return self

    def _write_failed(self, message: str) -> None:
        self._on_error(message, 1)

    @property
    def evicted(self) -> dict[str, int]:
        """Messages evicted from the buffer by its bound, per topic."""
        with self._lock:
            return dict(self._buffer.evicted)

    def add_topic(self, topic: TopicInfo, definition: str | None = None) -> None:
        """Know a topic (its latched state, its triggers); add it to an open snapshot.

        A trigger condition that names a field the topic's type lacks stops the recording
        (``on_error``).
        """
        text = definition or ""
        with self._lock:
            self._topics[topic.name] = (topic, text)
            depth = latched_depth(topic, self._options)
            if depth:
                self._latched.track(topic.name, depth)
            window = self._window
            if window is not None:
                self._put(SnapshotTopic(window.record, topic, text))
        try:
            self.triggers.add_topic(topic)
        except TriggerError as exc:
            self._on_error(str(exc), exc.exit_code)

    def write_batch(
        self,
        topic: str,
        payloads: list[bytes],
        *,
        log_times: list[int],
        publish_times: list[int],
        sequences: list[int],
    ) -> None:
        """Buffer messages of one topic, act on the triggers among them, feed an open window."""
        hits = self.triggers.matching(topic, payloads, log_times)
        with self._lock:
            self._buffer.add(topic, payloads, log_times, publish_times, sequences)
            self._batches += 1
            for index, text in hits:
                self._trigger(log_times[index], text)
            window = self._window
            if window is not None and window.opened_at_batch < self._batches:
                self._forward(
                    window, MessageSlice(topic, payloads, log_times, publish_times, sequences)
                )
            self._close_if_over(self._buffer.newest_ns)

    def request(self, reason: str, at_ns: int | None = None) -> SnapshotRecord:
        """Trigger a snapshot now (a service call, a key), or at log time ``at_ns`` (a health
        check that broke then); return the snapshot it opened or extended."""
        with self._lock:
            now = self._now_ns()
            record = self._trigger(now if at_ns is None else at_ns, reason)
            self._close_if_over(now)
            return record

    def flush(self) -> None:
        """Trigger on a silence (a condition over time) and end a window whose time is over,
        although no newer message came."""
        now = self._now_ns()
        hits = self.triggers.tick(now)
        with self._lock:
            for text in hits:
                self._trigger(now, text)
            self._close_if_over(now)

    def close(self) -> None:
        """End the open window (its snapshot holds what came until now), wait for the writes."""
        with self._lock:
            if self._window is not None:
                self._end_window()
        if self._writer is not None:
            self._writer.close()
            self._writer = None

    def _trigger(self, at_ns: int, reason: str) -> SnapshotRecord:
        window = self._window
        if window is not None and at_ns <= window.record.end_ns:
            window.record.end_ns = max(window.record.end_ns, at_ns + self._post_ns)
            window.record.triggers += 1
            return window.record
        if window is not None:
            self._end_window()
        record = self._open_window(at_ns, reason)
        if not self._post_ns:
            self._end_window()  # nothing after the trigger: the snapshot is complete
        return record

    def _open_window(self, at_ns: int, reason: str) -> SnapshotRecord:
        buffer = self._buffer
        oldest = buffer.oldest_ns
        if self._pre_ns is not None:
            start = at_ns - self._pre_ns
        else:
            start = at_ns if oldest is None else min(oldest, at_ns)
        record = SnapshotRecord(
            path=self.path / f"snapshot_{len(self.snapshots)}",
            trigger=reason,
            trigger_ns=at_ns,
            start_ns=start,
            end_ns=at_ns + self._post_ns,
        )
        self.snapshots.append(record)
        self._window = _Window(record, self._batches)
        latched = buffer.latched_before(start)
        self._put(SnapshotStart(record, list(self._topics.values()), latched))
        for part in buffer.window(start, record.end_ns):
            self._put(SnapshotMessages(record, part))
        return record

    def _forward(self, window: _Window, messages: MessageSlice) -> None:
        """Send the messages of a batch taken while the window is open that fall inside it."""
        record = window.record
        times = messages.log_times
        inside = [i for i, t in enumerate(times) if record.start_ns <= t <= record.end_ns]
        if len(inside) == len(times):
            self._put(SnapshotMessages(record, messages))
        elif inside:
            self._put(
                SnapshotMessages(
                    record,
                    MessageSlice(
                        messages.topic,
                        [messages.payloads[i] for i in inside],
                        [times[i] for i in inside],
                        [messages.publish_times[i] for i in inside],
                        [messages.sequences[i] for i in inside],
                    ),
                )
            )

    def _close_if_over(self, now_ns: int) -> None:
        window = self._window
        if window is not None and now_ns > window.record.end_ns + CLOSE_GRACE_NS:
            self._end_window()

    def _end_window(self) -> None:
        assert self._window is not None
        self._put(SnapshotEnd(self._window.record))
        self._window = None

    def _put(self, item: SnapshotStart | SnapshotTopic | SnapshotMessages | SnapshotEnd) -> None:
        assert self._writer is not None, "open() first"
        self._writer.put(item)
