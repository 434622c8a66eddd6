"""The column-by-column migration against the message-by-message one for other layout changes:
a field added in the middle (alignment padding after it), a field removed (``--allow-drop``),
and values the message-by-message decoder refuses or rewrites (those batches go its way)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import Imu, Range, RegionOfInterest

from bagkit.bag import BagReader, BagWriter, TopicInfo, message_definition
from bagkit.decode.message_types import MessageTypes
from bagkit.migrate import Target, TopicMigration, migrate_topic
from bagkit.migrate import bulk as bulk_module
from bagkit.migrate.errors import MigrateError
from bagkit.surgery.migrate import MigrateOptions, migrate_bag

RANGE = "sensor_msgs/msg/Range"
IMU = "sensor_msgs/msg/Imu"
START_NS = 1_700_000_000_000_000_000
# Range stored before radiation_type (uint8, then 3 bytes of padding before field_of_view).
OLD_RANGE = "\n".join(
    line
    for line in message_definition(RANGE).splitlines()
    if line.split("#")[0].strip() != "uint8 radiation_type"
)
# Imu stored with a field after its header that today's lacks (padding after it, too).
OLD_IMU = message_definition(IMU).replace(
    "std_msgs/Header header", "std_msgs/Header header\nuint8 quality", 1
)


def _ranges(count: int) -> list[Range]:
    found = []
    for i in range(count):
        msg = Range()
        msg.header.frame_id = "r" * (1 + i % 4)  # four layouts: padding before each float
        msg.header.stamp.sec = i
        msg.field_of_view = 0.25 * i
        msg.range = 1.5 + i
        msg.variance = 0.01 * i
        found.append(msg)
    return found


def _imus(count: int) -> list[Imu]:
    found = []
    for i in range(count):
        msg = Imu()
        msg.header.frame_id = "imu" + "x" * (i % 2)
        msg.orientation.w = 1.0 - i
        msg.linear_acceleration_covariance[8] = 0.5 * i
        found.append(msg)
    return found


def _stored(name: str, old_text: str, messages: list, extra: dict[str, object]) -> list[bytes]:
    """``messages`` serialized with the old definition ``old_text`` (its fields today's lacks
    from ``extra``), by rosbags' serializer, as a recorder of that definition wrote them."""
    new_types = MessageTypes.from_definitions({name: message_definition(name)})
    old_types = MessageTypes.from_definitions({name: old_text})
    store, old_name = old_types.rosbags_typestore(), old_types.resolve(name)
    fields = [field for field, _ in store.fielddefs[old_name][1]]
    found = []
    for msg in messages:
        today = new_types.deserialize(bytes(serialize_message(msg)), name)
        values = {f: extra[f] if f in extra else getattr(today, f) for f in fields}
        found.append(bytes(store.serialize_cdr(store.types[old_name](**values), old_name)))
    return found


