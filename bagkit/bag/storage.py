"""The storage files of a bag: one MCAP or SQLite3 file each, read in log-time order."""

from __future__ import annotations

import abc
import heapq
import operator
import sqlite3
import struct
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bagkit.bag import db3, mcap
from bagkit.bag.definitions import canonical_type_name
from bagkit.bag.errors import CorruptBagError, NotABagError, UnsupportedStorageError
from bagkit.bag.types import BagMessage, TopicInfo, make_message

SQLITE_MAGIC = b"SQLite format 3\x00"
_LOG_TIME = operator.attrgetter("log_time")
_OFFSET = operator.itemgetter(0)


@dataclass(frozen=True, slots=True)
class BagChunk:
    """One MCAP chunk, decompressed, with the message-index entries of each of its topics.

    ``message_index[topic]`` is a ``mcap.MESSAGE_INDEX_DTYPE`` array (``log_time``, ``offset``):
    the Message record of each message starts at ``offset`` in ``records``; its payload starts at
    ``offset + mcap.MESSAGE_DATA_OFFSET`` and is ``u64 at offset+1`` minus
    ``mcap.MESSAGE_PREFIX.size`` bytes long.
    """

    file: Path
    records: bytes
    message_index: dict[str, np.ndarray]


def _extent(block: mcap.ChunkIndex | mcap.MessageRun) -> tuple[int, int]:
    """(offset, length) of a chunk record or a run of loose messages in its file."""
    if isinstance(block, mcap.MessageRun):
        return block.offset, block.length
    return block.chunk_start_offset, block.chunk_length


def _merged(blocks: list[tuple[int, Iterator[BagMessage]]]) -> Iterator[BagMessage]:
    """Merge the log-time ordered messages of overlapping ``(file offset, messages)`` blocks.

    Equal log times come in storage order: heapq.merge takes them from the earlier iterable.
    """
    if len(blocks) == 1:
        return blocks[0][1]
    return heapq.merge(*(messages for _, messages in sorted(blocks, key=_OFFSET)), key=_LOG_TIME)


def _may_hold(block: mcap.ChunkIndex | mcap.MessageRun, channel_ids: set[int]) -> bool:
    """False when a chunk's message indexes show none of ``channel_ids`` (skip reading it)."""
    if isinstance(block, mcap.ChunkIndex) and block.message_index_offsets:
        return not channel_ids.isdisjoint(block.message_index_offsets)
    return True


class StorageFile(abc.ABC):
    """What the reader needs from one storage file, whatever its format."""

    path: Path
    storage_identifier: str
    topics: dict[str, TopicInfo]
    definitions: dict[str, str]
    topic_counts: dict[str, int]
    start_ns: int
    end_ns: int
    problems: list[str]
    compressed_size: int = 0
    uncompressed_size: int = 0
    compression: str = ""

    @abc.abstractmethod
    def messages(
        self, topics: set[str] | None, start_ns: int | None, end_ns: int | None
    ) -> Iterator[BagMessage]:
        """Yield the messages in log-time order (ties in storage order)."""

    @abc.abstractmethod
    def close(self) -> None:
        """Release the file."""


