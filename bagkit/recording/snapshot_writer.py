"""The snapshot writer thread: writes each snapshot's bag while the recording goes on.

A snapshot's messages come in as they are decided: at its trigger the latched copies and the
buffered part of its window, then the messages taken during its ``--post`` time, then its end.
The thread writes them into a new bag (:class:`bagkit.bag.BagWriter`) in that order, so that the
recorder's writer thread only hands references over and is never held up by the disk. No rclpy
import.
"""

from __future__ import annotations

import contextlib
import queue
import threading
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from bagkit.bag import BagWriteError, BagWriter, TopicInfo
from bagkit.bag.errors import BagError
from bagkit.bag.messages import BagMessage
from bagkit.native import name_native_thread
from bagkit.recording.report import SnapshotRecord
from bagkit.recording.snapshot_buffer import MessageSlice


@dataclass(frozen=True, slots=True)
class SnapshotStart:
    """Open a snapshot's bag with these topics, and write its latched copies first."""

    record: SnapshotRecord
    topics: list[tuple[TopicInfo, str]]
    latched: list[BagMessage]


@dataclass(frozen=True, slots=True)
class SnapshotTopic:
    """A topic that appeared while the snapshot's window was open."""

    record: SnapshotRecord
    info: TopicInfo
    definition: str


@dataclass(frozen=True, slots=True)
class SnapshotMessages:
    """Messages of the snapshot's window, in the order taken."""

    record: SnapshotRecord
    messages: MessageSlice


@dataclass(frozen=True, slots=True)
class SnapshotEnd:
    """The snapshot's window is over: finish its bag."""

    record: SnapshotRecord


SnapshotItem = SnapshotStart | SnapshotTopic | SnapshotMessages | SnapshotEnd | None


class SnapshotWriter:
    """A thread that writes snapshots in the order their items are put.

    Args:
        compression: the bags' chunk compression.
        custom_data: metadata.yaml custom data of every snapshot.
        on_error: called (from the thread) with the error line when a snapshot cannot be
            written; later snapshots are still tried.
    """

    def __init__(
        self,
        compression: str,
        custom_data: dict[str, str],
        on_error: Callable[[str], None],
    ) -> None:
        self._compression = compression
        self._custom_data = custom_data
        self._on_error = on_error
        self._items: queue.SimpleQueue[SnapshotItem] = queue.SimpleQueue()
        self._bags: dict[Path, BagWriter] = {}
        self._thread = threading.Thread(target=self._run, name="bagkit-snapshot", daemon=True)
        self._thread.start()

    def put(self, item: SnapshotItem) -> None:
        """Queue an item; never waits."""
        self._items.put(item)

    def close(self) -> None:
        """Write what was queued, then end the thread."""
        self._items.put(None)
        self._thread.join()

    def _run(self) -> None:
        name_native_thread("bagkit-snapshot")
        while (item := self._items.get()) is not None:
            record = item.record
            if record.error is not None:
                continue  # this snapshot failed already: the rest of it is dropped
            try:
                self._handle(item)
            except BagError as exc:
                self._fail(record, exc)
            except Exception as exc:  # a bug must not stop the recording's other snapshots
                self._fail(record, BagError(f"snapshot {record.path}: {exc!r}"))

    def _handle(self, item: SnapshotStart | SnapshotTopic | SnapshotMessages | SnapshotEnd) -> None:
        record = item.record
        if isinstance(item, SnapshotStart):
            bag = BagWriter(record.path, compression=self._compression).open()
            self._bags[record.path] = bag
            for info, definition in item.topics:
                bag.add_topic(info, definition=definition)
            for message in item.latched:
                # The copies are logged at the window's start, before every message of it.
                bag.write(
                    message.topic,
                    message.data,
                    log_time=record.start_ns,
                    publish_time=message.publish_time,
                    sequence=message.sequence,
                )
                record.latched += 1
        elif isinstance(item, SnapshotTopic):
            self._bags[record.path].add_topic(item.info, definition=item.definition)
        elif isinstance(item, SnapshotMessages):
            messages = item.messages
            self._bags[record.path].write_batch(
                messages.topic,
                messages.payloads,
                log_times=messages.log_times,
                publish_times=messages.publish_times,
                sequences=messages.sequences,
            )
            record.messages[messages.topic] = record.messages.get(messages.topic, 0) + len(messages)
        else:
            bag = self._bags.pop(record.path)
            bag.custom_data.update(self._custom_data)
            bag.close()

    def _fail(self, record: SnapshotRecord, exc: BagError) -> None:
        message = exc.reason if isinstance(exc, BagWriteError) else str(exc)
        record.error = message
        bag = self._bags.pop(record.path, None)
        if bag is not None:
            with contextlib.suppress(BagError):  # what was written stays readable
                bag.close()
        self._on_error(message)
