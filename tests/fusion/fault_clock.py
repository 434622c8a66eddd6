"""Where a fault schedule's zero falls in a recording of fusion's live system.

The schedule counts from the sensor publisher's first tick, which the recording does not
hold. It is found from the ground truth: /sim/truth's altitude during the climb is inverted
with fusion's own flight model (read with rosbags, not bagkit), giving the time since that tick.
"""

from __future__ import annotations

from pathlib import Path

import yaml
from rosbags.highlevel import AnyReader

from fusion.processors.sensor_publisher import SensorPublisher
from fusion.sim import trajectory_state

NS = 1_000_000_000


def scenario(path: Path) -> dict[str, object]:
    """The sensor publisher's parameters of a scenario.yaml, flattened (``flight.x``)."""
    params = yaml.safe_load(path.read_text())
    flat = dict(params["sensor_publisher"]["ros__parameters"])
    flat.update({f"flight.{k}": v for k, v in flat.pop("flight").items()})
    return flat


def schedule_zero_ns(bag: Path, publisher: SensorPublisher) -> int:
    """Log time of the publisher's first tick in ``bag``, from the truth's climb."""
    profile = publisher.profile
    estimates = []
    with AnyReader([bag]) as reader:
        truth = [c for c in reader.connections if c.topic == "/sim/truth"]
        for connection, _, raw in reader.messages(connections=truth):
            msg = reader.deserialize(raw, connection.msgtype)
            stamp = msg.header.stamp.sec * NS + msg.header.stamp.nanosec
            altitude = msg.pose.pose.position.z
            low = profile.takeoff_delay + 0.5  # well inside the climb: altitude rises
            high = profile.takeoff_delay + profile.climb_duration - 0.5
            if (
                not trajectory_state(profile, low).altitude
                < altitude
                < trajectory_state(profile, high).altitude
            ):
                continue
            for _ in range(80):  # bisection: the altitude rises monotonically in the climb
                middle = (low + high) / 2
                if trajectory_state(profile, middle).altitude < altitude:
                    low = middle
                else:
                    high = middle
            estimates.append(stamp - round(low * NS))
    assert len(estimates) > 50
    assert max(estimates) - min(estimates) < 1_000_000  # one zero for every sample, to 1 ms
    return sorted(estimates)[len(estimates) // 2]
