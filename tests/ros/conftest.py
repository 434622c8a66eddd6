"""Fixtures of the ROS tests: a known-stamp bag, listeners closed after each test."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest
from replay_harness import (
    Listener,
    write_test_bag,
)


@pytest.fixture
def listener_factory() -> Iterator[type[Listener]]:
    listeners: list[Listener] = []

    class Tracked(Listener):
        def __init__(self, topics: dict[str, type]) -> None:
            super().__init__(topics)
            listeners.append(self)

    yield Tracked
    for listener in listeners:
        listener.close()


@pytest.fixture(scope="module")
def test_bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_test_bag(tmp_path_factory.mktemp("replay") / "known")
