"""BagWriter: rosbag2-compatible MCAP bags (directory, split files, ``metadata.yaml`` v9)."""

from __future__ import annotations

import contextlib
import threading
import time
from array import array
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import TracebackType
from typing import BinaryIO

import lz4.frame
import zstandard

from bagkit import __version__
from bagkit.bag import mcap
from bagkit.bag.definitions import canonical_type_name, message_definition, type_description_hash
from bagkit.bag.errors import BagError, BagExistsError, BagWriteError, UnknownMessageTypeError
from bagkit.bag.metadata import BagMetadata, FileInformation, write_metadata
from bagkit.bag.types import TopicInfo

COMPRESSIONS = ("zstd", "lz4", "none")
LIBRARY = f"bagkit {__version__}"
PROFILE = "ros2"
SCHEMA_ENCODING = "ros2msg"
DEFAULT_CHUNK_SIZE = 1 << 20


def _compressor(compression: str) -> tuple[str, Callable[[bytearray], bytes]]:
    if compression == "zstd":
        return "zstd", zstandard.ZstdCompressor(level=1).compress
    if compression == "lz4":
        return "lz4", lz4.frame.compress
    if compression == "none":
        return "", bytes
    raise BagError(f"unknown compression {compression!r} (choose from {', '.join(COMPRESSIONS)})")


@dataclass(slots=True)
class _StorageFile:
    """The MCAP file being written and what its summary will need."""

    path: Path
    handle: BinaryIO
    offset: int = 0
    chunk_indexes: list[mcap.ChunkIndex] = field(default_factory=list)
    metadata_indexes: list[mcap.MetadataIndex] = field(default_factory=list)
    channel_counts: dict[int, int] = field(default_factory=dict)
    message_count: int = 0
    start_time: int | None = None
    end_time: int = 0


