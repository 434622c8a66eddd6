"""The recorder over real DDS with messages of several MB: each one in the bag byte for byte."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from mcap.reader import make_reader
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import serialize_message
from sensor_msgs.msg import PointCloud2, PointField
from waiting import wait_for, wait_matched

from bagkit.bag import BagReader
from bagkit.recording.options import RecordOptions
from bagkit.ros.record.recorder import Recorder

pytestmark = pytest.mark.ros

TOPIC = "/rec_large/points"
# Sizes of the clouds published: each larger than a chunk, the take thread's byte budget per
# round and Fast DDS's default shared-memory segment; the last one holds zeros (the writer
# compresses it), the others noise (stored as they are).
CLOUD_BYTES = (3 << 20, (9 << 20) + 5, 5 << 20)


def _cloud(index: int, size: int) -> PointCloud2:
    cloud = PointCloud2()
    cloud.header.frame_id = "lidar"
    cloud.header.stamp.sec = 100 + index
    cloud.fields = [PointField(name="x", offset=0, datatype=PointField.UINT8, count=1)]
    cloud.height, cloud.width, cloud.point_step, cloud.row_step = 1, size, 1, size
    cloud.data = bytes(size) if index == len(CLOUD_BYTES) - 1 else os.urandom(size)
    return cloud


def test_messages_of_several_mb_are_recorded_intact(node: Node, tmp_path: Path) -> None:
    bag = tmp_path / "large"
    qos = QoSProfile(
        history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE, depth=1
    )
    publisher = node.create_publisher(PointCloud2, TOPIC, qos)
    sent = [serialize_message(_cloud(i, size)) for i, size in enumerate(CLOUD_BYTES)]
    with Recorder(RecordOptions(bag, topics=(TOPIC,))) as recorder:
        wait_matched(publisher)
        for data in sent:
            publisher.publish(data)
        wait_for(lambda: recorder.progress().messages >= len(sent), timeout=60.0)
    report = recorder.report
    assert report.error is None and report.lost == 0
    assert report.topic(TOPIC).bytes == sum(map(len, sent))
    with BagReader(bag) as reader:
        assert [m.data for m in reader.messages()] == sent
    # The mcap package checks every chunk's CRC-32 and finds the same payloads; the zeros went
    # through the compressed path, the noise through the stored one.
    (mcap_file,) = bag.glob("*.mcap")
    with mcap_file.open("rb") as stream:
        reader_ = make_reader(stream)
        payloads = [m.data for _s, _c, m in reader_.iter_messages()]
        summary = reader_.get_summary()
    assert payloads == sent
    assert summary is not None
    assert {index.compression for index in summary.chunk_indexes} == {"", "zstd"}
