"""The column-by-column migration of a chunk's payloads gives the bytes the message-by-message
one gives, and hands back what it cannot take."""

from __future__ import annotations

import numpy as np
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import Imu

from bagkit.bag import TopicInfo, message_definition
from bagkit.migrate import Target, migrate_topic

IMU = "sensor_msgs/msg/Imu"
LAST = "float64[9] linear_acceleration_covariance"


def _messages() -> list[Imu]:
    found = []
    for i in range(40):
        msg = Imu()
        msg.header.frame_id = "imu" + "x" * (i % 3)  # three layouts
        msg.header.stamp.sec = i
        msg.linear_acceleration.z = 9.81 + i
        msg.orientation_covariance[4] = 0.5 * i
        found.append(msg)
    return found


def test_bulk_equals_one_by_one() -> None:
    text = "\n".join(
        line for line in message_definition(IMU).splitlines() if line.split("#")[0].strip() != LAST
    )
    migration = migrate_topic(TopicInfo("/imu", IMU), text, Target())
    assert migration is not None and migration.bulk is not None
    messages = _messages()
    old = [bytes(serialize_message(m))[:-72] for m in messages]
    buf = np.frombuffer(b"".join(old), np.uint8)
    lengths = np.array([len(p) for p in old], np.int64)
    starts = np.concatenate([[0], np.cumsum(lengths)[:-1]]).astype(np.int64)
    bulk = migration.bulk.payloads(buf, starts, lengths)
    assert bulk is not None
    assert bulk == [migration.payload(p) for p in old]
    decoded = [deserialize_message(p, Imu) for p in bulk]
    assert [(d.header.frame_id, d.header.stamp.sec, d.linear_acceleration.z) for d in decoded] == [
        (m.header.frame_id, m.header.stamp.sec, m.linear_acceleration.z) for m in messages
    ]
    assert {tuple(d.linear_acceleration_covariance) for d in decoded} == {(0.0,) * 9}
    # A payload cut short is not taken in bulk: the whole batch goes one by one.
    assert (
        migration.bulk.payloads(buf, starts, lengths - np.eye(1, len(old), 3, np.int64)[0] * 8)
        is None
    )
