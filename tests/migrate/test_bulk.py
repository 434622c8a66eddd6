"""The column-by-column migration of a chunk's payloads gives the bytes the message-by-message
one gives, hands back what it cannot take, and the records rebuilt around its rows keep each
message's channel, sequence and times."""

from __future__ import annotations

import itertools
import threading
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from mcap.reader import make_reader
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import Imu, Range

from bagkit.bag import BagReader, BagWriter, TopicInfo, message_definition
from bagkit.bag.mcapio.records import MESSAGE_RECORD_HEADER
from bagkit.bag.writer import DEFAULT_CHUNK_SIZE
from bagkit.migrate import Target, TopicMigration, migrate_topic
from bagkit.migrate import bulk as bulk_module
from bagkit.migrate.errors import MigrateError
from bagkit.surgery.migrate import MigrateOptions, migrate_bag

IMU = "sensor_msgs/msg/Imu"
LAST = "float64[9] linear_acceleration_covariance"
LAST_BYTES = 72  # float64[9], the last field: no padding after it
OLD_IMU = "\n".join(
    line for line in message_definition(IMU).splitlines() if line.split("#")[0].strip() != LAST
)
START_NS = 1_700_000_000_000_000_000


def _messages(count: int = 40) -> list[Imu]:
    found = []
    for i in range(count):
        msg = Imu()
        msg.header.frame_id = "imu" + "x" * (i % 3)  # three layouts
        msg.header.stamp.sec = i
        msg.linear_acceleration.z = 9.81 + i
        msg.orientation_covariance[4] = 0.5 * i
        found.append(msg)
    return found


def _old(msg: Imu) -> bytes:
    return bytes(serialize_message(msg))[:-LAST_BYTES]


def _migration() -> TopicMigration:
    migration = migrate_topic(TopicInfo("/imu", IMU), OLD_IMU, Target())
    assert migration is not None and migration.bulk is not None
    return migration


def _by_index(groups: Sequence[Sequence[Any]], room: int) -> dict[int, bytes]:
    """Payload per batch index (groups ``(indexes, rows, ...)``); asserts each index comes
    once and the room is zeros."""
    found: dict[int, bytes] = {}
    for indexes, rows, *_ in groups:
        assert not rows[:, :room].any()
        for index, row in zip(indexes.tolist(), rows, strict=True):
            assert index not in found
            found[index] = row[room:].tobytes()
    return found


def test_bulk_equals_one_by_one() -> None:
    migration = _migration()
    assert migration.bulk is not None
    messages = _messages()
    old = [_old(m) for m in messages]
    buf = np.frombuffer(b"".join(old), np.uint8)
    lengths = np.array([len(p) for p in old], np.int64)
    starts = np.concatenate([[0], np.cumsum(lengths)[:-1]]).astype(np.int64)
    groups = migration.bulk.payloads(buf, starts, lengths, 7)
    assert groups is not None and len(groups) == 3
    bulk = _by_index(groups, 7)
    assert [bulk[i] for i in range(len(old))] == [migration.payload(p) for p in old]
    decoded = [deserialize_message(bulk[i], Imu) for i in range(len(old))]
    assert [(d.header.frame_id, d.header.stamp.sec, d.linear_acceleration.z) for d in decoded] == [
        (m.header.frame_id, m.header.stamp.sec, m.linear_acceleration.z) for m in messages
    ]
    assert {tuple(d.linear_acceleration_covariance) for d in decoded} == {(0.0,) * 9}
    # A payload cut short is not taken in bulk: the whole batch goes one by one.
    short = lengths - np.eye(1, len(old), 3, np.int64)[0] * 8
    assert migration.bulk.payloads(buf, starts, short, 0) is None


