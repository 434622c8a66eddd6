"""ROS 1 bags written by rosbags' rosbag1 writer, and their messages as rosbags reads them back."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from rosbags.rosbag1 import Reader, Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

START_NS = 1_700_000_000_000_000_000
# A package of one's own, as ROS 1 teams have them: time, duration, arrays, strings, nesting.
SAMPLE_MSG = """\
Header header
time taken
duration exposure
uint8[] blob
float32[3] gains
string[] labels
int64 counter
bool ok
"""
SAMPLE = "acme_msgs/msg/Sample"


def ros1_store() -> Any:
    """ROS 1 Noetic's types plus ``acme_msgs/msg/Sample``."""
    store = get_typestore(Stores.ROS1_NOETIC)
    store.register(get_types_from_msg(SAMPLE_MSG, SAMPLE))
    return store


def write_ros1_bag(
    path: Path, n_imu: int = 300, *, compression: str = "none", chunk_threshold: int = 0
) -> Path:
    """A ROS 1 bag: ``/imu`` (Imu at 100 Hz, two connections: two publishers), ``/status``
    (String, latched, every 50th step), ``/sample`` (acme_msgs/Sample every 10th step)."""
    store = ros1_store()
    t = store.types
    rng = np.random.default_rng(1)
    writer = Writer(path)
    if compression != "none":
        writer.set_compression(Writer.CompressionFormat[compression.upper()])
    if chunk_threshold:
        writer.chunk_threshold = chunk_threshold
    with writer:
        imu = [
            writer.add_connection("/imu", "sensor_msgs/msg/Imu", typestore=store, callerid=name)
            for name in ("/driver_a", "/driver_b")
        ]
        status = writer.add_connection(
            "/status", "std_msgs/msg/String", typestore=store, latching=1
        )
        sample = writer.add_connection("/sample", SAMPLE, typestore=store)
        for i in range(n_imu):
            stamp = START_NS + i * 10_000_000
            time = t["builtin_interfaces/msg/Time"](stamp // 10**9, stamp % 10**9)
            header = t["std_msgs/msg/Header"](i, time, "imu_link")
            vec = t["geometry_msgs/msg/Vector3"]
            message = t["sensor_msgs/msg/Imu"](
                header,
                t["geometry_msgs/msg/Quaternion"](0.0, 0.0, 0.0, 1.0),
                rng.random(9),
                vec(*rng.random(3)),
                rng.random(9),
                vec(0.0, 0.0, 9.81 + float(rng.normal())),
                rng.random(9),
            )
            writer.write(imu[i % 2], stamp, store.serialize_ros1(message, "sensor_msgs/msg/Imu"))
            if i % 50 == 0:
                text = t["std_msgs/msg/String"](f"state {i}")
                writer.write(status, stamp, store.serialize_ros1(text, "std_msgs/msg/String"))
            if i % 10 == 0:
                value = t[SAMPLE](
                    header,
                    time,
                    t["builtin_interfaces/msg/Duration"](i, 500),
                    np.arange(i % 7, dtype=np.uint8),
                    np.array([0.5, -1.0, i], np.float32),
                    [f"label{j}" for j in range(i % 3)],
                    -(i**3),
                    i % 20 == 0,
                )
                writer.write(sample, stamp, store.serialize_ros1(value, SAMPLE))
    return path


def ros1_messages(path: Path, topic: str) -> list[tuple[int, Any]]:
    """``(log time, message)`` of a topic as rosbags reads the ROS 1 bag."""
    store = ros1_store()
    with Reader(path) as reader:
        connections = [c for c in reader.connections if c.topic == topic]
        return [
            (time, store.deserialize_ros1(data, conn.msgtype))
            for conn, time, data in reader.messages(connections)
        ]
