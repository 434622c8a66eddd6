"""rosbag2's SQLite3 (``.db3``) storage as untrusted input: schema checks and typed rows.

A ``.db3`` file is a program as much as data: views and generated columns are evaluated on
read (an infinite recursive view, a ``zeroblob(1e9)`` column). Only real tables with plain
columns are read; rows whose values have the wrong type (text timestamps, BLOB topic names,
NULLs) are skipped and counted, not decoded; SQLite errors become bag errors.
"""

from __future__ import annotations

import sqlite3
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from urllib.request import pathname2url

from bagkit.bag.definitions import canonical_type_name
from bagkit.bag.errors import CorruptBagError, NotABagError
from bagkit.bag.types import TopicInfo

# Columns read from each table; the first two tables are required, message_definitions is not.
TOPIC_COLUMNS = ("id", "name", "type", "serialization_format")
MESSAGE_COLUMNS = ("topic_id", "timestamp", "data")
DEFINITION_COLUMNS = ("topic_type", "encoding", "encoded_message_definition")
_OPTIONAL_TOPIC_COLUMNS = ("offered_qos_profiles", "type_description_hash")
# A message row is readable when its timestamp is an integer and its data a blob.
_VALID_ROW = "typeof(timestamp) = 'integer' AND typeof(data) = 'blob'"
INT64_MIN = -(1 << 63)
INT64_MAX = (1 << 63) - 1


@dataclass(slots=True)
class Db3Contents:
    """What a ``.db3`` file holds, from its tables (messages themselves are read on demand)."""

    topic_ids: dict[int, str] = field(default_factory=dict)
    topics: dict[str, TopicInfo] = field(default_factory=dict)
    definitions: dict[str, str] = field(default_factory=dict)
    topic_counts: dict[str, int] = field(default_factory=dict)
    topic_spans: dict[str, tuple[int, int]] = field(default_factory=dict)  # first, last log time
    start_ns: int = 0
    end_ns: int = 0
    problems: list[str] = field(default_factory=list)


def connect(path: Path) -> sqlite3.Connection:
    """Open read-only and immutable (no -shm/-wal side files next to bags in read-only folders).

    The path is URL-quoted: a ``?`` or ``#`` in a bag's name would otherwise end the file name.
    """
    uri = f"file:{pathname2url(str(path.resolve()))}?mode=ro&immutable=1"
    try:
        db = sqlite3.connect(uri, uri=True)
    except sqlite3.Error as exc:
        raise NotABagError(f"{path}: not a SQLite3 database ({exc})") from exc
    db.text_factory = _text
    return db


class _NotUtf8(bytes):
    """TEXT that is not UTF-8: not a str, so the row holding it is skipped as of a wrong type."""


def _text(raw: bytes) -> str | _NotUtf8:
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError:
        return _NotUtf8(raw)


def read_contents(db: sqlite3.Connection, path: Path) -> Db3Contents:
    """Check the rosbag2 schema and read topics, definitions, counts and the time range.

    Raises:
        NotABagError: not SQLite3, or without the rosbag2 tables and columns.
        CorruptBagError: SQLite3 reports damage (a bad page) while reading them.
    """
    try:
        columns = _table_columns(db)
        missing = _missing_columns(columns)
        if missing:
            raise NotABagError(f"{path}: SQLite3 file without rosbag2 {missing}")
        # Ordering ties by rowid: a WITHOUT ROWID table is refused here, not halfway through.
        db.execute("SELECT rowid FROM messages LIMIT 0")
        contents = Db3Contents()
        _read_topics(db, columns["topics"], contents)
        if "message_definitions" in columns:
            _read_definitions(db, columns["message_definitions"], contents)
        _read_counts(db, contents)
    except sqlite3.DatabaseError as exc:
        kind = NotABagError if "file is not a database" in str(exc) else CorruptBagError
        raise kind(f"{path}: unreadable SQLite3 database ({exc})") from exc
    except sqlite3.Error as exc:
        raise CorruptBagError(f"{path}: unreadable SQLite3 database ({exc})") from exc
    return contents