def test_a_layout_is_checked_against_one_by_one_once() -> None:
    """The first group of each old layout (its length prefixes) is checked against the
    message-by-message path, its first and last rows decoded with the new definition; a later
    batch of the same layouts is built the same way and not checked again, one of a new layout
    is; every row still equals the one-by-one migration of its payload."""
    migration = _migration()
    checked: list[bytes] = []
    check = migration.check

    def counted(data: bytes | memoryview) -> object:
        checked.append(bytes(data))
        return check(data)

    migration.check = counted

    def batch(messages: list[Imu]) -> tuple[list[bytes], dict[int, bytes]]:
        old = [_old(m) for m in messages]
        buf = np.frombuffer(b"".join(old), np.uint8)
        lengths = np.array([len(p) for p in old], np.int64)
        starts = np.concatenate([[0], np.cumsum(lengths)[:-1]]).astype(np.int64)
        return old, _by_index(migration.payloads(buf, starts, lengths, 31), 31)

    messages = _messages(12)  # three frame ids: three layouts
    old, first = batch(messages[:6])
    assert len(checked) == 6  # first and last row of each of three groups
    checked.clear()
    _, again = batch(messages[6:])
    assert checked == []
    longer = _messages(2)
    for msg in longer:
        msg.header.frame_id = "a_longer_frame"
    _, new_layout = batch(longer)
    assert len(checked) == 2
    checked.clear()
    expected = [migration.payload(p) for p in old + [_old(m) for m in messages[6:] + longer]]
    found = (
        [first[i] for i in range(6)] + [again[i] for i in range(6)] + [new_layout[0], new_layout[1]]
    )
    assert found == expected


def test_one_by_one_comes_as_rows_too() -> None:
    """The message-by-message path (a rule-free migration without bulk) hands out the same
    groups of rows."""
    migration = _migration()
    old = [_old(m) for m in _messages(9)]
    buf = np.frombuffer(b"".join(old), np.uint8)
    lengths = np.array([len(p) for p in old], np.int64)
    starts = np.concatenate([[0], np.cumsum(lengths)[:-1]]).astype(np.int64)
    expected = [migration.payload(p) for p in old]
    migration.bulk = None
    found = _by_index(migration.payloads(buf, starts, lengths, 31), 31)
    assert [found[i] for i in range(len(old))] == expected


def test_migrated_bag_keeps_every_record_s_fields(tmp_path: Path) -> None:
    """Imu in three layouts (migrated in bulk) interleaved in the same chunks with an unchanged
    Range: every Imu message equals the message-by-message migration of its old payload and
    keeps its log time, publish time and sequence; every Range message is stored as it was."""
    messages = _messages(300)
    bag = tmp_path / "old"
    expected_imu, expected_range = [], []
    migration = _migration()
    with BagWriter(bag) as writer:
        writer.add_topic(TopicInfo("/imu", IMU), OLD_IMU)
        writer.add_topic(TopicInfo("/range", "sensor_msgs/msg/Range"))
        for i, msg in enumerate(messages):
            t = START_NS + 10 * i
            writer.write("/imu", _old(msg), log_time=t, publish_time=t - 3, sequence=i + 1)
            expected_imu.append((t, t - 3, i + 1, migration.payload(_old(msg))))
            if i % 4 == 0:
                data = bytes(serialize_message(Range(range=float(i))))
                writer.write("/range", data, log_time=t + 5, publish_time=t, sequence=7)
                expected_range.append((t + 5, t, 7, data))
            if i % 50 == 49:
                writer.flush()  # several chunks
    report = migrate_bag(bag, tmp_path / "new", MigrateOptions())
    (done,) = report.migrated
    assert done.migrated == len(messages)
    with BagReader(tmp_path / "new") as reader:
        stored = list(reader.messages(["/imu", "/range"]))
    got = {
        topic: [
            (m.log_time, m.publish_time, m.sequence, m.data) for m in stored if m.topic == topic
        ]
        for topic in ("/imu", "/range")
    }
    assert got == {"/imu": expected_imu, "/range": expected_range}
    assert [deserialize_message(d, Imu).linear_acceleration.z for *_, d in got["/imu"]] == [
        m.linear_acceleration.z for m in messages
    ]


