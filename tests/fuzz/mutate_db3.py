"""Mutations of a rosbag2 SQLite3 (.db3) file: values of the wrong types, schema changes
(missing tables and columns, views, generated columns), damaged pages, bytes."""

from __future__ import annotations

import random
import sqlite3
from pathlib import Path

PAGE = 4096
# (column, value) pairs set on a few rows: SQLite stores whatever it is given.
WRONG_VALUES = [
    ("messages", "timestamp", "'soon'"),
    ("messages", "timestamp", "1.5"),
    ("messages", "timestamp", "NULL"),
    ("messages", "timestamp", "X'00ff'"),
    ("messages", "timestamp", "-9223372036854775808"),
    ("messages", "timestamp", "9223372036854775807"),
    ("messages", "data", "NULL"),
    ("messages", "data", "'text'"),
    ("messages", "data", "X''"),
    ("messages", "data", "zeroblob(3)"),
    ("messages", "topic_id", "NULL"),
    ("messages", "topic_id", "999"),
    ("messages", "topic_id", "'1'"),
    ("topics", "name", "X'ff2f'"),
    ("topics", "name", "NULL"),
    ("topics", "type", "42"),
    ("topics", "type", "'no/such/Type'"),
    ("topics", "type", "''"),
    ("topics", "serialization_format", "X'00'"),
    ("topics", "offered_qos_profiles", "'- [[[[[['"),
    ("topics", "offered_qos_profiles", "X'ff'"),
    ("topics", "id", "'x'"),
    ("message_definitions", "encoded_message_definition", "'garbage ]]] %%%'"),
    ("message_definitions", "encoded_message_definition", "X'ff'"),
    ("message_definitions", "encoding", "NULL"),
]
SCHEMA_CHANGES = [
    "DROP TABLE topics",
    "DROP TABLE messages",
    "DROP TABLE message_definitions",
    "DROP INDEX IF EXISTS timestamp_idx; ALTER TABLE messages DROP COLUMN timestamp",
    "ALTER TABLE messages DROP COLUMN data",
    "ALTER TABLE topics DROP COLUMN type",
    "ALTER TABLE topics DROP COLUMN offered_qos_profiles",
    "ALTER TABLE messages RENAME TO m; CREATE VIEW messages AS WITH RECURSIVE c(x) AS "
    "(SELECT 1 UNION ALL SELECT x + 1 FROM c) SELECT x AS id, 1 AS topic_id, x AS timestamp, "
    "zeroblob(10) AS data FROM c",
    "ALTER TABLE messages RENAME COLUMN data TO d; ALTER TABLE messages ADD COLUMN data BLOB "
    "GENERATED ALWAYS AS (zeroblob(900000000)) VIRTUAL",
    "CREATE TABLE m2(topic_id, timestamp, data, PRIMARY KEY (topic_id, timestamp)) WITHOUT ROWID;"
    "INSERT OR IGNORE INTO m2 SELECT topic_id, timestamp, data FROM messages; DROP TABLE messages;"
    "ALTER TABLE m2 RENAME TO messages",
    "DELETE FROM topics",
    "DELETE FROM messages",
    "INSERT INTO topics SELECT id + 100, name, type, serialization_format, "
    "offered_qos_profiles, type_description_hash FROM topics",
]


def _execute(path: Path, script: str) -> str | None:
    """Run ``script`` on the file; the SQLite error when it does not apply (a recipe note)."""
    db = sqlite3.connect(path)
    try:
        db.executescript(script)
        db.commit()
    except sqlite3.Error as exc:
        return str(exc)
    finally:
        db.close()
    return None


def wrong_value(rng: random.Random, path: Path) -> str:
    table, column, value = rng.choice(WRONG_VALUES)
    rows = rng.choice(["rowid = 1", "rowid % 3 = 0", "1"])
    note = _execute(path, f"UPDATE {table} SET {column} = {value} WHERE {rows}")
    return f"db3 {table}.{column} = {value} where {rows}" + (
        f" (not applied: {note})" if note else ""
    )


def schema_change(rng: random.Random, path: Path) -> str:
    script = rng.choice(SCHEMA_CHANGES)
    note = _execute(path, script)
    return f"db3 schema: {script[:60]}" + (f" (not applied: {note})" if note else "")


def damage_page(rng: random.Random, path: Path) -> str:
    data = bytearray(path.read_bytes())
    pages = len(data) // PAGE
    page = rng.randrange(pages) if pages else 0
    start = page * PAGE + rng.choice([0, 8, 100])
    fill = rng.choice([b"\x00", b"\xff", b"\xa5"])
    data[start : (page + 1) * PAGE] = fill * ((page + 1) * PAGE - start)
    path.write_bytes(bytes(data))
    return f"db3 page {page} of {pages} from byte {start % PAGE} filled with {fill!r}"


def flip_or_truncate(rng: random.Random, path: Path) -> str:
    data = bytearray(path.read_bytes())
    if rng.random() < 0.5:
        at = rng.randrange(len(data))
        path.write_bytes(bytes(data[:at]))
        return f"db3 truncated at byte {at} of {len(data)}"
    flips = [rng.randrange(len(data)) for _ in range(rng.randint(1, 32))]
    for at in flips:
        data[at] ^= 1 << rng.randrange(8)
    path.write_bytes(bytes(data))
    return f"db3 {len(flips)} bits flipped"


def mutate(rng: random.Random, path: Path) -> str:
    """Apply one or two mutations to the .db3 file in place; return the recipe."""
    steps = []
    for _ in range(rng.choice([1, 1, 2])):
        action = rng.choice(
            [wrong_value, wrong_value, schema_change, damage_page, flip_or_truncate]
        )
        steps.append(action(rng, path))
    return "; ".join(steps)
