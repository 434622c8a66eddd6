"""MCAP bags that other tools write, through the CLI: rosbags' rosbag2 writer (empty bags
included), mcap_ros2's writer (lz4, zstd, uncompressed), mcap's writer with optional summary
records left out, and bags as rosbag2 Rolling writes them (ros2idl schemas, ``ACTION:`` texts on
an action's five topics, two schemas of one type name). info, info -v, echo, stats, doctor and
filter run on each; values are compared with rosbags' or mcap_ros2's reader, or with the values
the test wrote where no other reader decodes (ros2idl with #include lines, ACTION texts)."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from bagkit_runs import bagkit_in_process, bagkit_subprocess
from mcap.reader import make_reader
from mcap.writer import CompressionType
from mcap_ros2.decoder import DecoderFactory
from mcap_ros2.writer import Writer as Ros2Writer
from rolling_bags import (
    EVENT_INFO,
    SEPARATOR,
    RollingBag,
    action_definition,
    action_topics,
    fibonacci_messages,
    idl_definition,
    msg_definition,
    serialize,
)
from ros2_messages import IMU, TEMPERATURE, TYPESTORE
from rosbags.rosbag2 import Reader, StoragePlugin, Writer
from test_bag_mcap_variants import VARIANTS, _write

ImuMsg = TYPESTORE.types[IMU]
Header = TYPESTORE.types["std_msgs/msg/Header"]
Time = TYPESTORE.types["builtin_interfaces/msg/Time"]
Quaternion = TYPESTORE.types["geometry_msgs/msg/Quaternion"]
Vector3 = TYPESTORE.types["geometry_msgs/msg/Vector3"]


def bagkit(*args: str | Path) -> subprocess.CompletedProcess[str]:
    """``bagkit ARGS`` in this process (tests/bagkit_runs.py): what the bags hold is the point,
    not the process; one run per test module is a real ``bagkit`` process (``ok(process=True)``)."""
    return bagkit_in_process(list(args))


def ok(*args: str | Path, process: bool = False) -> str:
    done = bagkit_subprocess(list(args), Path.cwd()) if process else bagkit(*args)
    assert done.returncode == 0, done.stderr
    assert "Traceback" not in done.stderr
    return done.stdout


def echo_json(bag: Path, topic: str, *extra: str) -> list[dict[str, Any]]:
    return [
        json.loads(line)
        for line in ok("echo", bag, topic, "--format", "json", *extra).split("\n")
        if line
    ]


def _imu(i: int) -> Any:
    covariance = np.arange(9, dtype=np.float64) * i
    return ImuMsg(
        Header(Time(i, 7), "imu"),
        Quaternion(0.0, 0.0, 0.0, 1.0),
        covariance,
        Vector3(0.1 * i, -0.2 * i, 0.5),
        covariance,
        Vector3(1.0, 2.0, 9.81 + 0.01 * i),
        covariance,
    )


def write_rosbags_bag(path: Path, count: int) -> None:
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        imu = writer.add_connection("/imu", IMU, typestore=TYPESTORE)
        writer.add_connection("/temperature", TEMPERATURE, typestore=TYPESTORE)
        for i in range(count):
            data = TYPESTORE.serialize_cdr(_imu(i), IMU)
            writer.write(imu, 1_000_000_000 + i * 10_000_000, data)


def rosbags_values(path: Path) -> list[tuple[int, float, int]]:
    """(log time, linear_acceleration.x, header.stamp.sec) of /imu, read by rosbags."""
    with Reader(path) as reader:
        return [
            (t, msg.linear_acceleration.x, msg.header.stamp.sec)
            for connection, t, raw in reader.messages()
            for msg in [TYPESTORE.deserialize_cdr(raw, connection.msgtype)]
        ]


def test_rosbags_mcap_bag_through_every_command(tmp_path: Path) -> None:
    bag = tmp_path / "rosbags_bag"
    write_rosbags_bag(bag, 120)
    expected = rosbags_values(bag)
    info = json.loads(ok("info", bag, "--format", "json", process=True))
    assert info["summary"] is True
    assert {t["topic"]: t["count"] for t in info["topics"]} == {"/imu": 120, "/temperature": 0}
    assert (info["start_ns"], info["end_ns"]) == (expected[0][0], expected[-1][0])
    assert "salvaged" not in ok("info", "-v", bag)
    records = echo_json(bag, "/imu")
    assert [
        (r["log_time"], r["data"]["linear_acceleration"]["x"], r["data"]["header"]["stamp"]["sec"])
        for r in records
    ] == expected
    stats = json.loads(ok("stats", "summary", bag, "-t", "/imu", "--format", "json"))
    fields = {f["field"]: f for f in stats["topics"][0]["fields"]}
    xs = np.array([x for _, x, _ in expected])
    assert fields["linear_acceleration.x"]["count"] == len(xs)
    assert fields["linear_acceleration.x"]["mean"] == pytest.approx(xs.mean())
    assert fields["linear_acceleration.x"]["max"] == pytest.approx(xs.max())
    assert "healthy" in ok("doctor", "--deep", bag)
    out = tmp_path / "filtered"
    ok(
        "filter", bag, "-o", out, "--topics", "/imu", "--start", "0.5", "--end", "1"
    )  # from the start
    kept = [v for v in expected if 1_500_000_000 <= v[0] < 2_000_000_000]
    assert [
        (r["log_time"], r["data"]["linear_acceleration"]["x"]) for r in echo_json(out, "/imu")
    ] == [(t, x) for t, x, _ in kept]


def test_empty_rosbags_mcap_bag_is_valid(tmp_path: Path) -> None:
    bag = tmp_path / "empty"
    write_rosbags_bag(bag, 0)
    done = bagkit("doctor", bag)
    assert done.returncode == 0, done.stderr
    assert "ends before it starts" not in done.stdout + done.stderr
    assert "healthy (0 messages" in done.stdout
    from bagkit.bag import BagReader

    with BagReader(bag, allow_empty=True) as reader:
        assert reader.topic_counts == {"/imu": 0, "/temperature": 0}
        assert reader.problems == [] and reader.has_summary
        assert (reader.start_ns, reader.end_ns) == (0, 0)
    # Nothing lost: recover writes it whole, without 'no message could be recovered' (exit 1).
    done = bagkit("recover", bag, "-o", tmp_path / "recovered")
    assert done.returncode == 0 and "error" not in done.stderr, done.stderr
    assert "0 messages (2 topics" in done.stdout
    info = json.loads(ok("info", tmp_path / "recovered", "--format", "json"))
    assert {t["topic"]: t["count"] for t in info["topics"]} == {"/imu": 0, "/temperature": 0}


@pytest.mark.parametrize(
    "compression", [CompressionType.LZ4, CompressionType.ZSTD, CompressionType.NONE]
)
def test_mcap_ros2_writer(tmp_path: Path, compression: CompressionType) -> None:
    path = tmp_path / "mcap_ros2.mcap"
    with open(path, "wb") as f:
        writer = Ros2Writer(f, chunk_size=2048, compression=compression)
        schema = writer.register_msgdef("std_msgs/Header", msg_definition("std_msgs/msg/Header"))
        for i in range(200):
            message = {"stamp": {"sec": i, "nanosec": 3 * i}, "frame_id": f"frame{i % 3}"}
            writer.write_message("/header", schema, message, log_time=10_000 + i, publish_time=i)
        writer.finish()
    with open(path, "rb") as f:
        expected = [
            (m.log_time, d.stamp.nanosec, d.frame_id)
            for _, _, m, d in make_reader(
                f, decoder_factories=[DecoderFactory()]
            ).iter_decoded_messages()
        ]
    records = echo_json(path, "/header")
    assert [
        (r["log_time"], r["data"]["stamp"]["nanosec"], r["data"]["frame_id"]) for r in records
    ] == expected
    stats = json.loads(ok("stats", "summary", path, "--format", "json"))
    fields = {f["field"]: f for f in stats["topics"][0]["fields"]}
    assert fields["stamp.nanosec"]["mean"] == pytest.approx(np.mean([n for _, n, _ in expected]))
    assert "healthy (200 messages" in ok("doctor", "--deep", path)
    assert "salvaged" not in ok("info", "-v", path)


@pytest.mark.parametrize(
    "variant", ["no_statistics", "no_indexes", "no_chunks", "no_summary_offsets_or_crcs"]
)
def test_summaries_without_optional_records(tmp_path: Path, variant: str) -> None:
    path = tmp_path / f"{variant}.mcap"
    _write(path, VARIANTS[variant])
    with open(path, "rb") as f:
        counts: dict[str, int] = {}
        for _, channel, _ in make_reader(f).iter_messages():
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
    info = json.loads(ok("info", path, "--format", "json"))
    assert info["summary"] is True
    assert {t["topic"]: t["count"] for t in info["topics"]} == counts
    assert "salvaged" not in ok("info", "-v", path)
    doctor = ok("doctor", "--deep", path)
    assert f"healthy ({sum(counts.values())} messages" in doctor
    stats = json.loads(ok("stats", "summary", path, "-t", "/imu", "--format", "json"))
    assert stats["topics"][0]["count"] == counts["/imu"]


def _rolling_bag(path: Path) -> dict[str, list[tuple[int, dict[str, Any]]]]:
    """A bag as rosbag2 Rolling writes it; returns what was written per topic."""
    written: dict[str, list[tuple[int, dict[str, Any]]]] = {}
    bag = RollingBag(path)
    parts = fibonacci_messages(3)
    for part, (topic, type_name) in action_topics(
        "/fibonacci", "test_msgs/action/Fibonacci"
    ).items():
        channel = bag.topic(topic, type_name, action_definition("test_msgs/action/Fibonacci"))
        for t, message in parts[part]:
            bag.write(channel, t, serialize(type_name, message))
        written[topic] = parts[part]
    # A second action: its status schema (same type name) holds another action's text.
    topic, type_name = action_topics("/nested", "test_msgs/action/NestedMessage")["status"]
    channel = bag.topic(topic, type_name, action_definition("test_msgs/action/NestedMessage"))
    for t, message in parts["status"]:
        bag.write(channel, t + 7, serialize(type_name, message))
    written[topic] = [(t + 7, m) for t, m in parts["status"]]
    header = "std_msgs/msg/Header"
    channel = bag.topic("/idl_header", header, idl_definition(header), "ros2idl")
    written["/idl_header"] = []
    for i in range(4):
        message = {"stamp": {"sec": i, "nanosec": 1}, "frame_id": f"f{i}"}
        bag.write(channel, 1_000_000_000 + i, serialize(header, message))
        written["/idl_header"].append((1_000_000_000 + i, message))
    # One type name, two schemas: a field added between two recordings merged into one file.
    texts = {"/reading_v1": "float64 value\n", "/reading_v2": "float64 value\nuint32 count\n"}
    for topic, text in texts.items():
        channel = bag.topic(topic, "my_msgs/msg/Reading", text)
        written[topic] = []
        for i in range(5):
            message = {"value": i * 0.25} | ({"count": 10 + i} if "count" in text else {})
            bag.write(channel, 2_000_000_000 + i, serialize("my_msgs/msg/Reading", message, text))
            written[topic].append((2_000_000_000 + i, message))
    bag.finish()
    return written


def test_rolling_bag_actions_idl_and_schemas_per_topic(tmp_path: Path) -> None:
    path = tmp_path / "rolling.mcap"
    written = _rolling_bag(path)
    for topic, messages in written.items():
        records = echo_json(path, topic)
        assert [(r["log_time"], r["data"]) for r in records] == messages, topic
    action = echo_json(path, "/fibonacci")
    fibonacci = [
        (t, m) for topic, ms in written.items() if topic.startswith("/fibonacci/") for t, m in ms
    ]
    assert [(r["log_time"], r["data"]) for r in action] == sorted(fibonacci, key=lambda tm: tm[0])
    info = json.loads(ok("info", path, "--format", "json"))
    assert {a["action"]: a["type"] for a in info["actions"]} == {
        "/fibonacci": "test_msgs/action/Fibonacci",
        "/nested": "",
    }
    stats = json.loads(ok("stats", "summary", path, "-t", "/reading_v2", "--format", "json"))
    fields = {f["field"]: f for f in stats["topics"][0]["fields"]}
    assert fields["count"]["mean"] == pytest.approx(12.0)
    total = sum(len(messages) for messages in written.values())
    assert f"healthy ({total} messages in 1 file, all decoded)" in ok("doctor", "--deep", path)
    out = tmp_path / "filtered"
    ok("filter", path, "-o", out, "--topics", "/reading_v1", "/reading_v2", "/idl_header")
    for topic in ("/reading_v1", "/reading_v2", "/idl_header"):
        assert [(r["log_time"], r["data"]) for r in echo_json(out, topic)] == written[topic]


@pytest.mark.parametrize(
    ("text", "why"),
    [
        (
            f"{'=' * 80}\nIDL: my_msgs/msg/Reading\nmodule my_msgs {{ module msg {{\n"
            "struct Reading { double value;; }; }; };\n",
            "IDL my_msgs/msg/Reading does not parse at line",
        ),
        (
            action_definition("test_msgs/action/Fibonacci", "int32 order\n---\nint32[] sequence\n"),
            "ACTION test_msgs/action/Fibonacci has 2 sections, not 3",
        ),
    ],
    ids=["idl", "action"],
)
def test_bad_definition_texts_are_one_error_line(tmp_path: Path, text: str, why: str) -> None:
    path = tmp_path / "bad.mcap"
    bag = RollingBag(path)
    channel = bag.topic(
        "/bad",
        "test_msgs/action/Fibonacci_FeedbackMessage" if "ACTION" in text else "my_msgs/msg/Reading",
        text,
    )
    good = bag.topic("/good", "my_msgs/msg/Reading", "float64 value\n")
    for i in range(3):
        bag.write(channel, 1000 + i, b"\x00\x01\x00\x00" + bytes(8))
        bag.write(
            good, 1000 + i, serialize("my_msgs/msg/Reading", {"value": 1.5}, "float64 value\n")
        )
    bag.finish()
    done = bagkit("echo", path, "/bad")
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and why in lines[0], done.stderr
    assert [r["data"] for r in echo_json(path, "/good")] == [{"value": 1.5}] * 3
    doctor = bagkit("doctor", path)
    assert doctor.returncode != 0 and why in doctor.stdout + doctor.stderr
    assert "Traceback" not in doctor.stderr


def test_bag_writer_keeps_one_schema_per_text(tmp_path: Path) -> None:
    from bagkit.bag import BagWriter, TopicInfo

    texts = {"/v1": "float64 value\n", "/v2": "float64 value\nuint32 count\n"}
    header = "std_msgs/msg/Header"
    with BagWriter(tmp_path / "out") as bag:
        for topic, text in texts.items():
            bag.add_topic(TopicInfo(topic, "my_msgs/msg/Reading"), definition=text)
            message = {"value": 2.5} | ({"count": 3} if "count" in text else {})
            bag.write(topic, serialize("my_msgs/msg/Reading", message, text), log_time=5)
        bag.add_topic(TopicInfo("/idl", header), definition=idl_definition(header))
        stamp = {"stamp": {"sec": 1, "nanosec": 2}, "frame_id": "x"}
        bag.write("/idl", serialize(header, stamp), log_time=6)
    with open(tmp_path / "out" / "out_0.mcap", "rb") as f:
        schemas = make_reader(f).get_summary().schemas.values()
    assert sorted((s.name, s.encoding, s.data.decode()) for s in schemas) == sorted(
        [("my_msgs/msg/Reading", "ros2msg", text) for text in texts.values()]
        + [(header, "ros2idl", idl_definition(header))]
    )
    assert [r["data"] for r in echo_json(tmp_path / "out", "/v2")] == [{"value": 2.5, "count": 3}]
    assert [r["data"] for r in echo_json(tmp_path / "out", "/idl")] == [stamp]


def test_kilted_srv_text_of_a_service_event(tmp_path: Path) -> None:
    """Kilted's service-event schema: ``SRV: pkg/srv/Name`` before the ``.srv`` text."""
    path = tmp_path / "srv.mcap"
    bag = RollingBag(path)
    text = f"{SEPARATOR}SRV: example_interfaces/srv/AddTwoInts\nint64 a\nint64 b\n---\nint64 sum\n"
    oracle = (
        "service_msgs/ServiceEventInfo info\nexample_interfaces/Req[<=1] request\n"
        f"example_interfaces/Resp[<=1] response\n{SEPARATOR}{EVENT_INFO}{SEPARATOR}"
        f"MSG: example_interfaces/Req\nint64 a\nint64 b\n{SEPARATOR}"
        "MSG: example_interfaces/Resp\nint64 sum\n"
    )
    channel = bag.topic("/add/_service_event", "example_interfaces/srv/AddTwoInts_Event", text)
    events = [(0, [{"a": 1, "b": 2}], []), (3, [], [{"sum": 3}])]  # REQUEST_SENT, RESPONSE_RECEIVED
    for i, (kind, request, response) in enumerate(events):
        info = {"event_type": kind, "stamp": {"sec": 1, "nanosec": i}, "client_gid": [1] * 16}
        event = {"info": info | {"sequence_number": 1}, "request": request, "response": response}
        bag.write(channel, 1000 + i, serialize("example_interfaces/srv/E", event, oracle))
    bag.finish()
    (call,) = echo_json(path, "/add")
    assert (call["request"], call["response"], call["events"]) == (
        {"a": 1, "b": 2},
        {"sum": 3},
        ["REQUEST_SENT", "RESPONSE_RECEIVED"],
    )