def _table_columns(db: sqlite3.Connection) -> dict[str, set[str]]:
    """The plain columns of each real table (views and generated columns left out)."""
    tables = [row[0] for row in db.execute("SELECT name FROM sqlite_master WHERE type = 'table'")]
    return {
        table: {row[0] for row in db.execute("SELECT name FROM pragma_table_info(?)", (table,))}
        for table in tables
        if isinstance(table, str)
    }


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


def _read_topics(db: sqlite3.Connection, columns: set[str], contents: Db3Contents) -> None:
    optional = [c if c in columns else "''" for c in _OPTIONAL_TOPIC_COLUMNS]
    query = f"SELECT {', '.join((*TOPIC_COLUMNS, *optional))} FROM topics"
    for row in db.execute(query):
        topic_id, name, type_name, fmt, qos, type_hash = row
        texts = (name, type_name, fmt or "", qos or "", type_hash or "")
        if not isinstance(topic_id, int) or not all(isinstance(t, str) for t in texts):
            contents.problems.append(f"topics row {topic_id!r:.40} has wrong types, skipped")
            continue
        contents.topic_ids[topic_id] = name
        contents.topics.setdefault(
            name, TopicInfo(name, canonical_type_name(type_name), *texts[2:])
        )


def _read_definitions(db: sqlite3.Connection, columns: set[str], contents: Db3Contents) -> None:
    if not set(DEFINITION_COLUMNS) <= columns:
        contents.problems.append("message_definitions table without its columns, not used")
        return
    query = f"SELECT {', '.join(DEFINITION_COLUMNS)} FROM message_definitions"
    for type_name, encoding, text in db.execute(query):
        if not all(isinstance(v, str) for v in (type_name, encoding, text)):
            contents.problems.append(f"message_definitions row of {type_name!r:.60} unusable")
        elif encoding == "ros2msg" and text:
            contents.definitions.setdefault(canonical_type_name(type_name), text)


def _read_counts(db: sqlite3.Connection, contents: Db3Contents) -> None:
    contents.topic_counts = dict.fromkeys(contents.topics, 0)
    orphans = 0
    query = (
        "SELECT topic_id, COUNT(*), MIN(timestamp), MAX(timestamp) FROM messages "
        f"WHERE {_VALID_ROW} GROUP BY topic_id"
    )
    for topic_id, count, first, last in db.execute(query):
        name = contents.topic_ids.get(topic_id) if isinstance(topic_id, int) else None
        if name is None:
            orphans += count
            continue
        contents.topic_counts[name] += count
        old = contents.topic_spans.get(name, (first, last))
        contents.topic_spans[name] = (min(old[0], first), max(old[1], last))
    if orphans:
        contents.problems.append(f"{orphans} messages of no known topic skipped")
    (invalid,) = db.execute(f"SELECT COUNT(*) FROM messages WHERE NOT ({_VALID_ROW})").fetchone()
    if invalid:
        contents.problems.append(
            f"{invalid} messages without an integer timestamp or blob data skipped"
        )
    start, end = db.execute(
        f"SELECT MIN(timestamp), MAX(timestamp) FROM messages WHERE {_VALID_ROW}"
    ).fetchone()
    contents.start_ns, contents.end_ns = start or 0, end or 0


def iter_messages(
    db: sqlite3.Connection, topic_ids: list[int], lower: int, upper: int
) -> Iterator[tuple[int, int, bytes]]:
    """``(topic_id, timestamp, data)`` in timestamp order (ties by row id), valid rows only.

    Raises:
        sqlite3.Error: damage found while reading (the caller records it as a problem).
    """
    marks = ",".join("?" * len(topic_ids))
    query = (
        f"SELECT topic_id, timestamp, data FROM messages WHERE topic_id IN ({marks}) "
        f"AND timestamp >= ? AND timestamp < ? AND {_VALID_ROW} ORDER BY timestamp, rowid"
    )
    lower = max(lower, INT64_MIN)
    upper = min(upper, INT64_MAX)
    yield from db.execute(query, (*topic_ids, lower, upper))
