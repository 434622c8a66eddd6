"""Pause, resume and split over real DDS: the services, exact counts, latched state on resume."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import pytest
import yaml
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile
from sensor_msgs.msg import Imu
from std_msgs.msg import String
from std_srvs.srv import Trigger
from waiting import wait_for, wait_matched

from bagkit.bag import BagReader
from bagkit.recording.options import FileOptions, RecordOptions
from bagkit.ros.record.recorder import Recorder
from bagkit.ros.serialization import deserializer

pytestmark = pytest.mark.ros

LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)


class Services:
    """Trigger clients of the recorder's services, called from the test's node."""

    def __init__(self, node: Node, recorder_node: str) -> None:
        self.node = node
        self.clients = {
            name: node.create_client(Trigger, f"/{recorder_node}/{name}")
            for name in ("pause", "resume", "is_paused", "split_bagfile")
        }

    def call(self, name: str) -> Any:
        client = self.clients[name]
        assert client.wait_for_service(timeout_sec=10), name
        future = client.call_async(Trigger.Request())
        executor = SingleThreadedExecutor(context=self.node.context)
        executor.add_node(self.node)
        try:
            executor.spin_until_future_complete(future, timeout_sec=10)
        finally:
            executor.remove_node(self.node)
            executor.shutdown()
        assert future.done(), name
        return future.result()


def test_pause_resume_split_through_the_services(node: Node, tmp_path: Path) -> None:
    imu = node.create_publisher(Imu, "/pz/imu", 1000)
    state = node.create_publisher(String, "/pz/state", LATCHED)
    sent = 0

    def stream(count: int) -> None:
        nonlocal sent
        for _ in range(count):
            msg = Imu()
            msg.header.stamp.sec = sent
            imu.publish(msg)
            sent += 1
            time.sleep(0.002)

    services = Services(node, "pz_recorder")
    bag = tmp_path / "paused"
    opts = RecordOptions(bag, regex="^/pz/", node_name="pz_recorder", start_paused=True)
    with Recorder(opts) as recorder:
        wait_matched(imu, state)
        assert services.call("is_paused").success  # paused: success is the answer
        stream(100)
        state.publish(String(data="while paused 1"))
        state.publish(String(data="while paused 2"))
        wait_for(lambda: recorder.progress().paused >= 102)
        assert services.call("resume").message == "resumed"
        assert not services.call("is_paused").success
        stream(100)
        wait_for(lambda: recorder.progress().messages >= 101)
        assert services.call("split_bagfile").success
        stream(100)
        wait_for(lambda: recorder.progress().messages >= 201)
        assert services.call("pause").message == "paused"
        stream(50)
        wait_for(lambda: recorder.progress().messages + recorder.progress().paused >= sent + 2)
    report = recorder.report
    assert report.error is None and report.lost == 0
    imu_record = report.topic("/pz/imu")
    # Every message taken is written or counted paused, none lost.
    assert imu_record.messages + imu_record.paused == sent
    assert imu_record.paused >= 150 - 5  # the first 100 and the last 50 (give or take a batch)
    state_record = report.topic("/pz/state")
    # The last latched message taken while paused was written on resume; the other is paused.
    assert (state_record.messages, state_record.paused) == (1, 1)
    assert len(list(bag.glob("*.mcap"))) == 2
    imu_of, string_of = deserializer("sensor_msgs/msg/Imu"), deserializer("std_msgs/msg/String")
    with BagReader(bag) as reader:
        stamps = [imu_of(m.data).header.stamp.sec for m in reader.messages(topics=["/pz/imu"])]
        states = [string_of(m.data).data for m in reader.messages(topics=["/pz/state"])]
    assert states == ["while paused 2"]
    assert stamps == list(range(stamps[0], stamps[0] + len(stamps)))
    assert len(stamps) == imu_record.messages


def test_circular_recording_keeps_the_newest_files(node: Node, tmp_path: Path) -> None:
    imu = node.create_publisher(Imu, "/pz/circle", 1000)
    bag = tmp_path / "circle"
    files = FileOptions(max_bag_duration_ns=300_000_000, max_bag_files=2)
    opts = RecordOptions(bag, topics=("/pz/circle",), files=files)
    with Recorder(opts) as recorder:
        wait_matched(imu)
        for i in range(400):
            msg = Imu()
            msg.header.stamp.sec = i
            imu.publish(msg)
            time.sleep(0.005)
        wait_for(lambda: recorder.progress().messages >= 400)
    assert recorder.report.lost == 0
    info = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    listed = info["relative_file_paths"]
    assert len(listed) == 2
    assert sorted(listed) == sorted(p.name for p in bag.glob("*.mcap"))
    imu_of = deserializer("sensor_msgs/msg/Imu")
    with BagReader(bag) as reader:
        stamps = [imu_of(m.data).header.stamp.sec for m in reader.messages()]
    # The newest messages, in order, up to the last one published.
    assert stamps == list(range(stamps[0], 400))
    assert info["message_count"] == len(stamps) < 400
