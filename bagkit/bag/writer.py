"""BagWriter: rosbag2-compatible MCAP bags (directory, split files, ``metadata.yaml`` v9)."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from types import TracebackType

from bagkit.bag.bag_files import (
    compressor,
)
from bagkit.bag.bag_topics import BagTopics
from bagkit.bag.errors import BagError, BagExistsError, BagWriteError
from bagkit.bag.file_rotation import FileRotation
from bagkit.bag.mcapio.chunk_builder import ChunkBuilder
from bagkit.bag.mcapio.records import encode
from bagkit.bag.messages import BagMessage, TopicInfo
from bagkit.bag.metadata import write_metadata
from bagkit.bag.written_files import WrittenFiles

DEFAULT_CHUNK_SIZE = 1 << 20


class BagWriter:
    """Write a rosbag2-compatible MCAP bag: ``PATH/PATH_0.mcap`` ... and ``PATH/metadata.yaml``.

    Nothing is created before :meth:`open` (``with BagWriter(path) as bag:`` opens it). A chunk
    is closed when it reaches ``chunk_size`` bytes or ``chunk_interval_s`` of wall time (checked
    on each ``write``; call :meth:`flush` when idle), so a killed process loses at most the open
    chunk. Not meant for concurrent ``write`` calls from several threads, but
    ``add_topic``/``flush`` may come from another thread than ``write``.

    Args:
        path: the bag directory to create; it must not exist.
        compression: chunk compression, ``zstd`` (default), ``lz4`` or ``none``.
        max_bag_size: split to a new file when the current one reaches this many bytes (0: never).
        max_bag_duration_ns: split when a file spans this much log time (0: never).
        chunk_size: uncompressed bytes after which a chunk is closed.
        chunk_interval_s: wall time after which a chunk is closed at the next write.
        file_preamble: returns messages to write at the start of every split file after the
            first (the latched state), logged at the time of that file's first message.
        rotation: keep the newest files only, and guard the free space
            (:mod:`bagkit.bag.file_rotation`); ``metadata.yaml`` lists the files that exist.

    Raises:
        BagError: unknown compression.
    """

    def __init__(
        self,
        path: str | Path,
        *,
        compression: str = "zstd",
        max_bag_size: int = 0,
        max_bag_duration_ns: int = 0,
        chunk_size: int = DEFAULT_CHUNK_SIZE,
        chunk_interval_s: float = 1.0,
        file_preamble: Callable[[], Sequence[BagMessage]] | None = None,
        rotation: FileRotation | None = None,
    ) -> None:
        self.path = Path(path)
        self._file_preamble = file_preamble
        self._split_requested = False
        self._rotation = rotation or FileRotation()
        self.custom_data: dict[str, str] = {}
        self._compression, self._compress = compressor(compression)
        self._max_bag_size = max_bag_size
        self._max_bag_duration_ns = max_bag_duration_ns
        self._chunk_size = chunk_size
        self._chunk_interval_s = chunk_interval_s
        self._lock = threading.Lock()
        self._topics = BagTopics()
        self._files = WrittenFiles(self.path, self._topics)
        self._chunk = ChunkBuilder()
        self._opened = False
        self._closed = False

    def open(self) -> BagWriter:
        """Create the bag directory and its first file; return self.

        Raises:
            BagExistsError: ``path`` exists.
            BagWriteError: the directory or the file cannot be created.
        """
        if self._opened:
            return self
        if self.path.exists():
            raise BagExistsError(f"{self.path} already exists (bagkit never overwrites a bag)")
        try:
            self.path.mkdir(parents=True)
        except FileExistsError as exc:
            raise BagExistsError(f"{self.path} already exists") from exc
        except OSError as exc:
            raise BagWriteError(f"cannot create {self.path}: {exc.strerror or exc}") from exc
        self._opened = True
        self._files.open_next()
        return self

    def __enter__(self) -> BagWriter:
        return self.open()

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    @property
    def files(self) -> list[Path]:
        """The storage files written so far, the open one included."""
        return self._files.paths()

    @property
    def topics(self) -> dict[str, TopicInfo]:
        """The topics added so far, by name."""
        return dict(self._topics.topics)

    def add_topic(self, topic: TopicInfo, definition: str | None = None) -> None:
        """Add a topic (a channel, and a schema for its type unless the type has one already).

        Args:
            topic: name, type, serialization format, QoS and type hash. An empty type hash is
                filled from the installed type description when there is one.
            definition: the full ``ros2msg`` definition; None reads it from the installed
                ``.msg`` files (see :func:`message_definition`).

        Raises:
            UnknownMessageTypeError: ``definition`` is None and the type is not installed.
            BagError: the topic was already added with another type, or the bag is not open.
        """
        with self._lock:
            self._check_writable(topic.name)
            records = self._topics.add(topic, definition)
            if records:
                self._append(b"".join(map(encode, records)))

    def write(
        self,
        topic: str,
        data: bytes,
        *,
        log_time: int,
        publish_time: int | None = None,
        sequence: int = 0,
    ) -> None:
        """Append one serialized message.

        Args:
            topic: a topic added with :meth:`add_topic`.
            data: the serialized (CDR) message.
            log_time: receive time in ns.
            publish_time: the publisher's source timestamp in ns (default: ``log_time``).
            sequence: publication sequence number (stored modulo 2**32, as MCAP's u32).

        Raises:
            BagError: the topic was not added, or the writer is closed.
            BagWriteError: writing to disk failed; ``lost_by_topic``/``messages_lost`` count the
                messages that are not in the bag, this call's included (the rest of the failed
                chunk: messages of earlier calls). Earlier chunks stay readable.
        """
        channel_id = self._channel_id(topic)
        with self._lock:
            self._check_open(topic, 1)
            splitting = self._max_bag_size or self._max_bag_duration_ns or self._split_requested
            if splitting and self._split_due(log_time):
                self._close_for(topic, 1, split_at=log_time)
            self._chunk.add(
                channel_id,
                data,
                log_time,
                log_time if publish_time is None else publish_time,
                sequence,
            )
            if (
                self._chunk.held + len(self._chunk.records) >= self._chunk_size
                or time.monotonic() - self._chunk.opened >= self._chunk_interval_s
            ):
                self._close_chunk()

    def write_batch(
        self,
        topic: str,
        payloads: Sequence[bytes],
        *,
        log_times: Sequence[int],
        publish_times: Sequence[int] | None = None,
        sequences: Sequence[int] | None = None,
    ) -> None:
        """Append serialized messages of one topic, as one :meth:`write` call each would.

        A recorder's writer gets messages in batches; one call per batch saves most of the
        per-message cost of :meth:`write` (argument handling, lock, clock).

        Args:
            topic: a topic added with :meth:`add_topic`.
            payloads: the serialized (CDR) messages.
            log_times: receive time in ns of each message.
            publish_times: source timestamp in ns of each message (default: ``log_times``).
            sequences: publication sequence number of each message (default: 0).

        Raises:
            BagError: the topic was not added, or the writer is closed.
            BagWriteError: as for :meth:`write`; ``lost_by_topic`` counts the batch's messages
                that were not written, and the failed chunk's.
            ValueError: the sequences are not all as long as ``payloads``.
        """
        channel_id = self._channel_id(topic)
        if publish_times is None:
            publish_times = log_times
        if sequences is None:
            sequences = (0,) * len(payloads)
        if not len(payloads) == len(log_times) == len(publish_times) == len(sequences):
            raise ValueError("write_batch: payloads, times and sequences differ in length")
        chunk_size = self._chunk_size
        with self._lock:
            splitting = self._max_bag_size or self._max_bag_duration_ns or self._split_requested
            self._check_open(topic, len(payloads))
            chunk = self._chunk
            for written, (data, log_time, publish_time, sequence) in enumerate(
                zip(payloads, log_times, publish_times, sequences, strict=True)
            ):
                if splitting and self._split_due(log_time):
                    self._close_for(topic, len(payloads) - written, split_at=log_time)
                    chunk = self._chunk
                chunk.add(channel_id, data, log_time, publish_time, sequence)
                if chunk.held + len(chunk.records) >= chunk_size:
                    self._close_for(topic, len(payloads) - written - 1)
                    chunk = self._chunk
            if time.monotonic() - self._chunk.opened >= self._chunk_interval_s:
                self._close_chunk()

    def request_split(self) -> None:
        """Start a new file before the next message (``~/split_bagfile``); nothing happens
        while the current file is empty. Safe from any thread."""
        self._split_requested = True

    def flush(self) -> None:
        """Close the open chunk now, so that everything written so far is on disk.

        Raises:
            BagWriteError: writing the chunk failed.
        """
        with self._lock:
            if self._opened and not self._closed:
                self._close_chunk()

    def close(self) -> None:
        """Finish the bag: last chunk, MCAP summary and footer, then ``metadata.yaml``.

        Safe to call twice. Raises BagWriteError if something could not be written; the
        metadata is still written when possible.
        """
        with self._lock:
            if self._closed or not self._opened:
                return
            self._closed = True
            error: BagWriteError | None = None
            try:
                self._close_chunk()
            except BagWriteError as exc:
                error = exc
            try:
                self._files.finish(self.custom_data)
            except BagWriteError as exc:
                error = error or exc
            try:
                write_metadata(self.path, self._files.metadata(self.custom_data))
            except OSError as exc:
                error = error or BagWriteError(
                    f"cannot write {self.path / 'metadata.yaml'}: {exc.strerror or exc}"
                )
            if error is not None:
                raise error

    # -- internals --------------------------------------------------------------------------

    def _append(self, *parts: bytes | bytearray, lost: dict[str, int] | None = None) -> int:
        """Write ``parts`` at the end of the current file; return their offset."""
        return self._files.current(lost or {}).append(*parts, lost=lost)

    def _check_writable(self, topic: str) -> None:
        if self._closed:
            raise BagError(f"cannot write to {topic}: {self.path} is closed")
        if not self._opened:
            raise BagError(f"cannot write to {topic}: {self.path} is not open (use open())")

    def _channel_id(self, topic: str) -> int:
        channel = self._topics.channels.get(topic)
        self._check_writable(topic)
        if channel is None:
            raise BagError(f"cannot write to {topic}: the topic was not added to {self.path}")
        return channel.id

    def _check_open(self, topic: str, messages: int) -> None:
        self._files.current({topic: messages})

    def _close_for(self, topic: str, unwritten: int, *, split_at: int | None = None) -> None:
        """Close the chunk (and with ``split_at``, the next message's log time, the file) in
        the middle of a batch of ``topic``.

        A failure also loses the batch's ``unwritten`` messages: they are counted in the error.
        """
        try:
            if split_at is not None:
                self._split(split_at)
            else:
                self._close_chunk()
        except BagWriteError as exc:
            lost = exc.lost_by_topic
            if unwritten:
                lost[topic] = lost.get(topic, 0) + unwritten
            raise BagWriteError(exc.reason, lost_by_topic=lost) from exc

    def _split_due(self, log_time: int) -> bool:
        storage = self._files.open
        assert storage is not None
        chunk = self._chunk
        if storage.message_count + chunk.count == 0:
            return False
        if self._split_requested:
            return True
        if self._max_bag_size and storage.offset + chunk.size >= self._max_bag_size:
            return True
        if self._max_bag_duration_ns:
            start = min(storage.start_time or chunk.start, chunk.start)
            return log_time - start >= self._max_bag_duration_ns
        return False

    def _split(self, log_time: int) -> None:
        self._split_requested = False
        self._close_chunk()
        self._files.finish(self.custom_data, last=False)
        for _ in range(self._rotation.excess(len(self._files.finished) + 1)):
            self._files.delete_oldest()
        self._files.open_next()
        if self._file_preamble is not None:
            # Logged with the new file's first message, so that the file replays alone.
            for message in self._file_preamble():
                channel = self._topics.channels.get(message.topic)
                if channel is not None:
                    self._chunk.add(
                        channel.id, message.data, log_time, message.publish_time, message.sequence
                    )

    def _close_chunk(self) -> None:
        chunk = self._chunk
        if not chunk.count:
            chunk.opened = time.monotonic()
            return
        # A new builder for later messages: the closed one's buffer is compressed without a copy.
        self._chunk = ChunkBuilder()
        lost = self._topics.by_topic(chunk.message_counts())
        self._guard_free_space(lost)
        file = self._files.current(lost)
        file.write_chunk(chunk.close(self._compression, self._compress), lost=lost)
        self._files.count(chunk.message_counts())

    def _guard_free_space(self, lost: dict[str, int]) -> None:
        """Below the free-space floor: delete the oldest file of a circular bag, else stop."""
        floor = self._rotation.min_free
        if floor is None:
            return
        while floor.below(self.path):
            if not (self._rotation.max_files and self._files.finished):
                raise BagWriteError(
                    f"{self.path}: less than {floor.text} free: stopped before the disk fills",
                    lost_by_topic=lost,
                )
            self._files.delete_oldest()
