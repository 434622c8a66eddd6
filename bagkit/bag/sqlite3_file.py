"""The SQLite3 back-end: a rosbag2 ``.db3`` storage file, read as untrusted input.

A ``.db3`` file is a program as much as data: views and generated columns are evaluated on
read (an infinite recursive view, a ``zeroblob(1e9)`` column). Only real tables with plain
columns are read; rows whose values have the wrong type (text timestamps, BLOB topic names,
NULLs) are skipped and counted, not decoded; SQLite errors while opening become bag errors,
and damage found while reading messages ends this file's messages with a problem, as an
unreadable MCAP chunk does. Imported only when a ``.db3`` file is opened (``sqlite3`` is not
free at start-up).
"""

from __future__ import annotations

import sqlite3
import threading
from pathlib import Path
from typing import TYPE_CHECKING
from urllib.request import pathname2url

from bagkit.bag.action_definitions import split_action_part
from bagkit.bag.definitions import DEFINITION_ENCODINGS, canonical_type_name
from bagkit.bag.errors import CorruptBagError, NotABagError
from bagkit.bag.mcapio.message_index import Span, widen
from bagkit.bag.messages import TopicInfo
from bagkit.bag.sqlite3_reading import VALID_ROW, Sqlite3Reading
from bagkit.bag.storage import PayloadFilter
from bagkit.words import counted

if TYPE_CHECKING:
    import numpy as np

# Columns read from each table; the first two tables are required, message_definitions is not.
TOPIC_COLUMNS = ("id", "name", "type", "serialization_format")
MESSAGE_COLUMNS = ("topic_id", "timestamp", "data")
DEFINITION_COLUMNS = ("topic_type", "encoding", "encoded_message_definition")
_OPTIONAL_TOPIC_COLUMNS = ("offered_qos_profiles", "type_description_hash")
# Up to this many topic ids, counting at open filters per topic instead of grouping.
FILTERED_COUNT_TOPICS = 4
# From this many row ids on, counting at open scans two halves at once.
PARALLEL_COUNT_ROWS = 200_000


def connect(path: Path) -> sqlite3.Connection:
    """Open read-only and immutable (no -shm/-wal side files next to bags in read-only folders).

    The path is URL-quoted: a ``?`` or ``#`` in a bag's name would otherwise end the file name.
    """
    uri = f"file:{pathname2url(str(path.resolve()))}?mode=ro&immutable=1"
    try:
        # Not same-thread: bulk readers read chunks ahead in a thread (one user at a time).
        db = sqlite3.connect(uri, uri=True, check_same_thread=False)
    except sqlite3.Error as exc:
        raise NotABagError(f"{path}: not a SQLite3 database ({exc})") from exc
    db.text_factory = _text
    return db


def _owner_type(type_name: str) -> str:
    """The type rosbag2 stores the definition of ``type_name`` under: ``pkg/srv/Name`` for a
    service event, ``pkg/action/Name`` for an action's part, else ``type_name``."""
    package, _, name = type_name.rpartition("/")
    if package.endswith("/srv") and name.endswith("_Event"):
        return type_name.removesuffix("_Event")
    part = split_action_part(name) if package.endswith("/action") else None
    return f"{package}/{part[0]}" if part is not None else type_name


class _NotUtf8(bytes):
    """TEXT that is not UTF-8: not a str, so the row holding it is skipped as of a wrong type."""


def _text(raw: bytes) -> str | _NotUtf8:
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError:
        return _NotUtf8(raw)


def _table_columns(db: sqlite3.Connection) -> dict[str, set[str]]:
    """The plain columns of each real table (views and generated columns left out)."""
    tables = [row[0] for row in db.execute("SELECT name FROM sqlite_master WHERE type = 'table'")]
    return {
        table: {row[0] for row in db.execute("SELECT name FROM pragma_table_info(?)", (table,))}
        for table in tables
        if isinstance(table, str)
    }


def _row_id_halves(db: sqlite3.Connection) -> tuple[str, str] | None:
    """Conditions on the row id that split ``messages`` in two halves (None: a table under
    :data:`PARALLEL_COUNT_ROWS` row ids); each end found in the row id b-tree alone."""
    (first,) = db.execute("SELECT min(rowid) FROM messages").fetchone()
    (last,) = db.execute("SELECT max(rowid) FROM messages").fetchone()
    if (
        not isinstance(first, int)
        or not isinstance(last, int)
        or last - first < PARALLEL_COUNT_ROWS
    ):
        return None
    middle = first + (last - first) // 2
    return f" AND rowid <= {middle}", f" AND rowid > {middle}"


def _missing_columns(columns: dict[str, set[str]]) -> str:
    """What a rosbag2 reader needs and the file lacks ('' when nothing), for the error line."""
    needed = {"topics": TOPIC_COLUMNS, "messages": MESSAGE_COLUMNS}
    missing = []
    for table, names in needed.items():
        if table not in columns:
            missing.append(f"table {table}")
        else:
            missing += [f"column {table}.{n}" for n in names if n not in columns[table]]
    return ", ".join(missing)


