"""The recorder over real DDS: known sequences published in-process, read back by three readers."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import pytest
import yaml
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rosbags.highlevel import AnyReader
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Imu
from std_msgs.msg import Int32, String
from waiting import wait_for, wait_matched

from bagkit.bag import BagReader
from bagkit.recording import handoff, write_loop
from bagkit.recording.options import RecordOptions
from bagkit.recording.report import RecordReport
from bagkit.ros.errors import MessageClassNotFoundError
from bagkit.ros.qos import parse_offered_qos_profiles
from bagkit.ros.record import subscriptions
from bagkit.ros.record.recorder import Recorder

pytestmark = pytest.mark.ros

MATCH_TIMEOUT_S = 10.0


def imu(i: int) -> Imu:
    msg = Imu()
    msg.header.stamp.sec = 1000 + i
    msg.header.stamp.nanosec = i * 1000
    msg.header.frame_id = "imu_link"
    msg.linear_acceleration.z = 9.81 + i * 1e-3
    msg.angular_velocity.x = -0.5 * i
    msg.orientation_covariance[0] = -1.0
    return msg


N_IMU, N_TEXT, N_LATE = 300, 120, 20


def test_records_known_sequences_readable_by_rosbags_and_mcap(node: Node, tmp_path: Path) -> None:
    bag = tmp_path / "known"
    report = _record_known_sequences(node, bag)
    assert report.error is None
    assert report.topic("/rec/imu").messages == N_IMU
    assert report.topic("/rec/late").messages == N_LATE
    assert report.topic("/rec/latched").messages == 1
    text = report.topic("/rec/text")
    # Best effort may drop (rarely, on localhost); every hole between the first and the last
    # message received must be counted as a middleware gap.
    with BagReader(bag) as bag_reader:
        sequences = [m.sequence for m in bag_reader.messages(topics=["/rec/text"])]
    assert text.messages + text.gaps == sequences[-1] - sequences[0] + 1
    assert report.lost == text.gaps
    assert {t.publishers for t in report.topics} == {1}
    _check_rosbags_reads_what_was_published(bag, text.messages)
    _check_mcap_records(bag, {t.topic: t.messages for t in report.topics if t.messages})


def _record_known_sequences(node: Node, bag: Path) -> RecordReport:
    """Record reliable, best-effort, transient-local and late-appearing topics of ``node``."""
    reliable = node.create_publisher(Imu, "/rec/imu", 100)
    best_effort = node.create_publisher(
        String, "/rec/text", QoSProfile(depth=100, reliability=ReliabilityPolicy.BEST_EFFORT)
    )
    latched = node.create_publisher(
        String, "/rec/latched", QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    )
    # Published before the recorder exists: only transient-local durability brings it over.
    latched.publish(String(data="map v1"))
    with Recorder(RecordOptions(bag, regex="^/rec/")) as recorder:
        wait_matched(reliable, best_effort, latched)
        for i in range(N_IMU):
            reliable.publish(imu(i))
            if i < N_TEXT:
                best_effort.publish(String(data=f"text {i}"))
            time.sleep(0.001)
        # A topic that appears while recording is recorded from its first matched message.
        late = node.create_publisher(Int32, "/rec/late", 10)
        wait_matched(late)
        for i in range(N_LATE):
            late.publish(Int32(data=i * i))
        wait_for(lambda: recorder.progress().messages >= N_IMU + 1 + N_LATE)
        time.sleep(0.2)
    return recorder.report


def _check_rosbags_reads_what_was_published(bag: Path, texts_recorded: int) -> None:
    """Every message deserializes, in publication order, with the published content."""
    with AnyReader([bag]) as reader:
        by_topic: dict[str, list[Any]] = {}
        for connection, _timestamp, raw in reader.messages():
            by_topic.setdefault(connection.topic, []).append(
                reader.deserialize(raw, connection.msgtype)
            )
    imus = by_topic["/rec/imu"]
    assert [m.header.stamp.sec for m in imus] == [1000 + i for i in range(N_IMU)]
    assert [m.angular_velocity.x for m in imus] == [-0.5 * i for i in range(N_IMU)]
    assert imus[7].header.frame_id == "imu_link"
    assert imus[7].orientation_covariance[0] == -1.0
    assert [m.data for m in by_topic["/rec/late"]] == [i * i for i in range(N_LATE)]
    assert [m.data for m in by_topic["/rec/latched"]] == ["map v1"]
    texts = [m.data for m in by_topic["/rec/text"]]
    assert texts == sorted(texts, key=lambda t: int(t.split()[1]))
    assert len(texts) == texts_recorded


def _check_mcap_records(bag: Path, expected_counts: dict[str, int]) -> None:
    """mcap + mcap_ros2 read the same messages, with the record fields rosbag2 defines."""
    counts: dict[str, int] = {}
    for mcap_file in sorted(bag.glob("*.mcap")):
        with mcap_file.open("rb") as stream:
            reader_ = make_reader(stream, decoder_factories=[DecoderFactory()])
            assert reader_.get_header().profile == "ros2"
            for schema, channel, message, decoded in reader_.iter_decoded_messages():
                assert schema is not None and schema.encoding == "ros2msg"
                assert channel.message_encoding == "cdr"
                counts[channel.topic] = counts.get(channel.topic, 0) + 1
                # log_time is the receive time, publish_time the source timestamp.
                assert message.publish_time <= message.log_time
                if channel.topic == "/rec/imu":
                    # Publication sequence numbers of the only publisher: 1, 2, 3...
                    assert message.sequence == decoded.header.stamp.sec - 1000 + 1
    assert counts == expected_counts


def test_metadata_and_channel_qos(node: Node, tmp_path: Path) -> None:
    latched = node.create_publisher(
        String, "/meta/latched", QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    )
    latched.publish(String(data="hello"))
    bag = tmp_path / "meta"
    with Recorder(RecordOptions(bag, topics=("meta/latched",))) as recorder:
        wait_for(lambda: recorder.progress().messages == 1)
    info = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["version"] == 9
    assert info["storage_identifier"] == "mcap"
    assert info["relative_file_paths"] == ["meta_0.mcap"]
    assert info["message_count"] == 1
    assert info["ros_distro"] == "jazzy"
    (topic,) = info["topics_with_message_count"]
    assert topic["message_count"] == 1
    meta = topic["topic_metadata"]
    assert (meta["name"], meta["type"], meta["serialization_format"]) == (
        "/meta/latched",
        "std_msgs/msg/String",
        "cdr",
    )
    assert meta["type_description_hash"].startswith("RIHS01_")
    # Version 9 stores the profiles as a YAML sequence (rosbag2 Jazzy's form).
    (offered,) = parse_offered_qos_profiles(yaml.safe_dump(meta["offered_qos_profiles"]))
    assert offered.durability == DurabilityPolicy.TRANSIENT_LOCAL
    assert offered.reliability == ReliabilityPolicy.RELIABLE
    assert info["custom_data"]["bagkit.record.lost"] == "0"
    assert yaml.safe_load(info["custom_data"]["bagkit.record.loss"]) == {
        "/meta/latched": {
            "messages": 1,
            "bytes": recorder.report.topic("/meta/latched").bytes,
            "gaps": 0,
            "overflow": 0,
            "write_failed": 0,
            "publishers": 1,
        }
    }
    with BagReader(bag) as reader:
        (message,) = reader.messages()
        stored = reader.topics["/meta/latched"].offered_qos_profiles
        assert yaml.safe_load(stored) == meta["offered_qos_profiles"]
        assert info["starting_time"]["nanoseconds_since_epoch"] == message.log_time


def test_publisher_with_weaker_qos_joining_later_is_recorded(node: Node, tmp_path: Path) -> None:
    """Subscribed reliable; a best-effort publisher appears: re-subscribed to match both."""
    reliable = node.create_publisher(String, "/mixed", 10)
    bag = tmp_path / "mixed"
    with Recorder(RecordOptions(bag, topics=("/mixed",))) as recorder:
        wait_matched(reliable)
        reliable.publish(String(data="reliable 0"))
        best_effort = node.create_publisher(
            String, "/mixed", QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT)
        )
        wait_matched(best_effort)
        # The recorder replaced its reliable subscription: until the old one is off the graph,
        # the reliable publisher may still count it as its match, and publish to nobody.
        wait_for(
            lambda: (
                [
                    info.qos_profile.reliability
                    for info in node.get_subscriptions_info_by_topic("/mixed")
                ]
                == [ReliabilityPolicy.BEST_EFFORT]
            ),
            what="the recorder's best-effort subscription alone",
        )
        wait_matched(reliable)
        for i in range(1, 4):
            reliable.publish(String(data=f"reliable {i}"))
            best_effort.publish(String(data=f"best effort {i}"))
            time.sleep(0.01)
        wait_for(lambda: recorder.progress().messages == 7)
    assert recorder.report.topic("/mixed").publishers == 2
    assert recorder.report.lost == 0
    with BagReader(bag) as reader:
        assert reader.topic_counts == {"/mixed": 7}


def test_unknown_message_package_is_skipped_with_one_warning(
    node: Node, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    known = subscriptions.import_message_type

    def without_int32(type_name: str) -> Any:
        # Stands for a package that is not installed: the publisher's own process has it.
        if type_name == "std_msgs/msg/Int32":
            raise MessageClassNotFoundError(f"message type {type_name} is not installed")
        return known(type_name)

    monkeypatch.setattr(subscriptions, "import_message_type", without_int32)
    unknown = node.create_publisher(Int32, "/skip/int", 10)
    text = node.create_publisher(String, "/skip/text", 10)
    warnings: list[str] = []
    options = RecordOptions(tmp_path / "skip", regex="^/skip/")
    with Recorder(options, on_warning=warnings.append) as recorder:
        wait_matched(text)
        text.publish(String(data="kept"))
        unknown.publish(Int32(data=1))
        wait_for(lambda: recorder.progress().messages == 1)
        time.sleep(0.3)  # several graph polls: still one warning
    assert warnings == ["not recording /skip/int: message type std_msgs/msg/Int32 is not installed"]
    assert list(recorder.report.skipped) == ["/skip/int"]
    assert [t.topic for t in recorder.report.topics] == ["/skip/text"]


def test_use_sim_time_stamps_log_time_from_clock(node: Node, tmp_path: Path) -> None:
    clock = node.create_publisher(
        Clock, "/clock", QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)
    )
    data = node.create_publisher(String, "/sim/data", 10)
    bag = tmp_path / "sim"
    sim_times = []
    with Recorder(RecordOptions(bag, topics=("/sim/data",), use_sim_time=True)) as recorder:
        wait_matched(clock, data)
        for i in range(10):
            sim = Clock()
            sim.clock.sec = 500 + i
            clock.publish(sim)
            sim_times.append((500 + i) * 1_000_000_000)
            time.sleep(0.05)
            data.publish(String(data=str(i)))
            time.sleep(0.05)
        wait_for(lambda: recorder.progress().messages == 10)
    with BagReader(bag) as reader:
        messages = list(reader.messages())
    # Each message carries the sim time current when it was taken; publish_time stays wall time.
    assert [m.log_time for m in messages] == sim_times
    assert all(m.publish_time > 1_600_000_000 * 1_000_000_000 for m in messages)


def test_qos_overrides_replace_the_adapted_profile(node: Node, tmp_path: Path) -> None:
    publisher = node.create_publisher(String, "/ovr", 10)
    overrides = tmp_path / "overrides.yaml"
    overrides.write_text("ovr:\n  reliability: best_effort\n  depth: 5\n")  # a relative name
    options = RecordOptions(tmp_path / "ovr", topics=("/ovr",), qos_overrides=overrides)
    with Recorder(options) as rec:
        wait_matched(publisher)

        def recorder_subscriptions() -> list[Any]:
            infos = node.get_subscriptions_info_by_topic("/ovr")
            return [s for s in infos if s.node_name == "bagkit_recorder"]

        # Matching and the graph cache are updated by different discovery callbacks: the
        # publisher can match before the subscription's node name is in this node's graph.
        wait_for(lambda: len(recorder_subscriptions()) == 1)
        (subscription,) = recorder_subscriptions()
        publisher.publish(String(data="over"))
        wait_for(lambda: rec.progress().messages == 1)
    # Adapted, it would have been reliable keep-all: the publisher is reliable.
    assert subscription.qos_profile.reliability == ReliabilityPolicy.BEST_EFFORT


def test_write_queue_overflow_is_counted(
    node: Node, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A writer slower than the input: every message is either in the bag or counted lost."""
    write_batch = write_loop.BagWriter.write_batch

    def slow_write_batch(self: Any, topic: str, payloads: list[bytes], **kwargs: Any) -> None:
        time.sleep(0.005 * len(payloads))  # stands for a disk that cannot keep up
        write_batch(self, topic, payloads, **kwargs)

    monkeypatch.setattr(write_loop.BagWriter, "write_batch", slow_write_batch)
    monkeypatch.setattr(handoff, "QUEUE_WAIT_S", 0.01)
    publisher = node.create_publisher(String, "/slow", 1000)
    n = 600
    # Room for about two batches (5 ms of messages each) waiting for the writer.
    with Recorder(RecordOptions(tmp_path / "slow", topics=("/slow",), queue_bytes=200)) as recorder:
        wait_matched(publisher)
        for i in range(n):
            publisher.publish(String(data=f"slow {i:04d}"))
            time.sleep(0.001)
        wait_for(lambda: recorder.progress().messages + recorder.progress().lost == n, 20)
    record = recorder.report.topic("/slow")
    assert record.overflow > 0
    assert record.messages + record.lost == n
    with BagReader(tmp_path / "slow") as reader:
        assert reader.topic_counts == {"/slow": record.messages}


