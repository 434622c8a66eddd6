"""Fixtures of the golden-bag tests: the fixture specs, an in-process sensor simulation."""

from __future__ import annotations

from pathlib import Path

import pytest
from rclpy.serialization import serialize_message

from bagkit.bag import BagWriter, TopicInfo
from bagkit.ros.message_classes import message_type_name
from fusion.simulate import simulate


def simulate_inputs(path: Path, duration_s: float) -> Path:
    """A bag of the sensor_publisher's messages (fusion.simulate, no ROS), received 0.3 ms
    after publication: the inputs of a flight with the default fault schedule."""
    added: set[str] = set()
    with BagWriter(path) as bag:
        for out in simulate(duration_s, nodes=["sensor_publisher"]):
            if out.topic not in added:
                bag.add_topic(TopicInfo(out.topic, message_type_name(out.msg)))
                added.add(out.topic)
            data = serialize_message(out.msg)
            bag.write(out.topic, data, log_time=out.now_ns + 300_000, publish_time=out.now_ns)
    return path


@pytest.fixture(scope="module")
def simulated_flight(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """20 s of simulated sensor inputs, with the default fault schedule."""
    return simulate_inputs(tmp_path_factory.mktemp("sim") / "inputs", 20.0)
