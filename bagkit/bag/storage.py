"""The storage files of a bag, read in log-time order: what each back-end provides.

The back-ends: :mod:`bagkit.bag.mcap_file` (MCAP) and :mod:`bagkit.bag.sqlite3_file` (SQLite3,
imported only when a ``.db3`` file is opened: ``sqlite3`` is not free at start-up).
"""

from __future__ import annotations

import abc
from collections.abc import Iterator
from pathlib import Path

from bagkit.bag.types import BagMessage, TopicInfo

SQLITE_MAGIC = b"SQLite format 3\x00"


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
