"""``bagkit info``: what a bag holds, from summaries and indexes only (no message is read)."""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from bagkit.bag.rates import message_rate
from bagkit.bag.reader import BagReader


@dataclass(frozen=True, slots=True)
class TopicSummary:
    """One topic of :class:`BagInfo`; ``rate_hz`` is :func:`message_rate` (None below three
    messages), over the exact span or its chunk bounds (:attr:`BagInfo.exact_rates`)."""

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
    chunks; of the files in rosbag2's file compression); ``compression_format`` and
    ``compression_mode`` are rosbag2's (``zstd``, ``file``/``message``; ``""`` when it did not
    compress), ``chunk_compression`` the storage's own chunks' (``""`` for sqlite3);
    ``summary`` is False when a file had to be salvaged (no MCAP summary).
    ``exact_rates`` is False when each topic's span came from the chunk indexes (a bag in
    storage, without ``exact_rates=True``): from the start of the first chunk holding the topic
    to the end of the last, which holds the true span, so each rate is a lower bound.
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
    compression_format: str
    compression_mode: str
    chunk_compression: str
    summary: bool
    exact_rates: bool
    custom_data: dict[str, str]
    problems: list[str]

    def to_dict(self) -> dict[str, Any]:
        """The JSON form: the keys documented in docs/bag-format.md."""
        return asdict(self)


def bag_info(
    path: str | Path, *, check_crc: bool = True, exact_rates: bool | None = None
) -> BagInfo:
    """Describe a bag (directory, split bag, single ``.mcap`` or ``.db3``) like ``ros2 bag info``.

    ``check_crc``: check the CRC of the chunks a salvage scan opens (see ``BagReader``).
    ``exact_rates``: read the Message Index records of the chunks at each topic's ends; None:
    for a bag on disk, not for one in storage (see :meth:`BagReader.topic_spans`).

    Raises:
        BagError: the path is missing, not a bag, or in a foreign storage format (a bag
            without messages is described, its topics with count 0, as ``ros2 bag info`` does).
    """
    with BagReader(path, check_crc=check_crc, allow_empty=True) as bag:
        duration_s = (bag.end_ns - bag.start_ns) / 1e9
        exact = not bag.in_storage if exact_rates is None else exact_rates
        spans = bag.topic_spans(message_indexes=exact)
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
            compression_format="zstd" if bag.compression_mode else "",
            compression_mode=bag.compression_mode,
            chunk_compression=bag.chunk_compression,
            summary=bag.has_summary,
            exact_rates=exact or "mcap" not in bag.storage.split(","),
            custom_data=dict(bag.metadata.custom_data) if bag.metadata else {},
            problems=bag.problems,
        )
