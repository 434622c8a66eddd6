"""Flights of fusion's whole system (every node's processor, fusion.simulate, no ROS) written
as bags: each message received 0.3 ms after its publication, as a recorder on one host does."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from rclpy.serialization import serialize_message

from bagkit.bag import BagWriter, TopicInfo
from bagkit.ros.message_classes import message_type_name
from fusion.simulate import simulate

RECEIVE_NS = 300_000


def record_flight(path: Path, seconds: float, publisher: Mapping[str, object]) -> int:
    """Write ``seconds`` of the system's topics to the bag ``path`` with the sensor
    publisher's parameters ``publisher`` (dotted names); returns the log time of the
    schedule's zero, the publisher's first tick, from the simulation's own clock."""
    added: set[str] = set()
    first_tick = None
    with BagWriter(path) as bag:
        for out in simulate(seconds, {"sensor_publisher": dict(publisher)}):
            if out.node == "sensor_publisher" and first_tick is None:
                first_tick = out.now_ns
            if out.topic not in added:
                bag.add_topic(TopicInfo(out.topic, message_type_name(out.msg)))
                added.add(out.topic)
            data = serialize_message(out.msg)
            bag.write(out.topic, data, log_time=out.now_ns + RECEIVE_NS, publish_time=out.now_ns)
    assert first_tick is not None
    return first_tick + RECEIVE_NS
