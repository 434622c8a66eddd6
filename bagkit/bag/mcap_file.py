"""An MCAP storage file of a bag: topics and counts from its index, messages and chunks.

A chunk that cannot be read (damaged, too large, fails its CRC) costs its own messages only:
they are counted in ``problems`` and the rest of the file is read.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, BinaryIO

from mcap.well_known import Profile

from bagkit.bag.definitions import DEFINITION_ENCODINGS, canonical_type_name
from bagkit.bag.errors import ChunkError, CorruptBagError, NotABagError, UnsupportedStorageError
from bagkit.bag.mcap_messages import (
    MERGE_BUDGET_CHUNKS,
    chunk_messages,
    in_log_time_order,
    message_at,
)
from bagkit.bag.mcapio import (
    DEFAULT_MAX_CHUNK_SIZE,
    Block,
    ChunkContents,
    Source,
    extent,
    indexed,
    may_hold,
    read_chunk,
    read_file_index,
    unreadable_chunk,
)
from bagkit.bag.mcapio.message_index import (
    Span,
    channel_log_times,
    channel_spans,
    largest_messages,
    read_message_indexes,
    widen,
)
from bagkit.bag.mcapio.records import (
    RECORD_HEADER,
    ROSBAG2_METADATA,
    parse_metadata,
)
from bagkit.bag.mcapio.summary import read_header
from bagkit.bag.messages import BagMessage, TopicInfo
from bagkit.bag.storage import BagChunk
from bagkit.storage.urls import is_url

if TYPE_CHECKING:
    import numpy as np

    from bagkit.bag.mcapio.latest import Latest


def _in_range(block: Block, start_ns: int | None, end_ns: int | None) -> bool:
    """Whether a chunk (or run of loose messages) may hold messages logged in the range.

    ``Window.overlaps`` of the block's times; not imported from ``bagkit.selection.windows``,
    whose time parsing ``bagkit info`` would then load at start."""
    if start_ns is not None and block.message_end_time < start_ns:
        return False
    return end_ns is None or block.message_start_time < end_ns


class McapFile:
    """An MCAP storage file (summary and indexes when present, salvage otherwise).

    A :class:`~bagkit.bag.storage.StorageFile`: nothing is read before :meth:`open`.

    Args:
        path: the file.
        check_crc: check each chunk's CRC when it is read (a mismatch loses that chunk).
        max_chunk_size: the largest uncompressed chunk read (a larger one is a problem).
    """

    storage_identifier = "mcap"

    def __init__(
        self, path: Path, *, check_crc: bool = True, max_chunk_size: int = DEFAULT_MAX_CHUNK_SIZE
    ) -> None:
        self.path = path
        self.check_crc = check_crc
        self.max_chunk_size = max_chunk_size
        self.topics: dict[str, TopicInfo] = {}
        self.definitions: dict[str, str] = {}
        self.topic_definitions: dict[str, str] = {}
        self.topic_counts: dict[str, int] = {}
        self.start_ns = self.end_ns = 0
        self.problems: list[str] = []
        self.has_summary = False
        self.compression = ""
        self.compressed_size = self.uncompressed_size = 0
        self._handle: BinaryIO | None = None
        self._channel_topics: dict[int, str] = {}

    def open(self) -> None:
        """Read the summary (or salvage the file without one).

        Raises:
            NotABagError, CorruptBagError: not an MCAP file, or its header is unreadable.
            UnsupportedStorageError: a profile other than ``ros2``.
        """
        self._handle = self.path.open("rb")  # closed in close(); a UrlPath's reads by range
        try:
            self._source = Source(self._handle, self.path.name)
            # In storage the header is a request of its own: read when the summary is not
            # enough, or to check the profile of a file whose channels are not all CDR (a ROS
            # 2 bag's are; another profile's are not).
            in_storage = is_url(self.path)
            self.index = read_file_index(
                self._source,
                check_crc=self.check_crc,
                max_chunk_size=self.max_chunk_size,
                header_first=not in_storage,
            )
            header = self.index.header
            channels = self.index.channels.values()
            if header is None and any(c.message_encoding != "cdr" for c in channels):
                header = read_header(self._source)
        except (NotABagError, CorruptBagError) as exc:
            raise type(exc)(f"{self.path}: {exc}") from exc
        profile = header.profile if header is not None else Profile.ROS2
        if profile not in (Profile.ROS2, ""):
            raise UnsupportedStorageError(f"{self.path}: MCAP profile {profile!r} is not ROS 2")
        self.problems = list(self.index.problems)
        self.has_summary = self.index.summary
        self._describe_topics()
        self.start_ns = self.index.message_start_time
        self.end_ns = self.index.message_end_time
        chunks = self.index.chunk_indexes
        self.compressed_size = sum(chunks.compressed_sizes)
        self.uncompressed_size = sum(chunks.uncompressed_sizes)
        names = {chunks.compressions[i] for i in set(chunks.compression_ids)}
        self.compression = ",".join(sorted(name or "none" for name in names))

    def _describe_topics(self) -> None:
        """Topics, definitions and counts from the channels and schemas."""
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
            if schema is not None and schema.encoding in DEFINITION_ENCODINGS:
                text = schema.data.decode("utf-8", errors="replace")
                # One text per type; a topic whose schema holds another text keeps its own.
                if self.definitions.setdefault(type_name, text) != text:
                    self.topic_definitions.setdefault(channel.topic, text)
        self.topic_counts = dict.fromkeys(self.topics, 0)
        for channel_id, count in self.index.channel_message_counts.items():
            topic = self._channel_topics.get(channel_id)
            if topic is not None:
                self.topic_counts[topic] += count

    def close(self) -> None:
        """Close the file."""
        if self._handle is not None:
            self._handle.close()

    def rosbag2_metadata(self) -> str | None:
        """The ``metadata.yaml`` text the file carries (the ``serialized_metadata`` of its
        ``rosbag2`` Metadata record, as rosbag2's MCAP plugin and rosbags write it); None
        without one or when it cannot be read."""
        records = [m for m in self.index.metadata if m.name == ROSBAG2_METADATA]
        for entry in self.index.metadata_indexes:
            if entry.name == ROSBAG2_METADATA and not records:
                content = self._source.read(entry.offset, entry.length)[RECORD_HEADER.size :]
                try:
                    records.append(parse_metadata(content))
                except (CorruptBagError, ValueError, UnicodeDecodeError):
                    return None
        return records[0].metadata.get("serialized_metadata") if records else None

    def topic_spans(self, *, message_indexes: bool = True) -> dict[str, Span]:
        """(first, last) log time of each topic with messages, from the Message Index records
        of the chunks at its ends; with ``message_indexes=False`` the bounds of those chunks
        (the summary's chunk indexes only).

        Blocks without them (salvaged chunks, loose messages) widen every topic with messages
        to their bounds: reading them would cost what ``bagkit info`` avoids.
        """
        spans: dict[str, Span] = {}
        with_messages = [t for t, count in self.topic_counts.items() if count]
        chunks = self.index.chunk_indexes
        starts, ends = chunks.start_times, chunks.end_times
        for row in range(len(chunks)):
            start, end = starts[row], ends[row]
            if start > end:
                continue  # no messages
            if not chunks.indexed(row):
                for topic in with_messages:
                    widen(spans, topic, start, end)
            elif not message_indexes:
                for channel in chunks.channels(row):
                    if self.topic_counts.get(self._channel_topics.get(channel, ""), 0):
                        widen(spans, self._channel_topics[channel], start, end)
        for run in self.index.message_runs:
            for topic in with_messages:
                widen(spans, topic, run.message_start_time, run.message_end_time)
        if not message_indexes:
            return spans
        for channel, (first, last) in channel_spans(self._source, chunks).items():
            if channel in self._channel_topics:
                widen(spans, self._channel_topics[channel], first, last)
        return spans

    def index_log_times(self, topic: str) -> np.ndarray | None:
        """The log times of ``topic``'s messages from the Message Index records (no chunk
        decompressed), in no order; None when a block has none or they are damaged."""
        if self.index.message_runs:
            return None  # loose messages: only their records tell
        chunks = self.index.chunk_indexes
        return channel_log_times(self._source, chunks, self._channel_ids({topic}))

    def _channel_ids(self, topics: set[str] | None) -> set[int]:
        return {c for c, t in self._channel_topics.items() if topics is None or t in topics}

    def _blocks(self, start_ns: int | None, end_ns: int | None) -> Iterator[Block]:
        """Chunks (and runs of loose messages) that may hold messages in the time range."""
        for block in self.index.blocks():
            if _in_range(block, start_ns, end_ns):
                yield block

    def _problem(self, block: Block, what: str) -> None:
        message = unreadable_chunk(self.path.name, self._source, block, what)
        if message not in self.problems:
            self.problems.append(message)

    def _read(self, block: Block) -> ChunkContents | None:
        """A block's contents, or None (and a problem) when it cannot be read."""
        try:
            return read_chunk(
                self._source, block, check_crc=self.check_crc, max_size=self.max_chunk_size
            )
        except ChunkError as exc:
            self._problem(block, str(exc))
            return None

    def messages(
        self, topics: set[str] | None, start_ns: int | None, end_ns: int | None
    ) -> Iterator[BagMessage]:
        """The messages in log-time order (ties in storage order), read as they are taken."""
        wanted = self._channel_ids(topics)
        if not wanted:
            return iter(())
        window = (
            start_ns if start_ns is not None else 0,
            end_ns if end_ns is not None else 1 << 64,
        )
        return in_log_time_order(
            (b for b in self._blocks(start_ns, end_ns) if may_hold(b, wanted)),
            lambda block: self._block_messages(block, wanted, window),
            self.max_chunk_size,
            self._out_of_order,
        )

    def _out_of_order(self) -> None:
        message = (
            f"{self.path.name}: chunks overlapping in time beyond {MERGE_BUDGET_CHUNKS} chunks' "
            "worth of memory: some messages come out of log-time order"
        )
        if message not in self.problems:
            self.problems.append(message)

    def _block_messages(
        self, block: Block, wanted: set[int], window: tuple[int, int]
    ) -> Iterator[BagMessage]:
        """The messages of one block in log-time order (:func:`chunk_messages`)."""

        def lost(count: int) -> None:
            self.problems.append(
                f"{self.path.name}: chunk at byte {extent(block)[0]}: {count} message index "
                "entries point at no message: those messages are lost"
            )

        return chunk_messages(lambda: self._read(block), wanted, window, self._channel_topics, lost)

    def last_messages(self, topics: set[str], before_ns: int) -> dict[str, BagMessage]:
        """The last message with ``log_time < before_ns`` of each of ``topics`` that has one.

        Found from the Message Index records of the chunks near ``before_ns`` (see
        :mod:`bagkit.bag.mcapio.latest`); only the chunks holding the messages are read.
        """
        from bagkit.bag.mcapio.latest import latest_before  # a late start's only: not at start

        found: dict[str, tuple[tuple[int, int, int], BagMessage]] = {}
        latest = latest_before(
            self.index.blocks(), self._channel_ids(topics), before_ns, self._block_index
        )
        chunks: dict[int, ChunkContents | None] = {}  # by file offset: each read once
        for channel, where in latest.items():
            at = extent(where.block)[0]
            if at not in chunks:
                chunks[at] = self._read(where.block)
            message = self._message_at(chunks[at], where)
            topic = self._channel_topics[channel]
            if message is not None and (topic not in found or where.key() > found[topic][0]):
                found[topic] = (where.key(), message)
        return {topic: message for topic, (_, message) in found.items()}

    def largest_messages(self, topics: set[str]) -> dict[str, int] | None:
        """Payload bytes of each topic's largest message in the last chunk holding it, from that
        chunk's Message Index records (:func:`~bagkit.bag.mcapio.message_index.largest_messages`:
        no numpy, no decompression, may be over); None when such a chunk has no Message Index
        records (salvaged, loose messages) or they are damaged.
        """
        wanted = self._channel_ids(topics)
        last: dict[int, Block] = {}  # channel -> the block holding its latest messages
        for block in self.index.blocks():  # ties in end time: the first block
            held = wanted.intersection(block.message_index_offsets) if indexed(block) else wanted
            for channel in held:
                if channel not in last or block.message_end_time > last[channel].message_end_time:
                    last[channel] = block
        found: dict[str, int] = {}
        for block in {id(b): b for b in last.values()}.values():
            if not indexed(block):
                return None
            channels = {c for c, b in last.items() if b is block}
            try:
                sizes = largest_messages(self._source, block, channels)
            except CorruptBagError:
                return None
            for channel, size in sizes.items():
                topic = self._channel_topics[channel]
                found[topic] = max(found.get(topic, 0), size)
        return found

    def _block_index(self, block: Block, channels: set[int]) -> dict[int, np.ndarray] | None:
        """The message index of a block: its Message Index records, else the chunk read."""
        if indexed(block):
            if channels.isdisjoint(block.message_index_offsets):
                return {}
            try:
                return read_message_indexes(self._source, block)
            except CorruptBagError:
                pass  # read the chunk itself
        chunk = self._read(block)
        return chunk.message_index if chunk is not None else None

    def _message_at(self, chunk: ChunkContents | None, where: Latest) -> BagMessage | None:
        """The Message record at ``where`` in its block's ``chunk`` (None when unreadable, and
        a problem when no message is there)."""
        if chunk is None:
            return None
        message = message_at(chunk, where.offset, self._channel_topics)
        if message is not None:
            return message
        self.problems.append(
            f"{self.path.name}: chunk at byte {extent(where.block)[0]}: a message index entry "
            "points at no message: that message is lost"
        )
        return None

    def chunks(
        self, topics: set[str] | None, start_ns: int | None = None, end_ns: int | None = None
    ) -> Iterator[BagChunk]:
        """Yield the chunks holding messages of ``topics`` (all when None), in file order,
        those wholly outside ``start_ns <= log_time < end_ns`` left unread."""
        import numpy as np

        wanted = self._channel_ids(topics)
        for block in self.index.blocks_in_file_order():
            if not may_hold(block, wanted) or not _in_range(block, start_ns, end_ns):
                continue
            data = self._read(block)
            if data is None:
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
                    self.problems,
                )
