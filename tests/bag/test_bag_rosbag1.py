"""ROS 1 bags (written by rosbags' rosbag1 writer) through every read command: topics, counts,
times and values against rosbags' own reading of the ROS 1 bag."""

from __future__ import annotations

import csv
import json
import subprocess
from pathlib import Path

import numpy as np
import pytest
from bagkit_runs import bagkit_in_process, bagkit_subprocess
from rosbags.rosbag1 import Reader
from rosbags.typesys import Stores, get_typestore

from bagkit.bag import BagReader
from tests.bag.ros1_samples import SAMPLE, ros1_messages, write_ros1_bag


def _run(*args: str | Path) -> subprocess.CompletedProcess[str]:
    """``bagkit ARGS`` in this process (tests/bagkit_runs.py); ``info`` of each bag a real one."""
    if args[0] == "info":
        return bagkit_subprocess(list(args), Path.cwd())
    return bagkit_in_process(list(args))


@pytest.fixture(scope="module", params=["none", "lz4", "bz2"])
def ros1_bag(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Several chunks (a small chunk threshold), two connections on /imu."""
    path = tmp_path_factory.mktemp("ros1") / f"drive_{request.param}.bag"
    return write_ros1_bag(path, compression=request.param, chunk_threshold=4096)


def test_info_comes_from_the_index_as_rosbags_reads_it(ros1_bag: Path) -> None:
    result = _run("info", ros1_bag, "--format", "json")
    assert result.returncode == 0, result.stderr
    info = json.loads(result.stdout)
    with Reader(ros1_bag) as reader:
        expected = {name: t.msgcount for name, t in reader.topics.items()}
        start, end = reader.start_time, reader.end_time - 1
        chunks = len(reader.chunk_infos)
    assert chunks > 3
    assert info["storage"] == "rosbag1"
    assert {t["topic"]: t["count"] for t in info["topics"]} == expected
    assert (info["start_ns"], info["end_ns"]) == (start, end)
    types = {t["topic"]: t["type"] for t in info["topics"]}
    assert types == {
        "/imu": "sensor_msgs/msg/Imu",
        "/status": "std_msgs/msg/String",
        "/sample": SAMPLE,
    }
    qos = {t["topic"]: t["offered_qos_profiles"] for t in info["topics"]}
    assert "transient_local" in qos["/status"] and not qos["/imu"]
    rates = {t["topic"]: t["rate_hz"] for t in info["topics"]}
    times = [t for t, _ in ros1_messages(ros1_bag, "/imu")]
    assert rates["/imu"] == pytest.approx((len(times) - 1) * 1e9 / (times[-1] - times[0]))
    assert info["problems"] == []


def test_payloads_are_cdr_of_the_ros2_type(ros1_bag: Path) -> None:
    jazzy = get_typestore(Stores.ROS2_JAZZY)
    expected = ros1_messages(ros1_bag, "/imu")
    with BagReader(ros1_bag) as bag:
        got = list(bag.messages(["/imu"]))
        assert bag.topics["/imu"].type_description_hash == jazzy.hash_rihs01("sensor_msgs/msg/Imu")
    assert [m.log_time for m in got] == [t for t, _ in expected]
    for message, (_, ros1) in zip(got, expected, strict=True):
        ros2 = jazzy.deserialize_cdr(message.data, "sensor_msgs/msg/Imu")
        assert ros2.header.stamp.sec == ros1.header.stamp.sec
        assert ros2.header.stamp.nanosec == ros1.header.stamp.nanosec
        assert ros2.header.frame_id == ros1.header.frame_id
        assert ros2.linear_acceleration.z == ros1.linear_acceleration.z
        assert (ros2.orientation_covariance == ros1.orientation_covariance).all()
        assert message.publish_time == message.log_time


def test_messages_merge_chunks_in_log_time_order(ros1_bag: Path) -> None:
    with Reader(ros1_bag) as reader:
        expected = sorted(t for _, t, _ in reader.messages())
    with BagReader(ros1_bag) as bag:
        times = [m.log_time for m in bag.messages()]
        window = [m.log_time for m in bag.messages(None, expected[40], expected[90])]
    assert times == expected
    assert window == [t for t in expected if expected[40] <= t < expected[90]]


def test_echo_prints_the_values_rosbags_reads(ros1_bag: Path) -> None:
    result = _run("echo", ros1_bag, "/sample", "--format", "json")
    assert result.returncode == 0, result.stderr
    printed = [json.loads(line) for line in result.stdout.splitlines()]
    expected = ros1_messages(ros1_bag, "/sample")
    assert len(printed) == len(expected) == 30
    for row, (time, msg) in zip(printed, expected, strict=True):
        data = row["data"]
        assert row["log_time"] == time
        assert data["taken"] == {"sec": msg.taken.sec, "nanosec": msg.taken.nanosec}
        assert data["exposure"] == {"sec": msg.exposure.sec, "nanosec": msg.exposure.nanosec}
        assert data["blob"] == msg.blob.tolist()
        assert data["gains"] == msg.gains.tolist()
        assert data["labels"] == msg.labels
        assert (data["counter"], data["ok"]) == (msg.counter, msg.ok)


def test_stats_export_and_find_read_the_ros1_values(ros1_bag: Path, tmp_path: Path) -> None:
    z = np.array([m.linear_acceleration.z for _, m in ros1_messages(ros1_bag, "/imu")])
    table = tmp_path / "imu.csv"
    result = _run("export", ros1_bag, "-t", "/imu", "-o", table)
    assert result.returncode == 0, result.stderr
    with table.open() as f:
        column = [float(row["linear_acceleration.z"]) for row in csv.DictReader(f)]
    assert column == pytest.approx(z.tolist())
    result = _run("stats", "summary", ros1_bag, "--topics", "/imu", "--format", "json")
    assert result.returncode == 0, result.stderr
    (topic,) = json.loads(result.stdout)["topics"]
    field = next(f for f in topic["fields"] if f["field"] == "linear_acceleration.z")
    assert (field["count"], field["max"]) == (len(z), z.max())
    assert field["mean"] == pytest.approx(z.mean())
    when = "/imu: linear_acceleration.z > 10.5"
    result = _run("find", ros1_bag, "--when", when, "--format", "json")
    assert result.returncode == 0, result.stderr
    assert sum(e["count"] for e in json.loads(result.stdout)) == int((z > 10.5).sum())


def test_filter_writes_the_ros1_bag_as_ros2_mcap(ros1_bag: Path, tmp_path: Path) -> None:
    out = tmp_path / "cut"
    result = _run("filter", ros1_bag, "-o", out, "--where", "linear_acceleration.z > 10")
    assert result.returncode == 0, result.stderr
    z = [m.linear_acceleration.z for _, m in ros1_messages(ros1_bag, "/imu")]
    with BagReader(out) as bag:
        assert bag.storage == "mcap"
        assert bag.topic_counts["/imu"] == sum(v > 10 for v in z)
        assert bag.topic_counts["/sample"] == 30


def test_last_messages_and_spans_from_the_index(ros1_bag: Path) -> None:
    expected = ros1_messages(ros1_bag, "/status")
    with BagReader(ros1_bag) as bag:
        before = expected[3][0] + 1
        last = bag.last_messages(["/status"], before)["/status"]
        spans = bag.topic_spans()
    jazzy = get_typestore(Stores.ROS2_JAZZY)
    assert last.log_time == expected[3][0]
    assert jazzy.deserialize_cdr(last.data, "std_msgs/msg/String").data == expected[3][1].data
    assert spans["/status"] == (expected[0][0], expected[-1][0])


@pytest.mark.parametrize("command", ["info", "recover"])
@pytest.mark.parametrize("damage", ["truncated", "no_index", "index_cut"])
def test_a_broken_ros1_bag_is_one_error_line(tmp_path: Path, damage: str, command: str) -> None:
    """info, and recover (which rewrites MCAP and sqlite3 bags, not ROS 1), fail in one line
    that names what is wrong and, when the index is missing, what rebuilds it."""
    path = write_ros1_bag(tmp_path / "drive.bag", 100, chunk_threshold=4096)
    data = path.read_bytes()
    with Reader(path) as reader:
        first_chunk = reader.chunk_infos[0].pos
    if damage == "truncated":
        data = data[: len(data) // 2]
    elif damage == "no_index":  # index_pos 0, as a recorder killed before closing leaves it
        at = data.index(b"index_pos=") + len(b"index_pos=")
        data = data[:at] + bytes(8) + data[at + 8 :]
    else:
        data = data[:-20]
    path.write_bytes(data)
    output = ("-o", tmp_path / "recovered") if command == "recover" else ()
    result = _run(command, path, *output)
    assert result.returncode == 2, result.stdout
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:"), result.stderr
    assert "Traceback" not in result.stderr
    assert not (tmp_path / "recovered").exists()  # recover leaves no half-written bag
    assert first_chunk > 0
    if damage == "truncated":  # said as such, not as rosbags' "Header could not be read"
        assert f"cut short at {len(data)} bytes" in lines[0]
    if damage != "index_cut":
        assert "`rosbag reindex` it" in lines[0]


def test_a_damaged_chunk_loses_its_messages_not_the_bag(tmp_path: Path) -> None:
    path = write_ros1_bag(tmp_path / "drive.bag", 200, compression="lz4", chunk_threshold=4096)
    with Reader(path) as reader:
        chunk = reader.chunk_infos[1]
        lost = sum(chunk.connection_counts.values())
        total = reader.message_count
        data_at = reader.chunks[chunk.pos].datapos
    data = bytearray(path.read_bytes())
    data[data_at + 20 : data_at + 40] = bytes(20)
    path.write_bytes(bytes(data))
    with BagReader(path) as bag:
        count = sum(1 for _ in bag.messages())
        problems = bag.problems
    assert total - lost <= count < total
    assert len(problems) >= 1 and "chunk at byte" in problems[0]


def test_the_mapping_constants_are_rosbags_convert_s() -> None:
    import yaml
    from rosbags.convert.converter import LATCH, STATIC_MSGTYPE_RENAMES
    from rosbags.rosbag2.metadata import dump_qos_v9

    from bagkit.bag.ros1_types import LATCHED_QOS, RENAMES

    assert RENAMES == STATIC_MSGTYPE_RENAMES
    assert yaml.safe_dump(dump_qos_v9(LATCH), sort_keys=False) == LATCHED_QOS


def test_bags_with_the_same_connections_share_their_mapped_types(tmp_path: Path) -> None:
    """Two bags of one recorder: types mapped once (each caller gets its own dict), and a
    changed definition mapped anew."""
    from bagkit.bag.ros1_types import ros2_types

    bags = [write_ros1_bag(tmp_path / f"{name}.bag", 20) for name in ("a", "b")]
    connections = []
    for bag in bags:
        with Reader(bag) as reader:
            connections.append(list(reader.connections))
    first, problems = ros2_types(connections[0])
    second, _ = ros2_types(connections[1])
    assert not problems and first == second
    assert all(first[i] is second[i] for i in first)
    first.clear()
    assert ros2_types(connections[0])[0] == second
    changed = [
        c._replace(msgdef=c.msgdef._replace(data=c.msgdef.data + "\nint8 extra"))
        if c.topic == "/status"
        else c
        for c in connections[0]
    ]
    remapped, _ = ros2_types(changed)
    status = next(c.id for c in changed if c.topic == "/status")
    assert "int8 extra" in remapped[status].definition
    assert "int8 extra" not in second[status].definition
