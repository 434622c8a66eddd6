"""Fixtures of the bag tests."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from bag_samples import IMU, QOS_YAML, STRING, imu_cdr, string_cdr

from bagkit.bag import BagWriter, TopicInfo


@pytest.fixture
def write_sample_bag(tmp_path: Path) -> Callable[..., Path]:
    """Write a bag with ``n_imu`` Imu messages at 100 Hz and a String every 10th, return it.

    Log times start at 1.7e18 ns; publish_time = log_time - 1000; sequence = message number.
    """

    def write(name: str = "sample", n_imu: int = 300, **options: Any) -> Path:
        path = tmp_path / name
        with BagWriter(path, **options) as bag:
            bag.add_topic(TopicInfo("/imu/data", IMU, offered_qos_profiles=QOS_YAML))
            bag.add_topic(TopicInfo("/text", STRING, offered_qos_profiles=QOS_YAML))
            for i in range(n_imu):
                log_time = 1_700_000_000_000_000_000 + i * 10_000_000
                bag.write(
                    "/imu/data",
                    imu_cdr(i),
                    log_time=log_time,
                    publish_time=log_time - 1000,
                    sequence=i,
                )
                if i % 10 == 0:
                    bag.write(
                        "/text",
                        string_cdr(f"message {i}"),
                        log_time=log_time + 1,
                        publish_time=log_time,
                        sequence=i // 10,
                    )
            bag.custom_data["lost./imu/data"] = "0"
        return path

    return write
