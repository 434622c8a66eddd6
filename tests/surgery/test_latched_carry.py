"""filter/merge --start write the latched state first; custom_data and stored order carried.

Inputs are written here (payloads by rosbags); outputs are read back by rosbags' AnyReader and
the ``mcap`` package, and checked with ``bagkit doctor``'s library.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from ros2_messages import IMU, STRING, imu_cdr, qos_yaml, string_cdr
from surgery_samples import START, mcap_messages, rosbags_messages, run, run_here

from bagkit.bag import BagReader, BagWriter, TopicInfo
from bagkit.surgery import Selection, diagnose, filter_bag, merge_bags, recover_bag

LATCHED = qos_yaml(depth=1, reliability="reliable", durability="transient_local")
VOLATILE = qos_yaml(depth=10, reliability="reliable", durability="volatile")
Written = tuple[str, int, bytes]


def write_robot_bag(path: Path, *, offset_ns: int = 0, n: int = 2000) -> list[Written]:
    """/imu/data every 10 ms (volatile), /tf_static twice and /map every 300th
    (transient-local), /mode every 100th (volatile); per-topic batches of 20 in a chunk each
    (as bagkit's recorder writes them: stored out of log-time order inside chunks)."""
    written: list[Written] = []
    with BagWriter(path) as bag:
        bag.add_topic(TopicInfo("/imu/data", IMU, offered_qos_profiles=VOLATILE))
        bag.add_topic(TopicInfo("/tf_static", STRING, offered_qos_profiles=LATCHED))
        bag.add_topic(TopicInfo("/map", STRING, offered_qos_profiles=LATCHED))
        bag.add_topic(TopicInfo("/mode", STRING, offered_qos_profiles=VOLATILE))
        bag.custom_data.update({"robot": path.name, "bagkit.record.lost": "0"})
        for first in range(0, n, 20):
            batch: dict[str, list[tuple[int, bytes]]] = {}
            for i in range(first, first + 20):
                t = START + offset_ns + i * 10_000_000
                batch.setdefault("/imu/data", []).append((t, imu_cdr(i)))
                if i in (0, 1000):
                    batch.setdefault("/tf_static", []).append((t + 1, string_cdr(f"tf {i}")))
                if i % 300 == 7:
                    batch.setdefault("/map", []).append((t + 2, string_cdr(f"map {i}")))
                if i % 100 == 50:
                    batch.setdefault("/mode", []).append((t + 3, string_cdr(f"mode {i}")))
            for topic, items in batch.items():
                bag.write_batch(topic, [d for _, d in items], log_times=[t for t, _ in items])
                written += [(topic, t, d) for t, d in items]
            bag.flush()  # one chunk per batch round
    return sorted(written, key=lambda w: w[1])


def last_before(written: list[Written], topics: set[str], start: int) -> dict[str, Written]:
    found: dict[str, Written] = {}
    for message in written:
        if message[0] in topics and message[1] < start:
            found[message[0]] = message
    return found


@pytest.fixture(scope="module")
def robot(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[Written]]:
    path = tmp_path_factory.mktemp("robot") / "robot"
    return path, write_robot_bag(path)


def test_filter_start_writes_the_latched_state_first(
    robot: tuple[Path, list[Written]], tmp_path: Path
) -> None:
    bag, written = robot
    start = START + 12_345_000_000
    out = tmp_path / "out"
    result = run("filter", str(bag), "-o", str(out), "--start", f"{start}ns", "--format", "json")
    assert result.returncode == 0, result.stderr
    latched = last_before(written, {"/tf_static", "/map"}, start)
    assert len(latched) == 2  # the case has both
    # Logged at the start, in their original order, payloads as recorded; then the window.
    expected = [(t, start, d) for t, _, d in sorted(latched.values(), key=lambda w: w[1])]
    expected += [w for w in written if w[1] >= start]
    assert rosbags_messages(out) == expected
    assert mcap_messages(sorted(out.glob("*.mcap"))) == expected
    report = json.loads(result.stdout)
    assert report["latched_messages"] == 2 and report["message_count"] == len(expected)
    with BagReader(out) as reader:  # publish times stay as recorded
        first = next(reader.messages(["/tf_static"]))
        assert first.publish_time == latched["/tf_static"][1]


def test_latched_topics_and_no_latched(robot: tuple[Path, list[Written]], tmp_path: Path) -> None:
    bag, written = robot
    start = START + 9_000_000_000
    plus = tmp_path / "plus"
    result = run_here(
        "filter", str(bag), "-o", str(plus), "--start", f"{start}ns", "--latched-topics", "mode"
    )
    assert result.returncode == 0, result.stderr
    assert "3 latched" in result.stdout
    head = rosbags_messages(plus)[:3]
    expected = last_before(written, {"/tf_static", "/map", "/mode"}, start).values()
    assert {(t, d) for t, _, d in head} == {(t, d) for t, _, d in expected}
    assert all(t == start for _, t, _ in head)
    none = tmp_path / "none"
    result = run_here("filter", str(bag), "-o", str(none), "--start", f"{start}ns", "--no-latched")
    assert result.returncode == 0, result.stderr
    assert rosbags_messages(none) == [w for w in written if w[1] >= start]
    only_imu = filter_bag(
        bag, tmp_path / "imu", Selection.create(["/imu/data", "/map"], start=f"{start}ns")
    )
    assert only_imu.latched_messages == 1  # /map only: /tf_static is not selected
    bad = run_here(
        "filter", str(bag), "-o", str(tmp_path / "bad"), "--start", "5", "--latched-topics", "/x"
    )
    assert bad.returncode == 2 and bad.stderr.startswith("error:") and "/x" in bad.stderr
    assert "Traceback" not in bad.stderr and not (tmp_path / "bad").exists()


def test_merge_start_takes_the_latest_of_every_input(tmp_path: Path) -> None:
    first = write_robot_bag(tmp_path / "first", n=1000)
    second = write_robot_bag(tmp_path / "second", offset_ns=5_005_000_000, n=1000)
    start = START + 12_000_000_000
    report = merge_bags(
        [tmp_path / "first", tmp_path / "second"],
        tmp_path / "merged",
        Selection.create(start=f"{start}ns"),
    )
    everything = sorted(first + second, key=lambda w: w[1])
    latched = last_before(everything, {"/tf_static", "/map"}, start)
    assert latched["/tf_static"] in second and latched["/map"] in second
    assert report.latched_messages == 2
    got = rosbags_messages(tmp_path / "merged")
    assert got[:2] == [(t, start, d) for t, _, d in sorted(latched.values(), key=lambda w: w[1])]
    assert got[2:] == [w for w in everything if w[1] >= start]


def test_merge_is_stored_in_log_time_order(tmp_path: Path) -> None:
    """Two overlapping recordings of per-topic batches: before, the chunks copied as stored
    kept their batches (doctor: 'N messages are stored out of log-time order')."""
    first = write_robot_bag(tmp_path / "a")
    second = write_robot_bag(tmp_path / "b", offset_ns=15_000_000_000)
    notes = diagnose(tmp_path / "a").to_dict()["notes"]
    assert any("out of log-time order" in n["note"] for n in notes)  # the input's batches
    report = merge_bags([tmp_path / "a", tmp_path / "b"], tmp_path / "ab")
    merged = diagnose(tmp_path / "ab").to_dict()
    assert merged["healthy"] and merged["notes"] == []
    expected = sorted(first + second, key=lambda w: w[1])
    assert [(t, time) for t, time, _ in rosbags_messages(tmp_path / "ab")] == [
        (t, time) for t, time, _ in expected
    ]
    # filter keeps chunks as stored (readers order by index): same messages, same order read.
    filtered = filter_bag(tmp_path / "a", tmp_path / "a2", Selection())
    assert filtered.chunks_copied > 50 and report.message_count == len(expected)
    assert rosbags_messages(tmp_path / "a2") == first


def test_custom_data_is_kept(tmp_path: Path) -> None:
    write_robot_bag(tmp_path / "one", n=200)
    write_robot_bag(tmp_path / "two", offset_ns=10**10, n=200)
    bags = [tmp_path / "one", tmp_path / "two"]
    filter_bag(bags[0], tmp_path / "f", Selection.create(["/imu/data"]))
    recover_bag(bags[0], tmp_path / "r")
    merge_bags(bags, tmp_path / "m")
    expected_one = {"robot": "one", "bagkit.record.lost": "0"}
    for out in ("f", "r"):
        with BagReader(tmp_path / out) as reader:
            assert reader.metadata is not None and reader.metadata.custom_data == expected_one
    with BagReader(tmp_path / "m") as reader:
        assert reader.metadata is not None
        # Agreed values once, disagreeing ones per input.
        assert reader.metadata.custom_data == {
            "one/robot": "one",
            "bagkit.record.lost": "0",
            "two/robot": "two",
        }
