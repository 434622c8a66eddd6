"""Chunks a rewrite opens are read ahead in a thread: the output is the bytes a rewrite reading
each chunk in its turn writes, a chunk that cannot be read is reported as it was, and no thread
is left behind."""

from __future__ import annotations

import threading
from pathlib import Path

import pytest
from mcap.reader import make_reader
from rclpy.serialization import serialize_message
from sensor_msgs.msg import Imu

from bagkit.bag import BagReader, BagWriter, TopicInfo, message_definition
from bagkit.surgery import Selection, filter_bag
from bagkit.surgery import copy as chunk_copy
from bagkit.surgery.migrate import MigrateOptions, migrate_bag
from bagkit.surgery.options import OutputOptions, RewriteReport

IMU = "sensor_msgs/msg/Imu"
LAST = "float64[9] linear_acceleration_covariance"
LAST_BYTES = 72  # float64[9], the last field of Imu
OLD_IMU = "\n".join(
    line for line in message_definition(IMU).splitlines() if line.split("#")[0].strip() != LAST
)
START_NS = 1_700_000_000_000_000_000
CHUNKS = 6
PER_CHUNK = 400


def _old_bag(path: Path) -> list[bytes]:
    """An Imu bag stored without Imu's last field, :data:`CHUNKS` chunks; its payloads."""
    payloads = []
    for i in range(CHUNKS * PER_CHUNK):
        msg = Imu()
        msg.header.frame_id = "imu" + "x" * (i % 3)
        msg.linear_acceleration.z = 9.81 + i
        payloads.append(bytes(serialize_message(msg))[:-LAST_BYTES])
    with BagWriter(path) as writer:
        writer.add_topic(TopicInfo("/imu", IMU), OLD_IMU)
        for at in range(0, len(payloads), PER_CHUNK):
            times = [START_NS + i for i in range(at, at + PER_CHUNK)]
            writer.write_batch("/imu", payloads[at : at + PER_CHUNK], log_times=times)
            writer.flush()
    return payloads


def _chunk_spans(bag: Path) -> list[tuple[int, int, int, int]]:
    """(offset, length, first log time, last log time) of each chunk, by the mcap package."""
    (file,) = sorted(bag.glob("*.mcap"))
    with file.open("rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    return [
        (c.chunk_start_offset, c.chunk_length, c.message_start_time, c.message_end_time)
        for c in summary.chunk_indexes
    ]


def _damage_chunk(bag: Path, which: int) -> tuple[int, int, int, int]:
    """Flip bytes in the middle of a chunk's compressed data; return its span."""
    span = _chunk_spans(bag)[which]
    offset, length, _, _ = span
    (file,) = sorted(bag.glob("*.mcap"))
    data = bytearray(file.read_bytes())
    middle = offset + length // 2
    data[middle : middle + 16] = bytes(b ^ 0xFF for b in data[middle : middle + 16])
    file.write_bytes(bytes(data))
    return span


def _rewrite(kind: str, bag: Path, out: Path) -> RewriteReport:
    """Rewrite ``bag`` into ``out``/new (one name: the files name themselves)."""
    out.mkdir()
    out = out / "new"
    if kind == "migrate":
        return migrate_bag(bag, out, MigrateOptions()).rewrite
    # Another compression: every chunk is opened and written again (as convert does).
    return filter_bag(bag, out, Selection(), OutputOptions(compression="lz4"))


def _bagkit_threads() -> list[str]:
    return [t.name for t in threading.enumerate() if t.name.startswith("bagkit-")]


@pytest.mark.parametrize("kind", ["migrate", "recompress"])
def test_read_ahead_writes_the_bytes_of_reading_in_turn(
    kind: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    payloads = _old_bag(tmp_path / "old")
    ahead = _rewrite(kind, tmp_path / "old", tmp_path / "ahead")
    assert not _bagkit_threads()
    monkeypatch.setattr(chunk_copy, "READ_AHEAD", 0)  # each chunk read in its turn, no thread
    in_turn = _rewrite(kind, tmp_path / "old", tmp_path / "in_turn")
    assert ahead.chunks_copied == in_turn.chunks_copied == 0
    assert ahead.problems == in_turn.problems == []
    (a,), (b,) = (sorted((tmp_path / n / "new").glob("*.mcap")) for n in ("ahead", "in_turn"))
    assert a.read_bytes() == b.read_bytes()
    with BagReader(tmp_path / "ahead" / "new") as reader:
        stored = [(m.log_time, len(m.data)) for m in reader.messages(["/imu"])]
    grown = LAST_BYTES if kind == "migrate" else 0
    assert stored == [(START_NS + i, len(p) + grown) for i, p in enumerate(payloads)]


@pytest.mark.parametrize("kind", ["migrate", "recompress"])
def test_a_damaged_chunk_read_ahead_is_reported_as_read_in_turn(
    kind: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The read-ahead thread meets the damaged chunk before its turn: the loss is reported
    in its place, the chunks after it are written, and the thread ends."""
    payloads = _old_bag(tmp_path / "old")
    offset, length, first, last = _damage_chunk(tmp_path / "old", 2)
    ahead = _rewrite(kind, tmp_path / "old", tmp_path / "ahead")
    assert not _bagkit_threads()
    (problem,) = ahead.problems
    lost = sum(first <= START_NS + i <= last for i in range(len(payloads)))
    assert lost == PER_CHUNK
    assert f"chunk at byte {offset} ({length} bytes) unreadable" in problem
    assert problem.endswith(f"its {lost} messages are lost")
    with BagReader(tmp_path / "ahead" / "new") as reader:
        times = [m.log_time for m in reader.messages(["/imu"])]
    assert times == [
        START_NS + i for i in range(len(payloads)) if not first <= START_NS + i <= last
    ]
    monkeypatch.setattr(chunk_copy, "READ_AHEAD", 0)
    in_turn = _rewrite(kind, tmp_path / "old", tmp_path / "in_turn")
    assert in_turn.problems == ahead.problems
    (a,), (b,) = (sorted((tmp_path / n / "new").glob("*.mcap")) for n in ("ahead", "in_turn"))
    assert a.read_bytes() == b.read_bytes()