def _batch(payloads: list[bytes]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    buf = np.frombuffer(b"".join(payloads), np.uint8)
    lengths = np.array([len(p) for p in payloads], np.int64)
    starts = np.concatenate([[0], np.cumsum(lengths)[:-1]]).astype(np.int64)
    return buf, starts, lengths


def _bulk_payloads(migration: TopicMigration, payloads: list[bytes]) -> list[bytes] | None:
    """The bulk path's payloads in batch order, or None when it hands the batch back."""
    assert migration.bulk is not None
    buf, starts, lengths = _batch(payloads)
    groups = migration.bulk.payloads(buf, starts, lengths, 5)
    if groups is None:
        return None
    found: dict[int, bytes] = {}
    for indexes, rows, _ in groups:
        assert not rows[:, :5].any()
        found.update(zip(indexes.tolist(), (r[5:].tobytes() for r in rows), strict=True))
    assert sorted(found) == list(range(len(payloads)))
    return [found[i] for i in range(len(payloads))]


def test_a_field_added_in_the_middle_before_padding() -> None:
    messages = _ranges(24)
    old = _stored(RANGE, OLD_RANGE, messages, {})
    migration = migrate_topic(TopicInfo("/range", RANGE), OLD_RANGE, Target())
    assert migration is not None and migration.bulk is not None
    bulk = _bulk_payloads(migration, old)
    assert bulk == [migration.payload(p) for p in old]
    decoded = [deserialize_message(p, Range) for p in bulk]
    assert [(d.header.frame_id, d.radiation_type, d.field_of_view, d.range) for d in decoded] == [
        (m.header.frame_id, 0, pytest.approx(m.field_of_view), pytest.approx(m.range))
        for m in messages
    ]


def test_a_field_removed_with_allow_drop() -> None:
    messages = _imus(12)
    old = _stored(IMU, OLD_IMU, messages, {"quality": 7})
    with pytest.raises(MigrateError, match="quality"):
        migrate_topic(TopicInfo("/imu", IMU), OLD_IMU, Target())
    migration = migrate_topic(TopicInfo("/imu", IMU), OLD_IMU, Target(), allow_drop=True)
    assert migration is not None and migration.bulk is not None
    assert migration.dropped == ["sensor_msgs/msg/Imu: quality (uint8)"]
    bulk = _bulk_payloads(migration, old)
    assert bulk == [migration.payload(p) for p in old]
    assert bulk == [bytes(serialize_message(m)) for m in messages]


@pytest.mark.parametrize(
    ("frame_id", "taken"), [("caé".encode(), False), (b"\xffxxx", False), (b"camx", True)]
)
def test_strings_the_decoder_may_refuse_go_message_by_message(frame_id: bytes, taken: bool) -> None:
    """A string that is not ASCII is left to the message-by-message path, which keeps it
    (UTF-8) or refuses it (not UTF-8), as it would without the bulk path."""
    messages = _ranges(6)
    old = _stored(RANGE, OLD_RANGE, messages, {})
    odd = old[3].replace(b"rrrr\x00", frame_id + b"\x00")  # four bytes in place of four
    assert len(odd) == len(old[3]) and odd != old[3]
    migration = migrate_topic(TopicInfo("/range", RANGE), OLD_RANGE, Target())
    assert migration is not None
    payloads = [*old[:3], odd, *old[4:]]
    assert (_bulk_payloads(migration, payloads) is not None) == taken
    buf, starts, lengths = _batch(payloads)
    if frame_id == b"\xffxxx":  # not UTF-8
        with pytest.raises(MigrateError, match="/range message 4"):
            migration.payloads(buf, starts, lengths)
        return
    (found,) = [rows for indexes, rows in migration.payloads(buf, starts, lengths) if 3 in indexes]
    assert found.shape[1] == len(migration.payload(odd))


def test_a_bool_past_1_goes_message_by_message() -> None:
    """A bool stored as 2: the message-by-message path writes it as 1 (true), so the batch
    goes that way; one of 0 and 1 only is taken in bulk."""
    roi = "sensor_msgs/msg/RegionOfInterest"
    old_text = "\n".join(
        line
        for line in message_definition(roi).splitlines()
        if line.split("#")[0].strip() != "uint32 width"
    )
    messages = [RegionOfInterest(x_offset=7, height=i, do_rectify=bool(i % 2)) for i in range(5)]
    old = _stored(roi, old_text, messages, {})
    migration = migrate_topic(TopicInfo("/roi", roi), old_text, Target())
    assert migration is not None
    assert _bulk_payloads(migration, old) == [migration.payload(p) for p in old]
    at = 4 + 3 * 4  # do_rectify: after the encapsulation header and three uint32
    assert (old[0][at], old[1][at]) == (0, 1)
    two = old[1][:at] + b"\x02" + old[1][at + 1 :]
    assert _bulk_payloads(migration, [old[0], two]) is None
    buf, starts, lengths = _batch([old[0], two])
    rows = {
        i: r
        for indexes, group in migration.payloads(buf, starts, lengths)
        for i, r in zip(indexes.tolist(), group, strict=True)
    }
    assert deserialize_message(rows[1].tobytes(), RegionOfInterest).do_rectify is True
    assert rows[1].tobytes() == migration.payload(old[1])


def test_a_bag_migrated_in_bulk_equals_one_by_one(tmp_path: Path) -> None:
    """A real MCAP bag (Range with a field added in the middle, frame ids of four lengths,
    several chunks): every stored payload is what the message-by-message path gives."""
    messages = _ranges(400)
    old = _stored(RANGE, OLD_RANGE, messages, {})
    with BagWriter(tmp_path / "old") as writer:
        writer.add_topic(TopicInfo("/range", RANGE), OLD_RANGE)
        for i, payload in enumerate(old):
            writer.write("/range", payload, log_time=START_NS + i, sequence=i)
            if i % 100 == 99:
                writer.flush()
    migration = migrate_topic(TopicInfo("/range", RANGE), OLD_RANGE, Target())
    assert migration is not None
    expected = [migration.payload(p) for p in old]
    report = migrate_bag(tmp_path / "old", tmp_path / "new", MigrateOptions())
    assert report.migrated[0].migrated == len(old)
    with BagReader(tmp_path / "new") as reader:
        stored = [(m.log_time, m.sequence, m.data) for m in reader.messages(["/range"])]
    assert stored == [(START_NS + i, i, p) for i, p in enumerate(expected)]
    assert [deserialize_message(d, Range).range for *_, d in stored] == [
        pytest.approx(m.range) for m in messages
    ]


def test_rows_keep_nothing_of_the_memory_they_are_built_in(monkeypatch: pytest.MonkeyPatch) -> None:
    """Every byte of a row is written (the spans copied, the template elsewhere: padding, new
    fields, prefixes): rows built in memory full of other bytes equal the serializer's."""
    messages = _ranges(24)
    old = _stored(RANGE, OLD_RANGE, messages, {})
    migration = migrate_topic(TopicInfo("/range", RANGE), OLD_RANGE, Target())
    assert migration is not None and migration.bulk is not None
    monkeypatch.setattr(
        bulk_module.np, "empty", lambda shape, dtype=float, **_: np.full(shape, 0xAB, dtype)
    )
    assert _bulk_payloads(migration, old) == [migration.payload(p) for p in old]