class McapFile(StorageFile):
    """An MCAP storage file (summary and indexes when present, salvage otherwise)."""

    storage_identifier = "mcap"

    def __init__(self, path: Path) -> None:
        self.path = path
        self._handle = open(path, "rb")  # noqa: SIM115 (closed in close())
        try:
            self.index = mcap.read_file_index(self._handle, name=path.name)
        except (NotABagError, CorruptBagError) as exc:
            self._handle.close()
            raise type(exc)(f"{path}: {exc}") from exc
        except BaseException:
            self._handle.close()
            raise
        profile = self.index.header.profile
        if profile not in ("ros2", ""):
            self._handle.close()
            raise UnsupportedStorageError(f"{path}: MCAP profile {profile!r} is not ROS 2")
        self.problems = list(self.index.problems)
        self._channel_topics: dict[int, str] = {}
        self.topics = {}
        self.definitions = {}
        for channel in self.index.channels.values():
            schema = self.index.schemas.get(channel.schema_id)
            type_name = canonical_type_name(schema.name) if schema else ""
            self._channel_topics[channel.id] = channel.topic
            self.topics.setdefault(
                channel.topic,
                TopicInfo(
                    name=channel.topic,
                    type=type_name,
                    serialization_format=channel.message_encoding,
                    offered_qos_profiles=channel.metadata.get("offered_qos_profiles", ""),
                    type_description_hash=channel.metadata.get("topic_type_hash", ""),
                ),
            )
            if schema is not None and type_name not in self.definitions:
                self.definitions[type_name] = schema.data.decode("utf-8", errors="replace")
        self.topic_counts = dict.fromkeys(self.topics, 0)
        for channel_id, count in self.index.channel_message_counts.items():
            topic = self._channel_topics.get(channel_id)
            if topic is not None:
                self.topic_counts[topic] += count
        self.start_ns = self.index.message_start_time
        self.end_ns = self.index.message_end_time
        chunks = self.index.chunk_indexes
        self._sorted_blocks: list[mcap.ChunkIndex | mcap.MessageRun] = sorted(
            [*chunks, *self.index.message_runs],
            key=lambda b: (b.message_start_time, _extent(b)[0]),
        )
        self.compressed_size = sum(c.compressed_size for c in chunks)
        self.uncompressed_size = sum(c.uncompressed_size for c in chunks)
        self.compression = ",".join(sorted({c.compression or "none" for c in chunks}))

    def close(self) -> None:
        """Close the file."""
        self._handle.close()

    def _channel_ids(self, topics: set[str] | None) -> set[int]:
        return {c for c, t in self._channel_topics.items() if topics is None or t in topics}

    def _blocks(
        self, start_ns: int | None, end_ns: int | None
    ) -> Iterator[mcap.ChunkIndex | mcap.MessageRun]:
        """Chunks (and runs of loose messages) that may hold messages in the time range."""
        for block in self._sorted_blocks:
            if start_ns is not None and block.message_end_time < start_ns:
                continue
            if end_ns is not None and block.message_start_time >= end_ns:
                continue
            yield block

    def _problem(self, block: mcap.ChunkIndex | mcap.MessageRun, what: str) -> None:
        offset, length = _extent(block)
        message = f"{self.path.name}: chunk at byte {offset} ({length} bytes) unreadable: {what}"
        if message not in self.problems:
            self.problems.append(message)

    def messages(
        self, topics: set[str] | None, start_ns: int | None, end_ns: int | None
    ) -> Iterator[BagMessage]:
        """Yield the messages in log-time order (ties in storage order)."""
        wanted = self._channel_ids(topics)
        if not wanted:
            return
        lower = start_ns if start_ns is not None else 0
        upper = end_ns if end_ns is not None else 1 << 64
        # Blocks are sorted by start time. A block that starts before the ones already taken
        # end overlaps them: such a group is merged; groups simply follow one another.
        group: list[tuple[int, Iterator[BagMessage]]] = []
        group_end = 0
        for block in self._blocks(start_ns, end_ns):
            if not _may_hold(block, wanted):
                continue
            if group and block.message_start_time >= group_end:
                yield from _merged(group)
                group = []
            group_end = max(group_end, block.message_end_time) if group else block.message_end_time
            group.append((_extent(block)[0], self._block_messages(block, wanted, lower, upper)))
        yield from _merged(group)

    def _block_messages(
        self, block: mcap.ChunkIndex | mcap.MessageRun, wanted: set[int], lower: int, upper: int
    ) -> Iterator[BagMessage]:
        """The messages of one block in log-time order, built one at a time as they are taken.

        Only the message index is ordered up front (numpy): a replay that takes the next message
        when it is due is not held up for the whole chunk's worth of objects.
        """
        try:
            chunk = mcap.read_chunk(self._handle, block)
        except (CorruptBagError, struct.error, UnicodeDecodeError) as exc:
            self._problem(block, str(exc))
            return
        parts = [entries for channel, entries in chunk.message_index.items() if channel in wanted]
        if not parts:
            return
        index = np.concatenate(parts) if len(parts) > 1 else parts[0]
        times = index["log_time"]
        index = index[(times >= lower) & (times < upper)]
        offsets = index["offset"][np.lexsort((index["offset"], index["log_time"]))].tolist()
        records = chunk.records
        size = len(records)
        channel_topics = self._channel_topics
        unpack = mcap.MESSAGE_RECORD_HEADER.unpack_from
        for offset in offsets:
            try:
                opcode, length, channel_id, sequence, log_time, publish_time = unpack(
                    records, offset
                )
            except struct.error:
                opcode = length = channel_id = 0
            end = offset + mcap.RECORD_HEADER.size + length
            if opcode != mcap.Opcode.MESSAGE or end > size or channel_id not in channel_topics:
                self._problem(block, f"message index points at no message (offset {offset})")
                return
            yield make_message(
                channel_topics[channel_id],
                records[offset + mcap.MESSAGE_DATA_OFFSET : end],
                log_time,
                publish_time,
                sequence,
            )

    def chunks(self, topics: set[str] | None) -> Iterator[BagChunk]:
        """Yield the chunks holding messages of ``topics`` (all when None), in file order."""
        wanted = self._channel_ids(topics)
        for block in sorted(self._sorted_blocks, key=_extent):
            if not _may_hold(block, wanted):
                continue
            try:
                data = mcap.read_chunk(self._handle, block)
            except (CorruptBagError, struct.error) as exc:
                self._problem(block, str(exc))
                continue
            by_topic: dict[str, list[np.ndarray]] = {}
            for channel_id, entries in data.message_index.items():
                if channel_id in wanted:
                    by_topic.setdefault(self._channel_topics[channel_id], []).append(entries)
            if by_topic:
                yield BagChunk(
                    self.path,
                    data.records,
                    {
                        topic: parts[0]
                        if len(parts) == 1
                        else np.sort(np.concatenate(parts), order="offset")
                        for topic, parts in by_topic.items()
                    },
                )


