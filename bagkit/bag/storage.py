"""The storage files of a bag, read in log-time order: what each provides, and SQLite3 files.

MCAP files: :mod:`bagkit.bag.mcap_file`.
"""

from __future__ import annotations

import abc
import sqlite3
from collections.abc import Iterator
from pathlib import Path

from bagkit.bag.definitions import canonical_type_name
from bagkit.bag.errors import NotABagError
from bagkit.bag.types import BagMessage, TopicInfo, make_message

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


class Sqlite3File(StorageFile):
    """A rosbag2 SQLite3 (``.db3``) storage file, opened read-only and immutable."""

    storage_identifier = "sqlite3"

    def __init__(self, path: Path) -> None:
        self.path = path
        self.problems = []
        # immutable=1: no -shm/-wal side files next to bags in read-only folders.
        uri = f"file:{path.resolve()}?mode=ro&immutable=1"
        try:
            self._db = sqlite3.connect(uri, uri=True)
            tables = {row[0] for row in self._db.execute("SELECT name FROM sqlite_master")}
        except sqlite3.DatabaseError as exc:
            raise NotABagError(f"{path}: not a SQLite3 database ({exc})") from exc
        if not {"topics", "messages"} <= tables:
            self._db.close()
            raise NotABagError(f"{path}: SQLite3 file without rosbag2 tables")
        columns = {row[1] for row in self._db.execute("PRAGMA table_info(topics)")}
        hash_column = "type_description_hash" if "type_description_hash" in columns else "''"
        qos_column = "offered_qos_profiles" if "offered_qos_profiles" in columns else "''"
        self._topic_ids: dict[int, str] = {}
        self.topics = {}
        query = (
            f"SELECT id, name, type, serialization_format, {qos_column}, {hash_column} FROM topics"
        )
        for topic_id, name, type_name, fmt, qos, type_hash in self._db.execute(query):
            self._topic_ids[topic_id] = name
            self.topics[name] = TopicInfo(name, canonical_type_name(type_name), fmt, qos, type_hash)
        self.definitions = {}
        if "message_definitions" in tables:
            for type_name, encoding, text in self._db.execute(
                "SELECT topic_type, encoding, encoded_message_definition FROM message_definitions"
            ):
                if encoding == "ros2msg" and text:
                    self.definitions[canonical_type_name(type_name)] = text
        self.topic_counts = dict.fromkeys(self.topics, 0)
        for topic_id, count in self._db.execute(
            "SELECT topic_id, COUNT(*) FROM messages GROUP BY topic_id"
        ):
            if topic_id in self._topic_ids:
                self.topic_counts[self._topic_ids[topic_id]] += count
        start, end = self._db.execute(
            "SELECT MIN(timestamp), MAX(timestamp) FROM messages"
        ).fetchone()
        self.start_ns = int(start or 0)
        self.end_ns = int(end or 0)

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
        marks = ",".join("?" * len(wanted))
        query = (
            f"SELECT topic_id, timestamp, data FROM messages WHERE topic_id IN ({marks}) "
            "AND timestamp >= ? AND timestamp < ? ORDER BY timestamp, id"
        )
        lower = start_ns if start_ns is not None else 0
        upper = end_ns if end_ns is not None else (1 << 63) - 1
        for topic_id, timestamp, data in self._db.execute(query, (*wanted, lower, upper)):
            yield make_message(self._topic_ids[topic_id], bytes(data), timestamp, timestamp, 0)
