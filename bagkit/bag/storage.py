"""The storage files of a bag: what every back-end provides, and the chunks it hands out.

The back-ends, side by side: :mod:`bagkit.bag.mcap_file` (MCAP) and
:mod:`bagkit.bag.sqlite3_file` (SQLite3, imported only when a ``.db3`` file is opened:
``sqlite3`` is not free at start-up). The reader and ``bagkit info`` use them through
:class:`StorageFile` only.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Protocol

from bagkit.bag.mcapio.chunks import payload_spans
from bagkit.bag.mcapio.message_index import Span
from bagkit.bag.messages import BagMessage, TopicInfo

if TYPE_CHECKING:
    import numpy as np

SQLITE_MAGIC = b"SQLite format 3\x00"


@dataclass(frozen=True, slots=True)
class BagChunk:
    """One chunk, decompressed, with where each of its topics' messages are.

    ``message_index[topic]`` is a ``message_index_dtype`` array (``log_time``, ``offset`` of
    the Message record in ``records``, as stored); :meth:`payloads` gives the checked payload
    spans.
    """

    file: Path
    records: bytes
    message_index: dict[str, np.ndarray]
    problems: list[str] = field(default_factory=list, repr=False, compare=False)

    def payloads(self, topic: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(log_times, starts, lengths)`` (int64) of each payload of ``topic`` in ``records``.

        A message whose index entry points outside the chunk, or at no whole Message record,
        is left out and counted in ``problems``.
        """
        entries = self.message_index.get(topic)
        if entries is None:
            import numpy as np

            return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.int64)
        log_times, starts, lengths, dropped = payload_spans(self.records, entries)
        if dropped:
            self.problems.append(
                f"{self.file.name}: {dropped} messages of {topic} indexed outside their chunk "
                "(damaged message index): lost"
            )
        return log_times, starts, lengths


class StorageFile(Protocol):
    """One storage file of a bag, whatever its format.

    Constructing one does no I/O; :meth:`open` reads what the file holds (topics, counts,
    times) and fills the attributes, and raises ``NotABagError``/``CorruptBagError`` (the
    file is unusable) or ``UnsupportedStorageError``. Damage found later (an unreadable chunk,
    a bad page) is appended to ``problems``, never raised.

    Attributes:
        path: the file.
        storage_identifier: rosbag2's name of the format (``mcap``, ``sqlite3``).
        topics: by name; ``definitions``: ros2msg text by type name.
        topic_counts: messages per topic (every topic of ``topics``, 0 included).
        start_ns, end_ns: log times of the first and last message (0 without messages).
        problems: what could not be read, one line each, starting with the file's name.
        has_summary: False when the file had to be salvaged (an MCAP file without summary).
        compression: the chunk compressions used (``zstd``, ``lz4``, ``none``, comma-separated;
            ``""`` without chunks); ``compressed_size``, ``uncompressed_size``: chunk bytes as
            stored and decompressed (0 without chunks).
    """

    path: Path
    storage_identifier: str
    topics: dict[str, TopicInfo]
    definitions: dict[str, str]
    topic_counts: dict[str, int]
    start_ns: int
    end_ns: int
    problems: list[str]
    has_summary: bool
    compression: str
    compressed_size: int
    uncompressed_size: int

    def open(self) -> None:
        """Read what the file holds (the only I/O before messages are asked for)."""

    def close(self) -> None:
        """Release the file (also when :meth:`open` was not called or failed)."""

    def messages(
        self, topics: set[str] | None, start_ns: int | None, end_ns: int | None
    ) -> Iterator[BagMessage]:
        """Yield the messages of ``topics`` (all when None) with ``start_ns <= log_time <
        end_ns`` in log-time order (ties in storage order)."""

    def last_messages(self, topics: set[str], before_ns: int) -> dict[str, BagMessage]:
        """The last message with ``log_time < before_ns`` of each of ``topics`` that has one
        (ties: the one stored last), found from indexes, not by reading from the start."""

    def chunks(self, topics: set[str] | None) -> Iterator[BagChunk]:
        """Yield the chunks holding messages of ``topics`` in file order (none: no chunks)."""

    def topic_spans(self) -> dict[str, Span]:
        """(first, last) log time of each topic with messages, from indexes (no message read).

        Where no index tells (salvaged chunks without Message Index records), the bounds of
        the chunks that may hold the topic.
        """

    def index_log_times(self, topic: str) -> np.ndarray | None:
        """The log times (int64 ns, in no order) of ``topic``'s messages from indexes, no
        message read; None when an index is missing or damaged (read the messages)."""