def _per_output_chunk() -> int:
    """About how many migrated Imu records fill one output chunk."""
    return DEFAULT_CHUNK_SIZE // (MESSAGE_RECORD_HEADER.size + len(_old(Imu())) + LAST_BYTES)


def _many_chunks_bag(path: Path, chunks: int, bad_at: int | None = None) -> list[bytes]:
    """An old Imu bag whose migrated records fill about ``chunks`` output chunks (the payload
    at ``bad_at`` cut short: it decodes with no definition); returns the old payloads."""
    distinct = [_old(m) for m in _messages(7)]
    count = chunks * _per_output_chunk()
    payloads = [distinct[i % len(distinct)] for i in range(count)]
    if bad_at is not None:
        payloads[bad_at] = payloads[bad_at][:20]
    with BagWriter(path) as writer:
        writer.add_topic(TopicInfo("/imu", IMU), OLD_IMU)
        writer.write_batch("/imu", payloads, log_times=[START_NS + i for i in range(count)])
    return payloads


def test_a_bag_of_many_chunks_comes_out_in_order_and_the_same_each_time(tmp_path: Path) -> None:
    """Chunks are compressed on a thread while the next is built: they are written in the
    order built, and two migrations of one bag are the same bytes."""
    old = _many_chunks_bag(tmp_path / "old", 6)
    migration = _migration()
    outputs = [tmp_path / run / "new" for run in ("a", "b")]
    for out in outputs:
        out.parent.mkdir()
        migrate_bag(tmp_path / "old", out, MigrateOptions())
    files = [sorted(out.glob("*.mcap")) for out in outputs]
    assert len(files[0]) == 1
    assert files[0][0].read_bytes() == files[1][0].read_bytes()
    with files[0][0].open("rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    chunks = summary.chunk_indexes
    assert len(chunks) >= 5
    assert [c.chunk_start_offset for c in chunks] == sorted(c.chunk_start_offset for c in chunks)
    assert all(a.message_end_time < b.message_start_time for a, b in itertools.pairwise(chunks))
    with BagReader(outputs[0]) as reader:
        stored = [(m.log_time, m.data) for m in reader.messages(["/imu"])]
    migrated = {p: migration.payload(p) for p in set(old)}
    assert stored == [(START_NS + i, migrated[p]) for i, p in enumerate(old)]


def test_a_failure_after_chunks_were_written_leaves_nothing(tmp_path: Path) -> None:
    """A payload that does not decode, after several output chunks were compressed and
    written: the error names it, no output or partial directory is left, the compressing
    thread has ended."""
    _many_chunks_bag(tmp_path / "old", 6, bad_at=4 * _per_output_chunk())
    with pytest.raises(MigrateError, match=r"/imu message \d+"):
        migrate_bag(tmp_path / "old", tmp_path / "new", MigrateOptions())
    assert sorted(p.name for p in tmp_path.iterdir()) == ["old"]
    assert not [t for t in threading.enumerate() if t.name.startswith("bagkit-compress")]


def test_a_field_added_at_the_end_is_zeros_whatever_the_memory_held(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The rows are built in memory full of other bytes: the room, the new last field and the
    padding come out zero, the rest as the serializer writes it."""
    monkeypatch.setattr(
        bulk_module.np, "empty", lambda shape, dtype=float, **_: np.full(shape, 0xAB, dtype)
    )
    migration = _migration()
    assert migration.bulk is not None
    old = [_old(m) for m in _messages(12)]
    buf = np.frombuffer(b"".join(old), np.uint8)
    lengths = np.array([len(p) for p in old], np.int64)
    starts = np.concatenate([[0], np.cumsum(lengths)[:-1]]).astype(np.int64)
    groups = migration.bulk.payloads(buf, starts, lengths, 5)
    assert groups is not None
    bulk = _by_index(groups, 5)
    assert [bulk[i] for i in range(len(old))] == [migration.payload(p) for p in old]
    assert {bulk[i][-LAST_BYTES:] for i in bulk} == {bytes(LAST_BYTES)}