class Sqlite3File(StorageFile):
    """A rosbag2 SQLite3 (``.db3``) storage file, opened read-only and immutable.

    Untrusted like any input (:mod:`bagkit.bag.db3`): rows of the wrong types are skipped and
    reported in ``problems``; damage found while reading messages ends this file's messages
    with a problem, as an unreadable MCAP chunk does.
    """

    storage_identifier = "sqlite3"

    def __init__(self, path: Path) -> None:
        self.path = path
        self._db = db3.connect(path)
        try:
            contents = db3.read_contents(self._db, path)
        except BaseException:
            self._db.close()
            raise
        self._topic_ids = contents.topic_ids
        self.topics = contents.topics
        self.definitions = contents.definitions
        self.topic_counts = contents.topic_counts
        self.start_ns = contents.start_ns
        self.end_ns = contents.end_ns
        self.problems = [f"{path.name}: {problem}" for problem in contents.problems]

    def close(self) -> None:
        """Close the database."""
        self._db.close()

    def messages(
        self, topics: set[str] | None, start_ns: int | None, end_ns: int | None
    ) -> Iterator[BagMessage]:
        """Yield the messages in timestamp order (ties by row id); no publish time in SQLite3."""
        wanted = [i for i, t in self._topic_ids.items() if topics is None or t in topics]
        if not wanted:
            return
        lower = start_ns if start_ns is not None else db3.INT64_MIN
        upper = end_ns if end_ns is not None else db3.INT64_MAX
        read = 0
        try:
            for topic_id, timestamp, data in db3.iter_messages(self._db, wanted, lower, upper):
                read += 1
                yield make_message(self._topic_ids[topic_id], data, timestamp, timestamp, 0)
        except sqlite3.Error as exc:
            problem = f"{self.path.name}: unreadable after {read} messages ({exc})"
            if problem not in self.problems:
                self.problems.append(problem)


def open_storage_file(path: Path) -> StorageFile:
    """Open one storage file by its content (MCAP or SQLite3 magic).

    Raises:
        NotABagError: neither MCAP nor SQLite3.
    """
    with open(path, "rb") as f:
        head = f.read(len(SQLITE_MAGIC))
    if head.startswith(mcap.MAGIC):
        return McapFile(path)
    if head == SQLITE_MAGIC:
        return Sqlite3File(path)
    raise NotABagError(f"{path}: neither an MCAP nor a SQLite3 file")
