"""The recorder's writer thread: write handed-over batches to the bag and account for loss.

Every message taken is, at the end, either in the bag (``messages``) or counted lost on its
topic: ``gaps`` (holes in publication sequence numbers: lost inside the middleware),
``overflow`` (dropped on a full hand-off queue), ``write_failed`` (handed to the bag writer but
not in the bag, from :class:`~bagkit.bag.BagWriteError`'s ``lost_by_topic``, or taken after
writing failed); or, not lost, ``paused`` (taken while paused, :mod:`~bagkit.recording.pause`).
A live health check (``--health``) sees what is written here, after it is written, so that the
take thread never waits for it. No rclpy import.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TYPE_CHECKING

from bagkit.bag import BagWriteError, BagWriter
from bagkit.bag.errors import BagError
from bagkit.errors import BagkitError
from bagkit.native import name_native_thread
from bagkit.recording.handoff import Batch, BatchPart, HandoffQueue, StopSignal
from bagkit.recording.health_watch import (
    HEALTH_CUSTOM_DATA_KEY,
    HealthEvent,
    HealthWatch,
    health_summary,
)
from bagkit.recording.report import LOSS_CUSTOM_DATA_KEY, TopicRecord, loss_summary

if TYPE_CHECKING:
    from bagkit.recording.handoff import NewTopic
    from bagkit.recording.latched import LatchedRepeats
    from bagkit.recording.pause import PauseGate
    from bagkit.recording.snapshot import SnapshotSink

# The writer closes a chunk at least this often, so a killed recorder loses at most this much.
FLUSH_PERIOD_S = 1.0
CUSTOM_DATA_PREFIX = "bagkit.record."


class WriteLoop:
    """The writer thread's work: the bag, the per-topic records, whether writing failed.

    Args:
        bag: the open bag (in snapshot mode the snapshot sink, which stands for it).
        queue: the hand-off from the take thread.
        stop: failures are reported here (the take thread then stops).
        skip: ``skip(topic, reason)`` leaves a topic that cannot be added out, with a warning.
        latched: keeps the last messages of latched topics for the start of each split file.
        gate: says whether the recording is paused.
        health: the live health check fed with what is written (``--health``).
        on_health_break: called with a reason and the log time of each check that breaks
            (snapshot mode with ``--trigger-on-health``: the snapshot sink's ``request``).
    """

    def __init__(
        self,
        bag: BagWriter | SnapshotSink,
        queue: HandoffQueue,
        stop: StopSignal,
        skip: Callable[[str, str], None],
        *,
        latched: LatchedRepeats | None = None,
        gate: PauseGate | None = None,
        health: HealthWatch | None = None,
        on_health_break: Callable[[str, int], object] | None = None,
    ) -> None:
        self.bag = bag
        self.health = health
        self._on_health_break = on_health_break
        self._newest = 0  # the newest log time written (the clock of a sim-time recording)
        self._sim_time = False
        self.latched = latched
        self.gate = gate
        self.queue = queue
        self.stop = stop
        self.records: dict[str, TopicRecord] = {}
        self.failed = False
        self._skip = skip
        self._left_out: set[str] = set()

    def run(self) -> None:
        """The thread's body: write until the take thread ends, then finish the bag."""
        name_native_thread("bagkit-write")
        try:
            self._write_until_end()
        except Exception as exc:  # a bug must not leave the bag unfinished
            self.stop.fail(f"recording stopped: {exc!r}")
            self.failed = True
        self._finish()

    def _write_until_end(self) -> None:
        last_flush = time.monotonic()
        while True:
            item = self.queue.get(FLUSH_PERIOD_S / 2)
            now = time.monotonic()
            if item is None or now - last_flush >= FLUSH_PERIOD_S:
                # Idle or slow topics: close the open chunk so a crash loses at most a second.
                self._flush()
                last_flush = now
                if item is None:
                    continue
            kind, payload = item
            if kind == "end":
                return
            if kind == "topic":
                self._add_topic(payload)
            elif kind == "dropped":
                self._count_dropped(payload)
            elif kind == "wake":
                self._write_released()
            else:
                self._write_batch(payload)

    def _add_topic(self, new: NewTopic) -> None:
        name = new.info.name
        self.records[name] = new.topic.record
        if self.latched is not None:
            self.latched.add_topic(new.info)
        if self.gate is not None:
            self.gate.add_topic(new.info)
        if self.failed:
            return
        try:
            self.bag.add_topic(new.info, definition=new.definition)
        except BagWriteError as exc:
            self._write_failed(exc)
        except BagError as exc:
            self._left_out.add(name)
            del self.records[name]
            self._skip(name, str(exc))
            return
        if self.health is not None:
            self._health(lambda health: health.add_topic(new.info, new.definition))

    def _count_dropped(self, batch: Batch) -> None:
        for topic, taken in batch.parts:
            if topic.record.topic not in self._left_out:
                topic.count_gaps(taken.sequences)
                topic.record.overflow += len(taken)

    def _write_batch(self, batch: Batch) -> None:
        self._write_released()
        for part in batch.parts:
            topic, taken = part
            if topic.record.topic in self._left_out:
                continue
            topic.count_gaps(taken.sequences)
            if self.failed:
                topic.record.write_failed += len(taken)
            elif self.gate is None or not self.gate.hold(part, batch.sim_time):
                self._write(part, batch.sim_time)

    def _write_released(self) -> None:
        """After a resume: the last latched messages taken while paused."""
        if self.gate is None or self.failed:
            return
        for part in self.gate.release():
            part[0].record.paused -= len(part[1])
            self._write(part, None)

    def _write(self, part: BatchPart, sim_time: int | None) -> None:
        """Write one topic's messages of a batch; what the writer loses is taken back out."""
        topic, taken = part
        record = topic.record
        log_times = taken.received if sim_time is None else [sim_time] * len(taken)
        self._sim_time = sim_time is not None
        if not record.first_ns:
            record.first_ns = log_times[0]
        record.last_ns = log_times[-1]
        record.messages += len(taken)
        record.bytes += taken.nbytes
        try:
            self.bag.write_batch(
                record.topic,
                taken.payloads,
                log_times=log_times,
                publish_times=taken.sources,
                sequences=taken.sequences,
            )
            if self.latched is not None:
                self.latched.state.observe_batch(
                    record.topic, taken.payloads, log_times, taken.sources, taken.sequences
                )
            self._newest = max(self._newest, log_times[-1])
            if self.health is not None:
                self._health(lambda health: health.observe(record.topic, taken.payloads, log_times))
        except BagWriteError as exc:
            self._write_failed(exc)
        except BagError as exc:
            record.messages -= len(taken)
            record.write_failed += len(taken)
            self._write_failed(BagWriteError(str(exc)))

    def _flush(self) -> None:
        self._write_released()
        if self.health is not None:
            now = self._now_ns()
            self._health(lambda health: health.advance(now))
            overdue = self.health.overdue(now)
            if overdue is not None:
                self.stop.fail(
                    f"stopped by --stop-on-health: {overdue.topic}: {overdue.assertion} broken "
                    f"for {(now - (overdue.broken_since_ns or now)) / 1e9:.1f} s"
                )
        if not self.failed:
            try:
                self.bag.flush()
            except BagWriteError as exc:
                self._write_failed(exc)

    def _now_ns(self) -> int:
        """The log time now: the clock's, or with sim time the newest message's."""
        return self._newest if self._sim_time else max(time.time_ns(), self._newest)

    def _health(self, feed: Callable[[HealthWatch], list[HealthEvent]]) -> None:
        """Feed the health check; a check that broke triggers a snapshot if asked to."""
        assert self.health is not None
        try:
            events = feed(self.health)
        except BagkitError as exc:  # a field the topic's type lacks: bad input found late
            self.stop.fail(str(exc), 2)
            self.health = None
            return
        if self._on_health_break is None:
            return
        for event in events:
            if event.broken:
                self._on_health_break(f"health: {event.topic}: {event.assertion}", event.at_ns)

    def _write_failed(self, exc: BagWriteError) -> None:
        """Move the messages the bag writer lost from ``messages`` to ``write_failed``; stop."""
        for name, lost in exc.lost_by_topic.items():
            record = self.records.get(name)
            if record is not None:
                record.messages -= lost
                record.write_failed += lost
        self.failed = True
        # The report's error line gives the loss of the whole recording, not this chunk's.
        self.stop.fail(exc.reason)

    def _finish(self) -> None:
        """Flush, store the loss (and health) counts in metadata.yaml's custom data, close the
        bag."""
        self._flush()
        bag = self.bag
        if self.health is not None:
            end = self._now_ns()
            self._health(lambda health: health.finish(end))
        if self.health is not None:
            bag.custom_data[HEALTH_CUSTOM_DATA_KEY] = health_summary(self.health.counts)
        records = list(self.records.values())
        bag.custom_data[CUSTOM_DATA_PREFIX + "lost"] = str(sum(r.lost for r in records))
        bag.custom_data[LOSS_CUSTOM_DATA_KEY] = loss_summary(records)
        try:
            bag.close()
        except BagWriteError as exc:
            self._write_failed(exc)
        except BagError as exc:
            self.stop.fail(str(exc))
