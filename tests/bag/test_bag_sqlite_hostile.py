"""SQLite3 (.db3) bags as untrusted input: wrong types, missing schema, damage; clean outcomes."""

from __future__ import annotations

import os
import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest
from ros2_messages import DB3_SCHEMA as SCHEMA
from rosbags.typesys import Stores, get_typestore

from bagkit.bag import BagReader, CorruptBagError, NotABagError, sqlite3_file
from bagkit.bag.distro_definitions import DistroDefinitionsWarning
from bagkit.errors import BagkitError
from bagkit.words import counted

BAGKIT = str(Path(sys.executable).with_name("bagkit"))
TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
STRING = "std_msgs/msg/String"
START = 1_700_000_000_000_000_000


def _payload(text: str) -> bytes:
    return bytes(TYPESTORE.serialize_cdr(TYPESTORE.types[STRING](data=text), STRING))


def write_db3(path: Path, n: int = 20, text_size: int = 10) -> Path:
    """/a gets the even messages, /b the odd ones, 1 ms apart; payload i is 'i' padded."""
    db = sqlite3.connect(path)
    db.executescript(SCHEMA)
    db.executemany(
        "INSERT INTO topics VALUES (?, ?, ?, 'cdr', '', '')", [(1, "/a", STRING), (2, "/b", STRING)]
    )
    db.execute(
        "INSERT INTO message_definitions VALUES (1, ?, 'ros2msg', 'string data', '')", (STRING,)
    )
    db.executemany(
        "INSERT INTO messages VALUES (?, ?, ?, ?)",
        [
            (i + 1, 1 + i % 2, START + i * 1_000_000, _payload(str(i).ljust(text_size, "x")))
            for i in range(n)
        ],
    )
    db.commit()
    db.close()
    return path


def _alter(path: Path, script: str) -> Path:
    db = sqlite3.connect(path)
    db.executescript(script)
    db.commit()
    db.close()
    return path


def _read(path: Path) -> tuple[list[tuple[str, int, bytes]], list[str]]:
    with BagReader(path) as bag:
        messages = [(m.topic, m.log_time, m.data) for m in bag.messages()]
        return messages, bag.problems


def test_a_well_formed_db3_reads_every_message(tmp_path: Path) -> None:
    messages, problems = _read(write_db3(tmp_path / "ok.db3"))
    assert problems == []
    assert [t for _, t, _ in messages] == [START + i * 1_000_000 for i in range(20)]
    assert messages[3] == ("/b", START + 3_000_000, _payload("3".ljust(10, "x")))


@pytest.mark.parametrize(
    "script",
    [
        "UPDATE messages SET timestamp = 'soon' WHERE id = 4",
        "UPDATE messages SET timestamp = 17.5 WHERE id = 4",
        "UPDATE messages SET data = 'text' WHERE id = 4",
    ],
    ids=["text-timestamp", "real-timestamp", "text-data"],
)
def test_rows_of_the_wrong_types_are_skipped_and_reported(tmp_path: Path, script: str) -> None:
    bag = _alter(write_db3(tmp_path / "bad.db3"), script)
    messages, problems = _read(bag)
    assert [t for _, t, _ in messages] == [START + i * 1_000_000 for i in range(20) if i != 3]
    assert problems == ["bad.db3: 1 message without an integer timestamp or blob data skipped"]


def test_nulls_where_not_null_was_dropped(tmp_path: Path) -> None:
    """rosbag2 declares NOT NULL; a file built without it may hold NULL times and data."""
    bag = write_db3(tmp_path / "nulls.db3")
    _alter(
        bag,
        "CREATE TABLE m2(id INTEGER PRIMARY KEY, topic_id, timestamp, data);"
        "INSERT INTO m2 SELECT * FROM messages; DROP TABLE messages;"
        "ALTER TABLE m2 RENAME TO messages;"
        "UPDATE messages SET data = NULL WHERE id = 2; UPDATE messages SET timestamp = NULL "
        "WHERE id = 3; UPDATE messages SET topic_id = NULL WHERE id = 5",
    )
    messages, problems = _read(bag)
    assert len(messages) == 17
    assert "nulls.db3: 2 messages without an integer timestamp or blob data skipped" in problems
    assert "nulls.db3: 1 message of no known topic skipped" in problems


