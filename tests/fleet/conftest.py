"""One local Dask cluster (2 single-threaded worker processes on 127.0.0.1) for every fleet
test, and generated bags; every process the cluster starts is checked gone at teardown."""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import psutil
import pytest
from distributed import Client
from rosbags.typesys import Stores, get_typestore

from bagkit.bag import BagWriter, TopicInfo
from bagkit.fleet import local_cluster

STORE = get_typestore(Stores.ROS2_JAZZY)
IMU, TEMPERATURE = "sensor_msgs/msg/Imu", "sensor_msgs/msg/Temperature"
T0 = 1_700_000_000_000_000_000


@pytest.fixture(scope="session")
def client() -> Iterator[Client]:
    """A client of the shared cluster; its worker processes are checked gone afterwards."""
    cluster = local_cluster(2)
    with Client(cluster) as shared:
        yield shared
        pids = list(worker_pids(shared).values())
    cluster.close()
    alive = [pid for pid in pids if psutil.pid_exists(pid) and _running(pid)]
    assert not alive, f"processes of the cluster left running: {alive}"


def _running(pid: int) -> bool:
    try:
        return psutil.Process(pid).status() != psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return False


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


@pytest.fixture(scope="session")
def fleet_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Six bags under one root (two in a sub-directory), hours apart, different spreads."""
    root = tmp_path_factory.mktemp("fleet")
    for i in range(6):
        where = root / "day2" if i >= 4 else root
        where.mkdir(exist_ok=True)
        write_bag(where / f"flight_{i}", seed=i, n=400 + 50 * i, t0=T0 + i * 3_600 * 10**9)
    return root


@pytest.fixture(scope="session")
def fleet_bags(fleet_dir: Path) -> list[Path]:
    from bagkit.fleet import expand_bags

    return expand_bags([fleet_dir])


def worker_pids(client: Client) -> dict[str, int]:
    """Worker address -> pid of its process."""
    return dict(client.run(os.getpid))