class Sqlite3File(Sqlite3Reading):
    """A rosbag2 SQLite3 (``.db3``) storage file, opened read-only and immutable.

    A :class:`~bagkit.bag.storage.StorageFile`: nothing is read before :meth:`open`. Its
    tables are its index, so ``has_summary`` is True and topic spans come from them; SQLite3
    stores no publish time (a message's is its log time). Its chunks are its rows laid out as
    chunks; ``payload_filter`` (rosbag2's message compression) applies to every payload read.
    """

    storage_identifier = "sqlite3"
    has_summary = True
    compression = ""
    compressed_size = 0
    uncompressed_size = 0

    def __init__(self, path: Path) -> None:
        self.path = path
        self.topics: dict[str, TopicInfo] = {}
        self.definitions: dict[str, str] = {}
        self.topic_definitions: dict[str, str] = {}  # one text per type in message_definitions
        self.topic_counts: dict[str, int] = {}
        self.start_ns = self.end_ns = 0
        self.problems: list[str] = []
        self.payload_filter: PayloadFilter | None = None
        self._db: sqlite3.Connection | None = None
        self._topic_ids: dict[int, str] = {}
        self._spans: dict[str, Span] = {}
        self._clean = False  # every row valid and of a known topic (found by open)

    def open(self) -> None:
        """Check the rosbag2 schema and read topics, definitions, counts and the time range.

        Raises:
            NotABagError: not SQLite3, or without the rosbag2 tables and columns.
            CorruptBagError: SQLite3 reports damage (a bad page) while reading them.
        """
        self._db = db = connect(self.path)
        try:
            columns = _table_columns(db)
            missing = _missing_columns(columns)
            if missing:
                raise NotABagError(f"{self.path}: SQLite3 file without rosbag2 {missing}")
            # Ordering ties by rowid: a WITHOUT ROWID table is refused here, not halfway through.
            db.execute("SELECT rowid FROM messages LIMIT 0")
            self._read_topics(db, columns["topics"])
            if "message_definitions" in columns:
                self._read_definitions(db, columns["message_definitions"])
            self._read_counts(db)
        except sqlite3.DatabaseError as exc:
            kind = NotABagError if "file is not a database" in str(exc) else CorruptBagError
            raise kind(f"{self.path}: unreadable SQLite3 database ({exc})") from exc
        except sqlite3.Error as exc:
            raise CorruptBagError(f"{self.path}: unreadable SQLite3 database ({exc})") from exc

    def _read_topics(self, db: sqlite3.Connection, columns: set[str]) -> None:
        optional = [c if c in columns else "''" for c in _OPTIONAL_TOPIC_COLUMNS]
        query = f"SELECT {', '.join((*TOPIC_COLUMNS, *optional))} FROM topics"
        for row in db.execute(query):
            topic_id, name, type_name, fmt, qos, type_hash = row
            texts = (name, type_name, fmt or "", qos or "", type_hash or "")
            if not isinstance(topic_id, int) or not all(isinstance(t, str) for t in texts):
                self._problem(f"topics row {topic_id!r:.40} has wrong types, skipped")
                continue
            self._topic_ids[topic_id] = name
            self.topics.setdefault(
                name, TopicInfo(name, canonical_type_name(type_name), *texts[2:])
            )

    def _read_definitions(self, db: sqlite3.Connection, columns: set[str]) -> None:
        if not set(DEFINITION_COLUMNS) <= columns:
            self._problem("message_definitions table without its columns, not used")
            return
        query = f"SELECT {', '.join(DEFINITION_COLUMNS)} FROM message_definitions"
        for type_name, encoding, text in db.execute(query):
            if not all(isinstance(v, str) for v in (type_name, encoding, text)):
                self._problem(f"message_definitions row of {type_name!r:.60} unusable")
            elif encoding in DEFINITION_ENCODINGS:  # "" too: a message without fields
                self.definitions.setdefault(canonical_type_name(type_name), text)
        # rosbag2 stores a service's ``.srv`` text under ``pkg/srv/Name`` and an action's
        # ``ACTION:`` text under ``pkg/action/Name``, not under the types of their topics: those
        # are rebuilt from it (bagkit.decode.stored).
        for topic in self.topics.values():
            owner = _owner_type(topic.type)
            if owner in self.definitions:
                self.definitions.setdefault(topic.type, self.definitions[owner])

    def _read_counts(self, db: sqlite3.Connection) -> None:
        """Counts and spans in one scan of the rows; the rows of wrong types are the rest of
        ``COUNT(*)`` (read from the smallest index).

        A file of one topic id is scanned for its counts alone: when every row is valid and
        of that id (rosbag2 writes nothing else), its span is the table's, two lookups in the
        timestamp index; else the rows are scanned again for the spans of the valid ones.
        """
        (rows,) = db.execute("SELECT COUNT(*) FROM messages").fetchone()
        if len(self._topic_ids) == 1 and self._counted(db, rows, spans=False):
            return
        self._counted(db, rows, spans=True)

    def _counted(self, db: sqlite3.Connection, rows: int, *, spans: bool) -> bool:
        """Fill the counts from one scan; False (nothing filled) when ``spans`` is False and
        some row is invalid or of no known topic (their spans need a scan of their own)."""
        grouped = self._grouped_counts(db, spans=spans)
        valid = sum(count for _, count, _, _ in grouped)
        orphans = valid - sum(count for topic_id, count, _, _ in grouped if self._known(topic_id))
        self._clean = rows == valid and not orphans
        if not spans:
            if not self._clean:
                return False
            (first,) = db.execute("SELECT MIN(timestamp) FROM messages").fetchone()
            (last,) = db.execute("SELECT MAX(timestamp) FROM messages").fetchone()
            grouped = [(i, count, first, last) for i, count, _, _ in grouped]
        self.topic_counts = dict.fromkeys(self.topics, 0)
        starts: list[int] = []
        ends: list[int] = []
        for topic_id, count, first, last in grouped:
            starts.append(first)
            ends.append(last)
            if self._known(topic_id):
                name = self._topic_ids[topic_id]  # type: ignore[index]
                self.topic_counts[name] += count
                widen(self._spans, name, first, last)
        if orphans:
            self._problem(f"{counted(orphans, 'message')} of no known topic skipped")
        if rows > valid:
            self._problem(
                f"{counted(rows - valid, 'message')} without an integer timestamp or blob data "
                "skipped"
            )
        self.start_ns, self.end_ns = min(starts, default=0), max(ends, default=0)
        return True

    def _known(self, topic_id: object) -> bool:
        """True when ``topic_id`` is an integer of a topic row read."""
        return isinstance(topic_id, int) and topic_id in self._topic_ids

    def _grouped_counts(
        self, db: sqlite3.Connection, *, spans: bool
    ) -> list[tuple[object, int, int, int]]:
        """(topic id, count, first and last timestamp) of the valid rows of each topic id,
        several tuples of one id where the rows were counted in parts (``spans`` False: the
        timestamps are 0, not read).

        A large table is counted in two halves of its row ids at once, the second on a
        connection of its own in a thread (SQLite steps rows without the GIL): the scan is
        the one part of opening that grows with the rows.
        """
        halves = _row_id_halves(db)
        if halves is None:
            return self._counts_in(db, "", spans)
        second: list[tuple[object, int, int, int]] | BaseException = []

        def count_second_half() -> None:
            nonlocal second
            other = connect(self.path)
            try:
                second = self._counts_in(other, halves[1], spans)
            except BaseException as exc:  # raised by the opening thread
                second = exc
            finally:
                other.close()

        worker = threading.Thread(target=count_second_half, name="bagkit-db3-count")
        worker.start()
        try:
            first = self._counts_in(db, halves[0], spans)
        finally:
            worker.join()
        if isinstance(second, BaseException):
            raise second
        return first + second

    def _counts_in(
        self, db: sqlite3.Connection, rows: str, spans: bool
    ) -> list[tuple[object, int, int, int]]:
        """:meth:`_grouped_counts` of the rows that ``rows`` (an SQL condition after AND, or
        '') leaves in.

        Few topic ids are counted by one filtered aggregate each in one scan; SQLite would
        sort every row by topic id for ``GROUP BY``, which costs more than a few filters. The
        rows of no known id come as one of id None.
        """
        ids = list(self._topic_ids)
        times = "MIN(timestamp), MAX(timestamp)" if spans else "0, 0"
        if len(ids) > FILTERED_COUNT_TOPICS or sqlite3.sqlite_version_info < (3, 30):
            query = (
                f"SELECT topic_id, COUNT(*), {times} FROM messages "
                f"WHERE {VALID_ROW}{rows} GROUP BY topic_id"
            )
            return list(db.execute(query))
        per_id = "".join(
            f", COUNT(*) FILTER (WHERE topic_id = {i})"
            + (
                f", MIN(timestamp) FILTER (WHERE topic_id = {i}), "
                f"MAX(timestamp) FILTER (WHERE topic_id = {i})"
                if spans
                else ", 0, 0"
            )
            for i in ids
        )
        query = f"SELECT COUNT(*), {times}{per_id} FROM messages WHERE {VALID_ROW}{rows}"
        total, first, last, *found = db.execute(query).fetchone()
        grouped = [(i, *found[3 * k : 3 * k + 3]) for k, i in enumerate(ids)]
        grouped = [row for row in grouped if row[1]]
        orphans = total - sum(row[1] for row in grouped)
        return [*grouped, (None, orphans, first, last)] if orphans else grouped

    def close(self) -> None:
        """Close the database."""
        if self._db is not None:
            self._db.close()

    def topic_spans(self, *, message_indexes: bool = True) -> dict[str, Span]:
        """(first, last) timestamp of each topic with messages, from the counts' query (exact
        whatever ``message_indexes`` says: a database is a local file)."""
        return dict(self._spans)

    def index_log_times(self, topic: str) -> np.ndarray | None:
        """None: the messages are read (a timestamp query costs what reading them does)."""
        return None
