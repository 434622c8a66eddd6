"""Bags generated for the fleet tests (bagkit's writer, rosbags' serializer), and helpers."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from distributed import Client
from rosbags.typesys import Stores, get_typestore

from bagkit.bag import BagWriter, TopicInfo

STORE = get_typestore(Stores.ROS2_JAZZY)
IMU, TEMPERATURE = "sensor_msgs/msg/Imu", "sensor_msgs/msg/Temperature"
T0 = 1_700_000_000_000_000_000


def _imu(rng: np.random.Generator, t: int, offset: float) -> bytes:
    types = STORE.types
    vec = types["geometry_msgs/msg/Vector3"]
    msg = types[IMU](
        header=types["std_msgs/msg/Header"](
            stamp=types["builtin_interfaces/msg/Time"](sec=t // 10**9, nanosec=t % 10**9),
            frame_id="imu",
        ),
        orientation=types["geometry_msgs/msg/Quaternion"](*rng.normal(size=4)),
        orientation_covariance=rng.normal(size=9),
        angular_velocity=vec(*rng.normal(offset, 0.01, size=3)),
        angular_velocity_covariance=np.zeros(9),
        linear_acceleration=vec(*rng.normal([0.0, 0.0, 9.81], 0.05)),
        linear_acceleration_covariance=np.full(9, np.nan if t % 7 == 0 else 0.0),
    )
    return bytes(STORE.serialize_cdr(msg, IMU))


def write_bag(path: Path, seed: int, n: int, t0: int) -> Path:
    """A bag of ``n`` Imu messages at 100 Hz and ``n // 10`` Temperature messages from ``t0``."""
    rng = np.random.default_rng(seed)
    temperature = STORE.types[TEMPERATURE]
    header = STORE.types["std_msgs/msg/Header"]
    with BagWriter(path) as bag:
        bag.add_topic(TopicInfo("/imu/data", IMU))
        bag.add_topic(TopicInfo("/temperature", TEMPERATURE))
        for i in range(n):
            t = t0 + i * 10_000_000
            bag.write("/imu/data", _imu(rng, t, offset=seed * 1e3), log_time=t)
            if i % 10 == 0:
                stamp = STORE.types["builtin_interfaces/msg/Time"](sec=0, nanosec=0)
                msg = temperature(
                    header=header(stamp=stamp, frame_id=""),
                    temperature=20.0 + rng.normal(),
                    variance=0.0,
                )
                bag.write("/temperature", bytes(STORE.serialize_cdr(msg, TEMPERATURE)), log_time=t)
    return path


def worker_pids(client: Client) -> dict[str, int]:
    """Worker address -> pid of its process."""
    return dict(client.run(os.getpid))
