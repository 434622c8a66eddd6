"""The SQLite3 back-end: a rosbag2 ``.db3`` storage file (:mod:`bagkit.bag.db3` reads it)."""

from __future__ import annotations

import sqlite3
from collections.abc import Iterator
from pathlib import Path

from bagkit.bag import db3
from bagkit.bag.storage import StorageFile
from bagkit.bag.types import BagMessage, make_message


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
        self.topic_spans = contents.topic_spans
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
