"""Fixtures of the golden-bag tests: the fixture specs, an in-process sensor simulation."""

from __future__ import annotations

from pathlib import Path

import pytest
from rclpy.serialization import serialize_message

from bagkit.bag import BagWriter, TopicInfo
from bagkit.ros.types import message_type_name
from fusion.processors import create_processor

START_NS = 1_700_000_000_000_000_000


def simulate_inputs(path: Path, duration_s: float, **params: object) -> Path:
    """A bag of sensor messages from the sensor_publisher processor driven on its own timer,
    received 0.3 ms after publication: the inputs of a flight without ROS in the loop."""
    publisher = create_processor("sensor_publisher", params)
    assert publisher.timer_period_ns is not None
    added: set[str] = set()
    with BagWriter(path) as bag:
        now = START_NS
        while now <= START_NS + duration_s * 1e9:
            for topic, msg in publisher.on_timer(now):
                if topic not in added:
                    bag.add_topic(TopicInfo(topic, message_type_name(msg)))
                    added.add(topic)
                bag.write(topic, serialize_message(msg), log_time=now + 300_000, publish_time=now)
            now += publisher.timer_period_ns
    return path


@pytest.fixture(scope="module")
def simulated_flight(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """20 s of simulated sensor inputs, with the default fault schedule."""
    return simulate_inputs(tmp_path_factory.mktemp("sim") / "inputs", 20.0)