class BagWriter:
    """Write a rosbag2-compatible MCAP bag: ``PATH/PATH_0.mcap`` ... and ``PATH/metadata.yaml``.

    A chunk is closed when it reaches ``chunk_size`` bytes or ``chunk_interval_s`` of wall time
    (checked on each ``write``; call :meth:`flush` when idle), so a killed process loses at most
    the open chunk. Not meant for concurrent ``write`` calls from several threads, but
    ``add_topic``/``flush`` may come from another thread than ``write``.

    Args:
        path: the bag directory to create; it must not exist.
        compression: chunk compression, ``zstd`` (default), ``lz4`` or ``none``.
        max_bag_size: split to a new file when the current one reaches this many bytes (0: never).
        max_bag_duration_s: split when a file spans this much log time (0: never).
        chunk_size: uncompressed bytes after which a chunk is closed.
        chunk_interval_s: wall time after which a chunk is closed at the next write.

    Raises:
        BagExistsError: ``path`` exists.
        BagWriteError: the directory cannot be created.
    """

    _chunk: bytearray
    _chunk_index: dict[int, array[int]]
    _chunk_start: int
    _chunk_end: int
    _chunk_messages: int
    _chunk_opened: float

    def __init__(
        self,
        path: str | Path,
        *,
        compression: str = "zstd",
        max_bag_size: int = 0,
        max_bag_duration_s: float = 0,
        chunk_size: int = DEFAULT_CHUNK_SIZE,
        chunk_interval_s: float = 1.0,
    ) -> None:
        self.path = Path(path)
        self.custom_data: dict[str, str] = {}
        self._compression, self._compress = _compressor(compression)
        self._max_bag_size = max_bag_size
        self._max_bag_duration_ns = int(max_bag_duration_s * 1e9)
        self._chunk_size = chunk_size
        self._chunk_interval_s = chunk_interval_s
        self._lock = threading.Lock()
        self._topics: dict[str, TopicInfo] = {}
        self._schemas: dict[str, mcap.Schema] = {}
        self._channels: dict[str, mcap.Channel] = {}
        self._channel_topics: dict[int, str] = {}
        self._topic_counts: dict[int, int] = {}
        self._files: list[FileInformation] = []
        self._file: _StorageFile | None = None
        self._closed = False
        self._reset_chunk()
        if self.path.exists():
            raise BagExistsError(f"{self.path} already exists (bagkit never overwrites a bag)")
        try:
            self.path.mkdir(parents=True)
        except FileExistsError as exc:
            raise BagExistsError(f"{self.path} already exists") from exc
        except OSError as exc:
            raise BagWriteError(f"cannot create {self.path}: {exc.strerror or exc}") from exc
        self._open_file()

    def __enter__(self) -> BagWriter:
        return self

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
        paths = [self.path / f.path for f in self._files]
        if self._file is not None:
            paths.append(self._file.path)
        return paths

    @property
    def topics(self) -> dict[str, TopicInfo]:
        """The topics added so far, by name."""
        return dict(self._topics)

    def add_topic(self, topic: TopicInfo, definition: str | None = None) -> None:
        """Add a topic (a channel, and a schema for its type unless the type has one already).

        Args:
            topic: name, type, serialization format, QoS and type hash. An empty type hash is
                filled from the installed type description when there is one.
            definition: the full ``ros2msg`` definition; None reads it from the installed
                ``.msg`` files (see :func:`message_definition`).

        Raises:
            UnknownMessageTypeError: ``definition`` is None and the type is not installed.
            BagError: the topic was already added with another type.
        """
        with self._lock:
            known = self._topics.get(topic.name)
            if known is not None:
                if known.type != topic.type:
                    raise BagError(
                        f"topic {topic.name} already added with type {known.type}, not {topic.type}"
                    )
                return
            type_name = canonical_type_name(topic.type)
            if not topic.type_description_hash:
                try:
                    hash_string = type_description_hash(type_name)
                except UnknownMessageTypeError:
                    hash_string = ""
                topic = TopicInfo(
                    topic.name,
                    topic.type,
                    topic.serialization_format,
                    topic.offered_qos_profiles,
                    hash_string,
                )
            schema = self._schemas.get(topic.type)
            if schema is None:
                text = message_definition(type_name) if definition is None else definition
                schema = mcap.Schema(
                    len(self._schemas) + 1, topic.type, SCHEMA_ENCODING, text.encode("utf-8")
                )
                self._schemas[topic.type] = schema
                self._append(mcap.encode_schema(schema))
            metadata = {"offered_qos_profiles": topic.offered_qos_profiles}
            if topic.type_description_hash:
                metadata["topic_type_hash"] = topic.type_description_hash
            channel = mcap.Channel(
                len(self._channels) + 1,
                schema.id,
                topic.name,
                topic.serialization_format,
                metadata,
            )
            self._channels[topic.name] = channel
            self._channel_topics[channel.id] = topic.name
            self._topics[topic.name] = topic
            self._topic_counts[channel.id] = 0
            self._append(mcap.encode_channel(channel))

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
            if (self._max_bag_size or self._max_bag_duration_ns) and self._split_due(log_time):
                self._close_for(topic, 1, split=True)
            self._append_message(
                channel_id,
                data,
                log_time,
                log_time if publish_time is None else publish_time,
                sequence,
            )
            if (
                len(self._chunk) >= self._chunk_size
                or time.monotonic() - self._chunk_opened >= self._chunk_interval_s
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
        splitting = self._max_bag_size or self._max_bag_duration_ns
        append = self._append_message
        chunk_size = self._chunk_size
        with self._lock:
            self._check_open(topic, len(payloads))
            for written, (data, log_time, publish_time, sequence) in enumerate(
                zip(payloads, log_times, publish_times, sequences, strict=True)
            ):
                if splitting and self._split_due(log_time):
                    self._close_for(topic, len(payloads) - written, split=True)
                append(channel_id, data, log_time, publish_time, sequence)
                if len(self._chunk) >= chunk_size:
                    self._close_for(topic, len(payloads) - written - 1)
            if time.monotonic() - self._chunk_opened >= self._chunk_interval_s:
                self._close_chunk()

    def flush(self) -> None:
        """Close the open chunk now, so that everything written so far is on disk.

        Raises:
            BagWriteError: writing the chunk failed.
        """
        with self._lock:
            if not self._closed:
                self._close_chunk()

    def close(self) -> None:
        """Finish the bag: last chunk, MCAP summary and footer, then ``metadata.yaml``.

        Safe to call twice. Raises BagWriteError if something could not be written; the
        metadata is still written when possible.
        """
        with self._lock:
            if self._closed:
                return
            self._closed = True
            error: BagWriteError | None = None
            try:
                self._close_chunk()
            except BagWriteError as exc:
                error = exc
            try:
                self._finish_file()
            except BagWriteError as exc:
                error = error or exc
            try:
                write_metadata(self.path, self._bag_metadata())
            except OSError as exc:
                error = error or BagWriteError(
                    f"cannot write {self.path / 'metadata.yaml'}: {exc.strerror or exc}"
                )
            if error is not None:
                raise error

    # -- internals --------------------------------------------------------------------------

    def _reset_chunk(self) -> None:
        self._chunk = bytearray()
        self._chunk_index = {}
        self._chunk_start = 1 << 64
        self._chunk_end = 0
        self._chunk_messages = 0
        self._chunk_opened = time.monotonic()

    def _append(self, *parts: bytes | bytearray, lost: dict[str, int] | None = None) -> int:
        """Write ``parts`` one after the other at the end of the current file; return the offset.

        On failure the file is cut back to where it was, so it stays readable.
        """
        storage = self._file
        if storage is None:
            raise BagWriteError(
                f"{self.path}: no file open after an earlier error", lost_by_topic=lost
            )
        offset = storage.offset
        try:
            for part in parts:
                view = memoryview(part)
                while view:
                    written = storage.handle.write(view)
                    if written is None:
                        raise OSError("write would block")
                    view = view[written:]
        except OSError as exc:
            try:
                storage.handle.truncate(offset)
                storage.handle.seek(offset)
            except OSError:
                pass
            raise BagWriteError(
                f"cannot write {storage.path}: {exc.strerror or exc}"
                + (f" ({sum(lost.values())} messages lost)" if lost else ""),
                lost_by_topic=lost,
            ) from exc
        storage.offset = offset + sum(len(part) for part in parts)
        return offset

    def _open_file(self) -> None:
        index = len(self._files)
        path = self.path / f"{self.path.name}_{index}.mcap"
        try:
            handle = open(path, "xb", buffering=0)  # noqa: SIM115 (closed in _finish_file)
        except OSError as exc:
            raise BagWriteError(f"cannot create {path}: {exc.strerror or exc}") from exc
        self._file = _StorageFile(path=path, handle=handle)
        self._append(
            mcap.MAGIC
            + mcap.encode_header(mcap.Header(PROFILE, LIBRARY))
            + b"".join(mcap.encode_schema(s) for s in self._schemas.values())
            + b"".join(mcap.encode_channel(c) for c in self._channels.values())
        )

    def _channel_id(self, topic: str) -> int:
        channel = self._channels.get(topic)
        if self._closed:
            raise BagError(f"cannot write to {topic}: {self.path} is closed")
        if channel is None:
            raise BagError(f"cannot write to {topic}: the topic was not added to {self.path}")
        return channel.id

    def _check_open(self, topic: str, messages: int) -> None:
        if self._file is None:
            raise BagWriteError(
                f"{self.path}: no file open after an earlier error",
                lost_by_topic={topic: messages},
            )

    def _append_message(
        self, channel_id: int, data: bytes, log_time: int, publish_time: int, sequence: int
    ) -> None:
        """Add a message record to the open chunk, and its entry to the chunk's index."""
        chunk = self._chunk
        offset = len(chunk)
        chunk += mcap.MESSAGE_RECORD_HEADER.pack(
            5, 22 + len(data), channel_id, sequence & 0xFFFFFFFF, log_time, publish_time
        )
        chunk += data
        entries = self._chunk_index.get(channel_id)
        if entries is None:
            entries = self._chunk_index[channel_id] = array("Q")
        entries.append(log_time)
        entries.append(offset)
        # Plain comparisons: this is the per-message path, min()/max() calls cost more.
        if log_time < self._chunk_start:  # noqa: PLR1730
            self._chunk_start = log_time
        if log_time > self._chunk_end:  # noqa: PLR1730
            self._chunk_end = log_time
        self._chunk_messages += 1

    def _close_for(self, topic: str, unwritten: int, *, split: bool = False) -> None:
        """Close the chunk (and with ``split`` the file) in the middle of a batch of ``topic``.

        A failure also loses the batch's ``unwritten`` messages: they are counted in the error.
        """
        try:
            if split:
                self._split()
            else:
                self._close_chunk()
        except BagWriteError as exc:
            lost = exc.lost_by_topic
            if unwritten:
                lost[topic] = lost.get(topic, 0) + unwritten
            raise BagWriteError(str(exc), lost_by_topic=lost) from exc

    def _chunk_lost(self, chunk_index: dict[int, array[int]]) -> dict[str, int]:
        """Messages per topic in a chunk's index (what is lost if the chunk is)."""
        return {self._channel_topics[c]: len(entries) // 2 for c, entries in chunk_index.items()}

    def _split_due(self, log_time: int) -> bool:
        storage = self._file
        assert storage is not None
        if storage.message_count + self._chunk_messages == 0:
            return False
        if self._max_bag_size and storage.offset + len(self._chunk) >= self._max_bag_size:
            return True
        if self._max_bag_duration_ns:
            start = min(storage.start_time or self._chunk_start, self._chunk_start)
            return log_time - start >= self._max_bag_duration_ns
        return False

    def _split(self) -> None:
        self._close_chunk()
        self._finish_file()
        self._open_file()

    def _close_chunk(self) -> None:
        if not self._chunk_messages:
            self._chunk_opened = time.monotonic()
            return
        storage = self._file
        if storage is None:
            lost = self._chunk_lost(self._chunk_index)
            self._reset_chunk()
            raise BagWriteError(
                f"{self.path}: no file open after an earlier error", lost_by_topic=lost
            )
        records = self._chunk  # _reset_chunk gives later messages a new buffer: no copy needed
        start, end, messages = self._chunk_start, self._chunk_end, self._chunk_messages
        chunk_index = self._chunk_index
        self._reset_chunk()
        compressed = self._compress(records)
        chunk_header = mcap.encode_chunk_header(
            mcap.Chunk(start, end, len(records), mcap.crc32(records), self._compression, compressed)
        )
        chunk_length = len(chunk_header) + len(compressed)
        index_records = []
        index_offsets: dict[int, int] = {}
        position = storage.offset + chunk_length
        for channel_id, entries in chunk_index.items():
            record = mcap.encode_message_index(channel_id, entries.tobytes())
            index_offsets[channel_id] = position
            position += len(record)
            index_records.append(record)
        index_bytes = b"".join(index_records)
        chunk_offset = self._append(
            chunk_header, compressed, index_bytes, lost=self._chunk_lost(chunk_index)
        )
        storage.chunk_indexes.append(
            mcap.ChunkIndex(
                start,
                end,
                chunk_offset,
                chunk_length,
                index_offsets,
                len(index_bytes),
                self._compression,
                len(compressed),
                len(records),
            )
        )
        for channel_id, entries in chunk_index.items():
            count = len(entries) // 2
            storage.channel_counts[channel_id] = storage.channel_counts.get(channel_id, 0) + count
            self._topic_counts[channel_id] += count
        storage.message_count += messages
        if storage.start_time is None or start < storage.start_time:
            storage.start_time = start
        storage.end_time = max(storage.end_time, end)

    def _file_information(self, storage: _StorageFile) -> FileInformation:
        start = storage.start_time or 0
        return FileInformation(
            path=storage.path.name,
            starting_time=start,
            duration=storage.end_time - start if storage.message_count else 0,
            message_count=storage.message_count,
        )

    def _bag_metadata(self) -> BagMetadata:
        files = list(self._files)
        if self._file is not None:
            files.append(self._file_information(self._file))
        with_messages = [f for f in files if f.message_count]
        start = min((f.starting_time for f in with_messages), default=0)
        end = max((f.starting_time + f.duration for f in with_messages), default=0)
        return BagMetadata(
            storage_identifier="mcap",
            relative_file_paths=[f.path for f in files],
            starting_time=start,
            duration=end - start,
            message_count=sum(f.message_count for f in files),
            topics=[
                (topic, self._topic_counts[self._channels[name].id])
                for name, topic in self._topics.items()
            ],
            files=files,
            custom_data=dict(self.custom_data),
        )

    def _finish_file(self) -> None:
        """Write the rosbag2 metadata record, the summary and the footer, and close the file."""
        storage = self._file
        if storage is None:
            return
        try:
            record = mcap.encode_metadata(
                mcap.Metadata(
                    "rosbag2", {"serialized_metadata": self._bag_metadata().dump(root=False)}
                )
            )
            offset = self._append(record)
            storage.metadata_indexes.append(mcap.MetadataIndex(offset, len(record), "rosbag2"))
            self._append(mcap.encode_data_end())
            summary_start = storage.offset
            groups: list[tuple[mcap.Opcode, bytes]] = [
                (mcap.Opcode.SCHEMA, b"".join(map(mcap.encode_schema, self._schemas.values()))),
                (mcap.Opcode.CHANNEL, b"".join(map(mcap.encode_channel, self._channels.values()))),
                (
                    mcap.Opcode.STATISTICS,
                    mcap.encode_statistics(
                        mcap.Statistics(
                            message_count=storage.message_count,
                            schema_count=len(self._schemas),
                            channel_count=len(self._channels),
                            attachment_count=0,
                            metadata_count=len(storage.metadata_indexes),
                            chunk_count=len(storage.chunk_indexes),
                            message_start_time=storage.start_time or 0,
                            message_end_time=storage.end_time,
                            channel_message_counts={
                                c.id: storage.channel_counts.get(c.id, 0)
                                for c in self._channels.values()
                            },
                        )
                    ),
                ),
                (
                    mcap.Opcode.CHUNK_INDEX,
                    b"".join(map(mcap.encode_chunk_index, storage.chunk_indexes)),
                ),
                (
                    mcap.Opcode.METADATA_INDEX,
                    b"".join(map(mcap.encode_metadata_index, storage.metadata_indexes)),
                ),
            ]
            summary = bytearray()
            offsets = bytearray()
            for opcode, group in groups:
                if group:
                    offsets += mcap.encode_summary_offset(
                        opcode, summary_start + len(summary), len(group)
                    )
                    summary += group
            summary_offset_start = summary_start + len(summary)
            summary += offsets
            footer = mcap.encode_footer(summary_start, summary_offset_start, 0)
            crc = mcap.crc32(summary + footer[:-4])
            footer = mcap.encode_footer(summary_start, summary_offset_start, crc)
            self._append(bytes(summary) + footer + mcap.MAGIC)
        finally:
            self._files.append(self._file_information(storage))
            self._file = None
            with contextlib.suppress(OSError):
                storage.handle.close()
