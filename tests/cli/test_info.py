"""``bagkit info`` as a subprocess: table, JSON, salvaged bags and bad input."""

from __future__ import annotations

import json
import os
import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest
from mcap.reader import make_reader
from rosbags.typesys import Stores, get_typestore

from bagkit.bag import BagWriter, TopicInfo

BAGKIT = str(Path(sys.executable).with_name("bagkit"))
TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
STRING = "std_msgs/msg/String"
QOS = """\
- history: keep_last
  depth: 5
  reliability: best_effort
  durability: transient_local
  deadline:
    sec: 9223372036
    nsec: 854775807
  lifespan:
    sec: 9223372036
    nsec: 854775807
  liveliness: automatic
  liveliness_lease_duration:
    sec: 9223372036
    nsec: 854775807
  avoid_ros_namespace_conventions: false"""
START = 1_763_850_000_000_000_000


def _run(*args: str) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "COLUMNS": "200"}
    return subprocess.run(
        [BAGKIT, "info", *args], capture_output=True, text=True, timeout=60, check=False, env=env
    )


@pytest.fixture
def two_topic_bag(tmp_path: Path) -> Path:
    """/fast: 201 messages at 20 Hz over 10 s; /slow: 11 at 1 Hz; two files."""
    path = tmp_path / "drive"
    with BagWriter(path, max_bag_duration_s=6.0) as bag:
        bag.add_topic(TopicInfo("/fast", STRING, offered_qos_profiles=QOS))
        bag.add_topic(TopicInfo("/slow", STRING))
        for i in range(201):
            data = bytes(TYPESTORE.serialize_cdr(TYPESTORE.types[STRING](data=f"{i}"), STRING))
            bag.write("/fast", data, log_time=START + i * 50_000_000)
            if i % 20 == 0:
                bag.write("/slow", data, log_time=START + i * 50_000_000 + 1)
    return path


def test_json_reports_the_bag(two_topic_bag: Path) -> None:
    result = _run(str(two_topic_bag), "--format", "json")
    assert result.returncode == 0, result.stderr
    info = json.loads(result.stdout)
    files = [str(two_topic_bag / "drive_0.mcap"), str(two_topic_bag / "drive_1.mcap")]
    assert info["files"] == files
    assert info["path"] == str(two_topic_bag)
    assert info["storage"] == "mcap"
    assert info["size_bytes"] == sum(Path(f).stat().st_size for f in files)
    assert info["start_ns"] == START
    assert info["end_ns"] == START + 200 * 50_000_000 + 1
    assert info["duration_s"] == pytest.approx(10.000000001)
    assert info["message_count"] == 212
    topics = {t["topic"]: t for t in info["topics"]}
    assert topics["/fast"] == {
        "topic": "/fast",
        "type": STRING,
        "count": 201,
        "rate_hz": pytest.approx(20.1, rel=1e-6),
        "serialization_format": "cdr",
        "offered_qos_profiles": QOS,
    }
    assert topics["/slow"]["count"] == 11
    assert info["compression"] == "zstd"
    assert info["compression_ratio"] > 1.0
    assert info["summary"] is True
    assert info["problems"] == []


def test_table_is_for_people(two_topic_bag: Path) -> None:
    result = _run(str(two_topic_bag))
    assert result.returncode == 0, result.stderr
    out = result.stdout
    assert "drive_0.mcap" in out and "drive_1.mcap" in out
    assert "212" in out
    assert "10.000000001s" in out
    assert "best_effort, transient_local, keep_last(5)" in out
    assert "20.10" in out


def test_salvaged_bag_is_reported_with_its_problem(two_topic_bag: Path, tmp_path: Path) -> None:
    crashed = tmp_path / "crashed"
    crashed.mkdir()
    data = (two_topic_bag / "drive_0.mcap").read_bytes()
    (crashed / "crashed_0.mcap").write_bytes(data[: len(data) // 2])
    result = _run(str(crashed), "--format", "json")
    assert result.returncode == 0, result.stderr
    info = json.loads(result.stdout)
    assert info["summary"] is False
    assert 0 < info["message_count"] < 212
    assert len(info["problems"]) == 1
    assert "crashed_0.mcap: truncated at byte" in info["problems"][0]
    assert "warning: crashed_0.mcap: truncated at byte" in result.stderr


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda p: p / "missing", "no such file"),
        (lambda p: (p / "notes.mcap").write_text("not a bag") and p / "notes.mcap", "not"),
        (lambda p: (p / "emptydir").mkdir() or p / "emptydir", "not a bag"),
    ],
)
def test_unusable_input_exits_2_with_one_line(tmp_path: Path, make: object, message: str) -> None:
    target = make(tmp_path)  # type: ignore[operator]
    result = _run(str(target))
    assert result.returncode == 2
    assert result.stdout == ""
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("error:") and message in lines[0]
    assert "Traceback" not in result.stderr


def test_foreign_storage(tmp_path: Path) -> None:
    foreign = tmp_path / "foreign"
    foreign.mkdir()
    (foreign / "metadata.yaml").write_text(
        "rosbag2_bagfile_information:\n  version: 5\n  storage_identifier: hdf5\n"
        "  relative_file_paths: [foreign_0.h5]\n"
    )
    result = _run(str(foreign))
    assert result.returncode == 2
    assert "hdf5" in result.stderr and "not supported" in result.stderr


def test_empty_bag(interop_dir: Path) -> None:
    result = _run(str(interop_dir / "ros2bag/test/resources/empty_bag"))
    assert result.returncode == 2
    assert "no messages" in result.stderr


def _storage_counts(bag_dir: Path) -> dict[str, int]:
    """Messages per topic as the storage files hold them (mcap library, or sqlite3)."""
    counts: dict[str, int] = {}
    for file in sorted(bag_dir.iterdir()):
        if file.suffix == ".mcap":
            with open(file, "rb") as f:
                for _, channel, _ in make_reader(f).iter_messages():
                    counts[channel.topic] = counts.get(channel.topic, 0) + 1
        elif file.suffix == ".db3":
            db = sqlite3.connect(f"file:{file}?mode=ro&immutable=1", uri=True)
            for (name,) in db.execute("SELECT name FROM topics"):
                counts.setdefault(name, 0)
            query = "SELECT t.name, COUNT(*) FROM messages m JOIN topics t ON m.topic_id = t.id"
            for name, count in db.execute(query + " GROUP BY t.name"):
                counts[name] += count
            db.close()
    return counts


@pytest.mark.parametrize(
    "relative",
    [
        "rosbag2_py/test/resources/mcap/wbag",  # Go-written, split in five files
        "rosbag2_py/test/resources/sqlite3/talker",
        "rosbag2_tests/resources/mcap/wrong_rmw_test",
    ],
)
def test_interop_bags(interop_dir: Path, relative: str) -> None:
    result = _run(str(interop_dir / relative), "--format", "json")
    assert result.returncode == 0, result.stderr
    info = json.loads(result.stdout)
    expected = _storage_counts(interop_dir / relative)
    assert sum(expected.values()) > 0
    counted = {t["topic"]: t["count"] for t in info["topics"]}
    assert {t: c for t, c in counted.items() if c or t in expected} == expected
    assert info["message_count"] == sum(expected.values())
    if "wrong_rmw" in relative:
        assert {t["serialization_format"] for t in info["topics"]} == {"wrong_format"}
