"""The bag most stats tests read: written once per session by rosbags (the oracle)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from rosbags_oracle import TopicData, diagnostics_data, flag_data, imu_data, scan_data, write_bag


@pytest.fixture(scope="session")
def topics() -> dict[str, TopicData]:
    rng = np.random.default_rng(5)
    # 4000 Imu messages fill more than one 1 MiB chunk of rosbags' writer.
    return {
        "/imu/data": imu_data(rng, 4000),
        "/scan": scan_data(rng, 60),
        "/diagnostics": diagnostics_data(rng, 30),
        "/flag": flag_data(20),
    }


@pytest.fixture(scope="session")
def bag(tmp_path_factory: pytest.TempPathFactory, topics: dict[str, TopicData]) -> Path:
    """Written once per module: the tests only read it."""
    return write_bag(tmp_path_factory.mktemp("stats") / "bag", topics)
