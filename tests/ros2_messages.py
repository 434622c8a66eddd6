"""Messages and QoS text as rosbags and rosbag2 write them: oracles independent of bagkit,
shared by the test packages (tests/bag, tests/surgery, tests/cli)."""

from __future__ import annotations

from typing import Any

import numpy as np
from rosbags.typesys import Stores, get_typestore

TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
IMU = "sensor_msgs/msg/Imu"
STRING = "std_msgs/msg/String"
TEMPERATURE = "sensor_msgs/msg/Temperature"
# rosbag2's "infinite" durations in metadata.yaml (version 9).
_INFINITE = "    sec: 9223372036\n    nsec: 854775807"
# rosbag2 Jazzy's schema (as in its sqlite3 test bags).
DB3_SCHEMA = """
CREATE TABLE schema(schema_version INTEGER PRIMARY KEY, ros_distro TEXT NOT NULL);
CREATE TABLE metadata(id INTEGER PRIMARY KEY, metadata_version INTEGER NOT NULL,
                      metadata TEXT NOT NULL);
CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL,
                    serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL,
                    type_description_hash TEXT NOT NULL);
CREATE TABLE message_definitions(id INTEGER PRIMARY KEY, topic_type TEXT NOT NULL,
                                 encoding TEXT NOT NULL, encoded_message_definition TEXT NOT NULL,
                                 type_description_hash TEXT NOT NULL);
CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL,
                      timestamp INTEGER NOT NULL, data BLOB NOT NULL);
CREATE INDEX timestamp_idx ON messages (timestamp ASC);
"""


def qos_yaml(*, depth: int, reliability: str, durability: str) -> str:
    """rosbag2 Jazzy's (metadata version 9) text of one offered QoS profile."""
    return (
        f"- history: keep_last\n  depth: {depth}\n  reliability: {reliability}\n"
        f"  durability: {durability}\n  deadline:\n{_INFINITE}\n  lifespan:\n{_INFINITE}\n"
        f"  liveliness: automatic\n  liveliness_lease_duration:\n{_INFINITE}\n"
        "  avoid_ros_namespace_conventions: false"
    )


def string_cdr(text: str) -> bytes:
    """A std_msgs/String serialized by rosbags."""
    return bytes(TYPESTORE.serialize_cdr(TYPESTORE.types[STRING](data=text), STRING))


def imu_cdr(i: int) -> bytes:
    """An Imu message whose fields (and frame id length) depend on ``i``, serialized by rosbags."""
    t = TYPESTORE.types
    header = t["std_msgs/msg/Header"](
        stamp=t["builtin_interfaces/msg/Time"](sec=i // 10, nanosec=(i % 10) * 100_000_000),
        frame_id="imu" + "x" * (i % 3),
    )
    vec = t["geometry_msgs/msg/Vector3"]
    msg = t[IMU](
        header=header,
        orientation=t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
        orientation_covariance=np.zeros(9),
        angular_velocity=vec(x=0.001 * i, y=0.0, z=-0.001 * i),
        angular_velocity_covariance=np.zeros(9),
        linear_acceleration=vec(x=0.01 * i, y=0.5, z=9.81),
        linear_acceleration_covariance=np.zeros(9),
    )
    return bytes(TYPESTORE.serialize_cdr(msg, IMU))


def deserialize(data: bytes, type_name: str) -> Any:
    """Deserialize with rosbags."""
    return TYPESTORE.deserialize_cdr(data, type_name)
