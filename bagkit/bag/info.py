"""``bagkit info``: what a bag holds, from summaries and indexes only (no message is read)."""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

from bagkit.bag.errors import CorruptBagError
from bagkit.bag.mcap_file import McapFile
from bagkit.bag.mcapio.records import ChunkIndex
from bagkit.bag.reader import BagReader
from bagkit.bag.storage import StorageFile

if TYPE_CHECKING:
    from bagkit.bag.sqlite3_file import Sqlite3File

Span = tuple[int, int]


def message_rate(count: int, first_ns: int | None, last_ns: int | None) -> float | None:
    """A topic's rate in Hz: (count - 1) / (last - first log time), None below two messages.

    The one definition every command reports (info, stats, record): ``count - 1`` intervals
    between the first and the last message, so a steady 10 Hz topic is 10.0 Hz whatever the
    bag's length. None when it cannot be measured (fewer than two messages, or no time span).
    """
    if count < 2 or first_ns is None or last_ns is None or last_ns <= first_ns:
        return None
    return (count - 1) * 1e9 / (last_ns - first_ns)


@dataclass(frozen=True, slots=True)
class TopicSummary:
    """One topic of :class:`BagInfo`; ``rate_hz`` is :func:`message_rate` (None below two)."""

    topic: str
    type: str
    count: int
    rate_hz: float | None
    serialization_format: str
    offered_qos_profiles: str


@dataclass(frozen=True, slots=True)
class BagInfo:
    """What ``bagkit info`` reports; ``to_dict()`` is its JSON.

    ``compression_ratio`` is uncompressed / compressed chunk bytes (1.0 without compression or
    chunks); ``summary`` is False when a file had to be salvaged (no MCAP summary).
    """

    path: str
    files: list[str]
    storage: str
    size_bytes: int
    start_ns: int
    end_ns: int
    duration_s: float
    message_count: int
    topics: list[TopicSummary]
    compression: str
    compression_ratio: float
    summary: bool
    custom_data: dict[str, str]
    problems: list[str]

    def to_dict(self) -> dict[str, Any]:
        """The JSON form: the keys documented in docs/bag-format.md."""
        return asdict(self)


def _widen(spans: dict[str, Span], topic: str, first: int, last: int) -> None:
    old = spans.get(topic)
    spans[topic] = (first, last) if old is None else (min(old[0], first), max(old[1], last))


def _mcap_spans(storage: McapFile, spans: dict[str, Span]) -> None:
    """First and last log time per topic from the Message Index records of the chunks.

    Only the chunks that can hold a topic's first or last message are opened: the index of a
    chunk starting after the earliest time found (or ending before the latest) cannot.
    """
    topics = storage._channel_topics
    indexed = [c for c in storage.index.chunk_indexes if c.message_index_offsets]
    unindexed = [b for b in storage._sorted_blocks if b not in indexed]
    for block in unindexed:  # salvaged data without indexes: the block's bounds
        for topic in set(topics.values()):
            if storage.topic_counts.get(topic):
                _widen(spans, topic, block.message_start_time, block.message_end_time)
    found: dict[int, Span] = {}
    by_start = sorted(indexed, key=lambda c: c.message_start_time)
    by_end = sorted(indexed, key=lambda c: -c.message_end_time)
    for chunks, earliest in ((by_start, True), (by_end, False)):
        seen: set[int] = set()
        for chunk in chunks:
            # Chunks are visited in bound order: once a channel's time is beyond the next
            # chunk's bound, no later chunk can hold an earlier (later) message of it.
            wanted = [
                c
                for c in chunk.message_index_offsets
                if c not in seen
                or (chunk.message_start_time < found[c][0] if earliest else False)
                or (chunk.message_end_time > found[c][1] if not earliest else False)
            ]
            if wanted:
                _read_times(storage, chunk, wanted, found)
                seen.update(c for c in wanted if c in found)
    for channel, (first, last) in found.items():
        if channel in topics:
            _widen(spans, topics[channel], first, last)


def _read_times(
    storage: McapFile, chunk: ChunkIndex, channels: list[int], found: dict[int, Span]
) -> None:
    try:
        spans = storage.message_index_times(chunk, channels)
    except CorruptBagError:
        return
    for channel, (first, last) in spans.items():
        old = found.get(channel, (first, last))
        found[channel] = (min(old[0], first), max(old[1], last))


def _sqlite_spans(storage: Sqlite3File, spans: dict[str, Span]) -> None:
    for topic, (first, last) in storage.topic_spans.items():
        _widen(spans, topic, first, last)


def topic_spans(storage_files: list[StorageFile]) -> dict[str, Span]:
    """(first, last) log time of each topic with messages, from indexes (no message read)."""
    spans: dict[str, Span] = {}
    for storage in storage_files:
        if isinstance(storage, McapFile):
            _mcap_spans(storage, spans)
        elif storage.storage_identifier == "sqlite3":
            _sqlite_spans(cast("Sqlite3File", storage), spans)
    return spans


def bag_info(path: str | Path, *, check_crc: bool = True) -> BagInfo:
    """Describe a bag (directory, split bag, single ``.mcap`` or ``.db3``) like ``ros2 bag info``.

    ``check_crc``: check the CRC of the chunks a salvage scan opens (see ``BagReader``).

    Raises:
        BagError: the path is missing, not a bag, empty, or in a foreign storage format.
    """
    with BagReader(path, check_crc=check_crc) as bag:
        duration_s = (bag.end_ns - bag.start_ns) / 1e9
        spans = topic_spans(bag._storage)
        topics = [
            TopicSummary(
                topic=name,
                type=topic.type,
                count=bag.topic_counts[name],
                rate_hz=message_rate(bag.topic_counts[name], *spans.get(name, (None, None))),
                serialization_format=topic.serialization_format,
                offered_qos_profiles=topic.offered_qos_profiles,
            )
            for name, topic in sorted(bag.topics.items())
        ]
        compressed, uncompressed = bag.compressed_size, bag.uncompressed_size
        return BagInfo(
            path=str(bag.path),
            files=[str(f) for f in bag.files],
            storage=bag.storage,
            size_bytes=bag.size_bytes,
            start_ns=bag.start_ns,
            end_ns=bag.end_ns,
            duration_s=duration_s,
            message_count=bag.message_count,
            topics=topics,
            compression=bag.compression,
            compression_ratio=uncompressed / compressed if compressed else 1.0,
            summary=bag.has_summary,
            custom_data=dict(bag.metadata.custom_data) if bag.metadata else {},
            problems=bag.problems,
        )
