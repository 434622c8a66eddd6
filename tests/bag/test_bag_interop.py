"""Every rosbag2 test bag of the interop folder (tests/conftest.py): per-topic counts in storage."""

from __future__ import annotations

import sqlite3
from collections import Counter
from pathlib import Path

import pytest
from mcap.reader import make_reader

from bagkit.bag import BagReader, EmptyBagError

# Bag directories (relative to the interop folder) and the storage files each one holds.
BAG_DIRS = [
    "rosbag2_py/test/resources/mcap/convert_a",
    "rosbag2_py/test/resources/mcap/convert_b",
    "rosbag2_py/test/resources/mcap/reindex_test_bags/multiple_files",
    "rosbag2_py/test/resources/mcap/talker",
    "rosbag2_py/test/resources/mcap/wbag",
    "rosbag2_py/test/resources/sqlite3/convert_a",
    "rosbag2_py/test/resources/sqlite3/convert_b",
    "rosbag2_py/test/resources/sqlite3/reindex_test_bags/multiple_files",
    "rosbag2_py/test/resources/sqlite3/talker",
    "rosbag2_py/test/resources/sqlite3/wbag",
    "rosbag2_tests/resources/mcap/bag_with_topics_and_service_events",
    "rosbag2_tests/resources/mcap/cdr_test",
    "rosbag2_tests/resources/mcap/wrong_rmw_test",
    "rosbag2_tests/resources/sqlite3/bag_with_topics_and_service_events",
    "rosbag2_tests/resources/sqlite3/cdr_test",
    "rosbag2_tests/resources/sqlite3/wrong_rmw_test",
    "rosbag2_transport/test/resources/mcap/rewriter_a",
    "rosbag2_transport/test/resources/mcap/rewriter_b",
    "rosbag2_transport/test/resources/mcap/test_bag_for_seek",
    "rosbag2_transport/test/resources/sqlite3/rewriter_a",
    "rosbag2_transport/test/resources/sqlite3/rewriter_b",
    "rosbag2_transport/test/resources/sqlite3/test_bag_for_seek",
]
SINGLE_FILES = [
    "rosbag2_cpp/test/rosbag2_cpp/bags/only_services.mcap",
    "rosbag2_cpp/test/rosbag2_cpp/bags/only_topics.mcap",
    "rosbag2_cpp/test/rosbag2_cpp/bags/topics_and_services.mcap",
    "rosbag2_cpp/test/rosbag2_cpp/bags/topics_and_services.db3",
]


def _storage_counts(files: list[Path]) -> tuple[Counter[str], list[int]]:
    """Messages per topic and all log times, read with the mcap library or sqlite3 directly."""
    counts: Counter[str] = Counter()
    times: list[int] = []
    for file in files:
        if file.suffix == ".mcap":
            with open(file, "rb") as f:
                for _, channel, message in make_reader(f).iter_messages(log_time_order=False):
                    counts[channel.topic] += 1
                    times.append(message.log_time)
        else:
            db = sqlite3.connect(f"file:{file}?mode=ro&immutable=1", uri=True)
            query = "SELECT t.name, m.timestamp FROM messages m JOIN topics t ON m.topic_id = t.id"
            for name, timestamp in db.execute(query):
                counts[name] += 1
                times.append(timestamp)
            db.close()
    return counts, sorted(times)


def _check(bag_path: Path, files: list[Path]) -> None:
    expected, times = _storage_counts(files)
    with BagReader(bag_path) as bag:
        assert sorted(bag.files) == sorted(files)
        assert {t: c for t, c in bag.topic_counts.items() if c} == dict(expected)
        assert bag.start_ns == times[0]
        assert bag.end_ns == times[-1]
        messages = list(bag.messages())
        assert bag.problems == []
    assert Counter(m.topic for m in messages) == expected
    assert [m.log_time for m in messages] == times


@pytest.mark.parametrize("relative", BAG_DIRS)
def test_bag_directory(interop_dir: Path, relative: str) -> None:
    bag_dir = interop_dir / relative
    files = sorted(p for p in bag_dir.iterdir() if p.suffix in (".mcap", ".db3"))
    _check(bag_dir, files)


@pytest.mark.parametrize("relative", SINGLE_FILES)
def test_single_storage_file(interop_dir: Path, relative: str) -> None:
    _check(interop_dir / relative, [interop_dir / relative])


def test_metadata_and_storage_details(interop_dir: Path) -> None:
    mcap_dir = interop_dir / "rosbag2_transport/test/resources/mcap"
    with BagReader(mcap_dir / "test_bag_for_seek") as bag:
        # Written as test_msgs/BasicTypes: canonical name, definition under it too.
        assert bag.topics["topic1"].type == "test_msgs/msg/BasicTypes"
        assert "float64 float64_value" in bag.definitions["test_msgs/msg/BasicTypes"]
    tests_dir = interop_dir / "rosbag2_tests/resources/mcap"
    with BagReader(tests_dir / "wrong_rmw_test") as bag:
        assert {t.serialization_format for t in bag.topics.values()} == {"wrong_format"}
    with BagReader(tests_dir / "bag_with_topics_and_service_events") as bag:
        event = bag.topics["/test_service1/_service_event"]
        assert event.type == "test_msgs/srv/BasicTypes_Event"
        assert "---" in bag.definitions[event.type]
        assert event.type_description_hash.startswith("RIHS01_")
        assert "reliability: 1" in event.offered_qos_profiles


def test_empty_bag_is_a_clear_error_and_leaves_the_folder_pristine(interop_dir: Path) -> None:
    bag_dir = interop_dir / "ros2bag/test/resources/empty_bag"
    before = sorted((p.name, p.stat().st_size, p.stat().st_mtime_ns) for p in bag_dir.iterdir())
    with pytest.raises(EmptyBagError, match="no messages"):
        BagReader(bag_dir).open()
    with BagReader(bag_dir, allow_empty=True) as bag:
        assert bag.storage == "sqlite3"
        assert bag.topic_counts == {"/rosout": 0, "/parameter_events": 0}
    after = sorted((p.name, p.stat().st_size, p.stat().st_mtime_ns) for p in bag_dir.iterdir())
    assert after == before
