"""The fuzzer's seed bags: the repository's golden fixtures, small bags written here (MCAP with
each compression, a .db3), and the rosbag2 interop bags where BAGKIT_INTEROP_DIR points."""

from __future__ import annotations

import os
import shutil
import sqlite3
import struct
from dataclasses import dataclass
from pathlib import Path

from bagkit.bag import BagReader, BagWriter, TopicInfo, message_definition

REPO = Path(__file__).resolve().parents[2]
IMU = "sensor_msgs/msg/Imu"
STRING = "std_msgs/msg/String"
# Small interop bags of each kind (directories with metadata.yaml of versions 4-8, a split bag,
# single files); paths relative to BAGKIT_INTEROP_DIR.
INTEROP = [
    "rosbag2_tests/resources/mcap/cdr_test",
    "rosbag2_tests/resources/sqlite3/cdr_test",
    "rosbag2_py/test/resources/mcap/wbag",
    "rosbag2_transport/test/resources/mcap/rewriter_b",
    "rosbag2_tests/resources/mcap/bag_with_topics_and_service_events",
    "rosbag2_cpp/test/rosbag2_cpp/bags/topics_and_services.mcap",
]


@dataclass(frozen=True, slots=True)
class Seed:
    """A pristine bag: ``path`` is a bag directory or a single storage file."""

    name: str
    path: Path
    weight: int  # how often it is picked (the fixtures are slow to summarize)

    @property
    def storage(self) -> str:
        files = [self.path] if self.path.is_file() else sorted(self.path.iterdir())
        return "db3" if any(f.suffix == ".db3" for f in files) else "mcap"


def _imu(i: int) -> bytes:
    """An Imu payload (header stamp, frame id, orientation, covariances, vectors), in CDR."""
    frame = b"imu\x00"
    head = struct.pack("<4sIiI", b"\x00\x01\x00\x00", i // 10, (i % 10) * 100_000_000, len(frame))
    body = frame + struct.pack("<4d", 0.0, 0.0, 0.0, 1.0) + struct.pack("<9d", *[0.0] * 9)
    body += struct.pack("<3d", 0.001 * i, 0.0, -0.001 * i) + struct.pack("<9d", *[0.0] * 9)
    body += struct.pack("<3d", 0.01 * i, 0.5, 9.81) + struct.pack("<9d", *[0.0] * 9)
    return head + body


def _string(text: str) -> bytes:
    raw = text.encode() + b"\x00"
    return struct.pack("<4sI", b"\x00\x01\x00\x00", len(raw)) + raw


def _write_mcap(path: Path, compression: str) -> None:
    with BagWriter(path, compression=compression, chunk_size=2048) as bag:
        bag.add_topic(TopicInfo("/imu/data", IMU))
        bag.add_topic(TopicInfo("/text", STRING))
        for i in range(40):
            bag.write("/imu/data", _imu(i), log_time=1_700_000_000_000_000_000 + i * 10_000_000)
            if i % 8 == 0:
                bag.write("/text", _string(f"m{i}"), log_time=1_700_000_000_000_000_001 + i)


def _write_db3(path: Path) -> None:
    path.mkdir()
    db = sqlite3.connect(path / "gen_db3_0.db3")
    db.executescript(
        "CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL,"
        " serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL,"
        " type_description_hash TEXT NOT NULL);"
        "CREATE TABLE message_definitions(id INTEGER PRIMARY KEY, topic_type TEXT NOT NULL,"
        " encoding TEXT NOT NULL, encoded_message_definition TEXT NOT NULL,"
        " type_description_hash TEXT NOT NULL);"
        "CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL,"
        " timestamp INTEGER NOT NULL, data BLOB NOT NULL);"
        "CREATE INDEX timestamp_idx ON messages (timestamp ASC);"
    )
    db.executemany(
        "INSERT INTO topics VALUES (?, ?, ?, 'cdr', '', '')",
        [(1, "/imu/data", IMU), (2, "/text", STRING)],
    )
    db.executemany(
        "INSERT INTO message_definitions VALUES (?, ?, 'ros2msg', ?, '')",
        [(1, IMU, message_definition(IMU)), (2, STRING, message_definition(STRING))],
    )
    rows = [(1, 1_700_000_000_000_000_000 + i * 10_000_000, _imu(i)) for i in range(40)]
    rows += [(2, 1_700_000_000_000_000_001 + i, _string(f"m{i}")) for i in range(0, 40, 8)]
    db.executemany("INSERT INTO messages (topic_id, timestamp, data) VALUES (?, ?, ?)", rows)
    db.commit()
    db.close()


def _copy(source: Path, target: Path) -> None:
    """Copy a file or a tree, writable whatever the source's modes (the interop bags are not)."""
    if source.is_file():
        shutil.copyfile(source, target)
        return
    target.mkdir()
    for child in source.iterdir():
        _copy(child, target / child.name)


def _trim(source: Path, target: Path, messages: int) -> None:
    """The first ``messages`` messages of a bag, its topics, definitions and custom data kept."""
    with BagReader(source) as reader, BagWriter(target, chunk_size=4096) as bag:
        for topic in reader.topics.values():
            bag.add_topic(topic, definition=reader.definitions.get(topic.type))
        for i, message in enumerate(reader.messages()):
            if i == messages:
                break
            bag.write(
                message.topic,
                message.data,
                log_time=message.log_time,
                publish_time=message.publish_time,
                sequence=message.sequence,
            )
        if reader.metadata is not None:
            bag.custom_data.update(reader.metadata.custom_data)


def build_seeds(directory: Path, *, full_fixtures: bool = True) -> list[Seed]:
    """Write the seeds under ``directory``; return them. ``full_fixtures=False``: the first 120
    messages of each golden fixture (the whole ones take seconds per command)."""
    seeds = []
    for compression in ("zstd", "lz4", "none"):
        path = directory / f"gen_{compression}"
        _write_mcap(path, compression)
        seeds.append(Seed(path.name, path, 6))
    _write_db3(directory / "gen_db3")
    seeds.append(Seed("gen_db3", directory / "gen_db3", 6))
    for fixture in sorted((REPO / "fixtures").glob("*/golden")):
        copy = directory / f"fixture_{fixture.parent.name}"
        if full_fixtures:
            _copy(fixture, copy)
        else:
            _trim(fixture, copy, 120)
        seeds.append(Seed(copy.name, copy, 1))
    interop = os.environ.get("BAGKIT_INTEROP_DIR")
    if interop and Path(interop).is_dir():
        for relative in INTEROP:
            source = Path(interop) / relative
            if source.exists():
                copy = directory / ("interop_" + relative.replace("/", "_"))
                _copy(source, copy)
                seeds.append(Seed(copy.name, copy, 1))
    return seeds
