"""Seeded mutations of a small ROS 1 bag (written by rosbags), read through BagReader (index,
every message, every chunk, the last messages, the spans): nothing but a BagkitError may come
out, and every run ends."""

from __future__ import annotations

import random
from pathlib import Path

import pytest

from bagkit.bag import BagReader
from bagkit.errors import BagkitError
from tests.bag.ros1_samples import write_ros1_bag
from tests.bag.test_bag_fuzz import RUNS, SEED, _mutate, _read


@pytest.mark.parametrize("compression", ["none", "lz4", "bz2"])
def test_mutated_ros1_bags_raise_only_bagkit_errors(tmp_path: Path, compression: str) -> None:
    original = write_ros1_bag(
        tmp_path / "seed.bag", 60, compression=compression, chunk_threshold=2048
    ).read_bytes()
    rng = random.Random(f"{SEED}-ros1-{compression}")
    path = tmp_path / "mutant.bag"
    outcomes = {"read": 0, "refused": 0}
    for _ in range(RUNS // 2):
        path.write_bytes(_mutate(original, rng))
        try:
            _read(path)
            with BagReader(path, allow_empty=True) as bag:
                bag.last_messages(set(bag.topics), bag.end_ns)
                bag.topic_spans()
            outcomes["read"] += 1
        except BagkitError:
            outcomes["refused"] += 1
    assert outcomes["read"] and outcomes["refused"], outcomes
