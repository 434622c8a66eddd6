"""Definitions we store decode real rclpy-serialized messages of every type the system uses."""

from __future__ import annotations

import importlib
from pathlib import Path

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rclpy.serialization import serialize_message
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from bagkit.bag import BagWriter, TopicInfo

TYPES = [
    "sensor_msgs/msg/Imu",
    "sensor_msgs/msg/NavSatFix",
    "sensor_msgs/msg/Temperature",
    "sensor_msgs/msg/FluidPressure",
    "sensor_msgs/msg/Image",
    "diagnostic_msgs/msg/DiagnosticArray",
    "nav_msgs/msg/Odometry",
    "geometry_msgs/msg/PoseWithCovarianceStamped",
    "rosgraph_msgs/msg/Clock",
    "std_msgs/msg/String",
]


def _sample(type_name: str) -> tuple[object, bytes]:
    package, _, name = type_name.split("/")
    message = getattr(importlib.import_module(f"{package}.msg"), name)()
    if hasattr(message, "header"):
        message.header.frame_id = "base_link"
        message.header.stamp.sec = 42
    if type_name == "diagnostic_msgs/msg/DiagnosticArray":
        from diagnostic_msgs.msg import DiagnosticStatus, KeyValue

        message.status = [
            DiagnosticStatus(
                level=DiagnosticStatus.ERROR, name="baro", values=[KeyValue(key="p", value="1")]
            )
        ]
    return message, serialize_message(message)


def test_every_type_decodes_with_mcap_ros2_and_rosbags(tmp_path: Path) -> None:
    path = tmp_path / "types"
    samples = {t: _sample(t) for t in TYPES}
    with BagWriter(path) as bag:
        for i, type_name in enumerate(TYPES):
            topic = f"/t{i}"
            bag.add_topic(TopicInfo(topic, type_name))
            bag.write(topic, samples[type_name][1], log_time=i + 1)

    with open(path / "types_0.mcap", "rb") as f:
        decoded = {
            schema.name: message
            for schema, _, _, message in make_reader(
                f, decoder_factories=[DecoderFactory()]
            ).iter_decoded_messages()
        }
    assert set(decoded) == set(TYPES)
    assert decoded["diagnostic_msgs/msg/DiagnosticArray"].status[0].values[0].key == "p"
    assert decoded["nav_msgs/msg/Odometry"].header.frame_id == "base_link"

    # rosbags with an empty typestore: every type must come from the definitions in the bag.
    with AnyReader([path], default_typestore=get_typestore(Stores.EMPTY)) as reader:
        by_type = {c.msgtype: reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages()}
    assert set(by_type) == set(TYPES)
    assert by_type["sensor_msgs/msg/Imu"].header.stamp.sec == 42
    assert by_type["diagnostic_msgs/msg/DiagnosticArray"].status[0].name == "baro"
