"""Helpers of the bag tests: messages serialized by rosbags (an oracle independent of bagkit)."""

from __future__ import annotations

from typing import Any

import numpy as np
from rosbags.typesys import Stores, get_typestore

# rosbag2 Jazzy's (metadata version 9) serialization of a reliable, volatile, keep-last 10 offer.
QOS_YAML = """\
- history: keep_last
  depth: 10
  reliability: reliable
  durability: volatile
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

TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
IMU = "sensor_msgs/msg/Imu"
STRING = "std_msgs/msg/String"


def imu_cdr(i: int) -> bytes:
    """An Imu message whose fields depend on ``i``, serialized by rosbags."""
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


def string_cdr(text: str) -> bytes:
    """A std_msgs/String serialized by rosbags."""
    return bytes(TYPESTORE.serialize_cdr(TYPESTORE.types[STRING](data=text), STRING))


def deserialize(data: bytes, type_name: str) -> Any:
    """Deserialize with rosbags."""
    return TYPESTORE.deserialize_cdr(data, type_name)