def test_type_without_a_definition_is_skipped_and_recording_goes_on(
    node: Node, tmp_path: Path
) -> None:
    # A service's request type is importable, but there is no .msg file to store in the bag:
    # the same holds for an action's feedback message.
    from rcl_interfaces.srv import ListParameters

    odd = node.create_publisher(ListParameters.Request, "/odd/request", 10)
    text = node.create_publisher(String, "/odd/text", 10)
    warnings: list[str] = []
    bag = tmp_path / "odd"
    with Recorder(RecordOptions(bag, regex="^/odd/"), on_warning=warnings.append) as recorder:
        wait_matched(text)
        wait_for(lambda: "/odd/request" in recorder.report.skipped)
        odd.publish(ListParameters.Request())
        for i in range(3):
            text.publish(String(data=f"kept {i}"))
        wait_for(lambda: recorder.progress().messages == 3)
        time.sleep(0.3)  # several graph polls: still one warning
    assert len(warnings) == 1
    assert warnings[0].startswith("not recording /odd/request: no message definition")
    assert "rcl_interfaces/srv/ListParameters_Request" in warnings[0]
    assert recorder.report.error is None
    assert [t.topic for t in recorder.report.topics] == ["/odd/text"]
    with BagReader(bag) as reader:
        assert reader.topic_counts == {"/odd/text": 3}


def test_subscription_error_in_discovery_still_finishes_the_bag(
    node: Node, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    publisher = node.create_publisher(String, "/broken/topic", 10)
    create_subscription = Node.create_subscription

    def failing(self: Node, message_type: Any, topic: str, *args: Any, **kwargs: Any) -> Any:
        # Stands for the middleware refusing the subscription (rclpy raises RuntimeError).
        if topic == "/broken/topic":
            raise RuntimeError("could not create subscription: middleware refused")
        return create_subscription(self, message_type, topic, *args, **kwargs)

    monkeypatch.setattr(Node, "create_subscription", failing)
    wait_for(lambda: bool(node.get_publishers_info_by_topic("/broken/topic")))
    bag = tmp_path / "broken"
    recorder = Recorder(RecordOptions(bag, topics=("/broken/topic",)))
    recorder.start()
    assert recorder.stopped.wait(MATCH_TIMEOUT_S)
    report = recorder.stop()
    assert publisher.get_subscription_count() == 0
    assert report.error == "recording stopped: could not create subscription: middleware refused"
    with BagReader(bag, allow_empty=True) as reader:
        assert reader.has_summary
        assert reader.message_count == 0
    assert (bag / "metadata.yaml").is_file()
