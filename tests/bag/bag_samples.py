"""Helpers of the bag tests: messages serialized by rosbags (an oracle independent of bagkit)."""

from __future__ import annotations

from ros2_messages import IMU, STRING, TYPESTORE, deserialize, imu_cdr, qos_yaml, string_cdr

# rosbag2 Jazzy's serialization of a reliable, volatile, keep-last 10 offer.
QOS_YAML = qos_yaml(depth=10, reliability="reliable", durability="volatile")

__all__ = ["IMU", "QOS_YAML", "STRING", "TYPESTORE", "deserialize", "imu_cdr", "string_cdr"]