@pytest.mark.parametrize("halves", [1, 200_000], ids=["halves", "whole"])
@pytest.mark.parametrize("filtered", [0, 4], ids=["grouped", "filtered"])
def test_counts_at_open_by_either_query(
    tmp_path: Path, filtered: int, halves: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Counts, spans and the rows of no known topic are the same whether the topic ids are
    grouped or filtered one by one (a few ids), the rows counted whole or in two halves at
    once, against the rows as sqlite3 lists them."""
    monkeypatch.setattr(sqlite3_file, "FILTERED_COUNT_TOPICS", filtered)
    monkeypatch.setattr(sqlite3_file, "PARALLEL_COUNT_ROWS", halves)
    bag = _alter(
        write_db3(tmp_path / "orphans.db3", n=21),
        "UPDATE messages SET topic_id = 7 WHERE id IN (1, 2); "
        "UPDATE messages SET timestamp = 'soon' WHERE id = 5",
    )
    db = sqlite3.connect(bag)
    rows = db.execute("SELECT topic_id, timestamp FROM messages").fetchall()
    db.close()
    valid = [(i, t) for i, t in rows if isinstance(t, int)]
    with BagReader(bag) as reader:
        for topic_id, name in ((1, "/a"), (2, "/b")):
            times = [t for i, t in valid if i == topic_id]
            assert reader.topic_counts[name] == len(times)
            assert reader.topic_spans()[name] == (min(times), max(times))
        assert (reader.start_ns, reader.end_ns) == (
            min(t for _, t in valid),
            max(t for _, t in valid),
        )
        assert sorted(reader.problems) == [
            "orphans.db3: 1 message without an integer timestamp or blob data skipped",
            "orphans.db3: 2 messages of no known topic skipped",
        ]


@pytest.mark.parametrize("halves", [1, 200_000], ids=["halves", "whole"])
@pytest.mark.parametrize(
    "script",
    [
        "",
        "UPDATE messages SET timestamp = timestamp + 50000000 WHERE id = 3",
        "UPDATE messages SET topic_id = 7 WHERE id = 1",
        "UPDATE messages SET timestamp = 'soon' WHERE id = 20",
        "UPDATE messages SET timestamp = -5 WHERE id = 20; UPDATE messages SET data = 'text' "
        "WHERE id = 20",
    ],
    ids=["clean", "out-of-order", "orphan", "text-timestamp", "text-data"],
)
def test_counts_at_open_of_one_topic(
    tmp_path: Path, script: str, halves: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A file of one topic id is counted without spans, which then come from the timestamp
    index where every row is valid, else from a second scan: the same counts, spans and
    problems as the rows that sqlite3 lists say."""
    monkeypatch.setattr(sqlite3_file, "PARALLEL_COUNT_ROWS", halves)
    bag = _alter(
        write_db3(tmp_path / "one.db3", n=21),
        f"DELETE FROM topics WHERE id = 2; UPDATE messages SET topic_id = 1; {script}",
    )
    db = sqlite3.connect(bag)
    rows = db.execute("SELECT topic_id, timestamp, typeof(data) FROM messages").fetchall()
    db.close()
    valid = [(i, t) for i, t, kind in rows if isinstance(t, int) and kind == "blob"]
    times = [t for i, t in valid if i == 1]
    expected = [
        f"one.db3: {counted(count, 'message')} {what} skipped"
        for count, what in (
            (len(valid) - len(times), "of no known topic"),
            (len(rows) - len(valid), "without an integer timestamp or blob data"),
        )
        if count
    ]
    with BagReader(bag) as reader:
        assert reader.topic_counts == {"/a": len(times)}
        assert reader.topic_spans() == {"/a": (min(times), max(times))}
        assert (reader.start_ns, reader.end_ns) == (
            min(t for _, t in valid),
            max(t for _, t in valid),
        )
        assert reader.problems == expected
        assert sorted(m.log_time for m in reader.messages()) == sorted(times)


def test_a_blob_topic_name_skips_that_topic(tmp_path: Path) -> None:
    bag = _alter(write_db3(tmp_path / "blob.db3"), "UPDATE topics SET name = X'ff2f' WHERE id = 2")
    with BagReader(bag) as reader:
        assert list(reader.topics) == ["/a"]
        assert [m.log_time for m in reader.messages()] == [START + i * 2_000_000 for i in range(10)]
        assert reader.problems == [
            "blob.db3: topics row 2 has wrong types, skipped",
            "blob.db3: 10 messages of no known topic skipped",
        ]


def test_text_that_is_not_utf8_skips_its_row(tmp_path: Path) -> None:
    bag = _alter(
        write_db3(tmp_path / "latin.db3"),
        "UPDATE topics SET name = CAST(X'2fe9' AS TEXT) WHERE id = 2;"
        "UPDATE message_definitions SET encoded_message_definition = CAST(X'ff' AS TEXT)",
    )
    with BagReader(bag) as reader:
        assert list(reader.topics) == ["/a"]
        # The unusable stored text is not used: the type is Jazzy's, said in a warning.
        jazzy = get_typestore(Stores.ROS2_JAZZY)
        with pytest.warns(DistroDefinitionsWarning, match="Jazzy"):
            assert reader.definitions == {
                "std_msgs/msg/String": jazzy.generate_msgdef("std_msgs/msg/String")[0]
            }
        assert reader.problems == [
            "latin.db3: topics row 2 has wrong types, skipped",
            "latin.db3: message_definitions row of 'std_msgs/msg/String' unusable",
            "latin.db3: 10 messages of no known topic skipped",
        ]


@pytest.mark.parametrize(
    ("script", "missing"),
    [
        ("DROP TABLE topics", "table topics"),
        ("DROP TABLE messages", "table messages"),
        ("DROP INDEX timestamp_idx; ALTER TABLE messages DROP COLUMN timestamp", "timestamp"),
        ("ALTER TABLE messages DROP COLUMN data", "column messages.data"),
        ("ALTER TABLE topics DROP COLUMN type", "column topics.type"),
        # A view is evaluated on read: an infinite recursive one would never end.
        (
            "ALTER TABLE messages RENAME TO m; CREATE VIEW messages AS WITH RECURSIVE c(x) AS "
            "(SELECT 1 UNION ALL SELECT x + 1 FROM c) SELECT x AS id, 1 AS topic_id, "
            "x AS timestamp, zeroblob(10) AS data FROM c",
            "table messages",
        ),
        # A generated column too: a gigabyte per row out of a few bytes of schema.
        (
            "ALTER TABLE messages RENAME COLUMN data TO d; ALTER TABLE messages ADD COLUMN data "
            "BLOB GENERATED ALWAYS AS (zeroblob(900000000)) VIRTUAL",
            "column messages.data",
        ),
    ],
    ids=["topics", "messages", "timestamp", "data", "type", "view", "generated"],
)
def test_missing_tables_and_columns_are_one_clean_error(
    tmp_path: Path, script: str, missing: str
) -> None:
    bag = _alter(write_db3(tmp_path / "schema.db3"), script)
    with pytest.raises(NotABagError, match="SQLite3 file without rosbag2") as info:
        BagReader(bag).open()
    assert missing in str(info.value)


@pytest.mark.parametrize(
    "content",
    [b"", b"hello\n", b"SQLite format 3\x00" + b"garbage" * 100],
    ids=["empty", "text", "magic-then-garbage"],
)
def test_a_non_sqlite_file_named_db3_is_not_a_bag(tmp_path: Path, content: bytes) -> None:
    bag = tmp_path / "fake.db3"
    bag.write_bytes(content)
    with pytest.raises(NotABagError):
        BagReader(bag).open()


def test_a_truncated_db3_is_one_clean_error(tmp_path: Path) -> None:
    bag = write_db3(tmp_path / "cut.db3", n=200, text_size=100)
    bag.write_bytes(bag.read_bytes()[:8192])
    with pytest.raises(CorruptBagError, match="database disk image is malformed"):
        BagReader(bag).open()


def test_every_damaged_page_is_an_error_or_a_reported_problem(tmp_path: Path) -> None:
    """Each page of a copy in turn filled with garbage: open fails cleanly, or reading reports
    where it stopped. Payloads larger than a page live in overflow pages that only reading the
    messages touches: damage found at query time."""
    pristine = write_db3(tmp_path / "pristine.db3", n=30, text_size=5000).read_bytes()
    page_size = 4096
    outcomes = {"open": 0, "stopped": 0, "whole": 0}
    for page in range(1, len(pristine) // page_size):
        damaged = bytearray(pristine)
        damaged[page * page_size + 8 : (page + 1) * page_size] = b"\xa5" * (page_size - 8)
        bag = tmp_path / f"page{page}.db3"
        bag.write_bytes(damaged)
        try:
            messages, problems = _read(bag)
        except BagkitError:
            outcomes["open"] += 1
            continue
        stopped = [p for p in problems if "unreadable after" in p]
        outcomes["stopped" if stopped else "whole"] += 1
        if stopped:
            assert stopped == [
                f"page{page}.db3: unreadable after {counted(len(messages), 'message')} "
                f"(database disk image is malformed)"
            ]
    assert outcomes["open"] > 0 and outcomes["stopped"] > 0, outcomes


def test_a_name_with_uri_characters_is_opened(tmp_path: Path) -> None:
    bag = write_db3(tmp_path / "drive?mode=rw#1.db3", n=4)
    messages, problems = _read(bag)
    assert (len(messages), problems) == (4, [])


def test_the_cli_prints_warnings_and_errors_without_traceback(tmp_path: Path) -> None:
    texttime = _alter(
        write_db3(tmp_path / "texttime.db3"), "UPDATE messages SET timestamp = 'x' WHERE id = 1"
    )
    notable = _alter(write_db3(tmp_path / "notable.db3"), "DROP TABLE topics")
    env = {**os.environ, "COLUMNS": "200"}
    for bag, code in ((texttime, 0), (notable, 2)):
        for command in (["info"], ["stats", "summary"]):
            run = subprocess.run(
                [BAGKIT, *command, str(bag)],
                capture_output=True,
                text=True,
                timeout=60,
                check=False,
                env=env,
            )
            assert run.returncode == code, run.stderr
            assert "Traceback" not in run.stderr
            lines = run.stderr.splitlines()
            assert len(lines) == 1 and lines[0].startswith("warning:" if code == 0 else "error:")
