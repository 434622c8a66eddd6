"""Other publishers of replayed topics, named even when their names arrive late."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import pytest

from bagkit.ros.replay import publishers
from bagkit.ros.replay.publishers import UNKNOWN_NODE, other_publishers


class _Graph:
    """A node's graph view whose other publisher's name arrives after ``unnamed_calls`` reads."""

    def __init__(self, unnamed_calls: int) -> None:
        self.unnamed_calls = unnamed_calls
        self.reads = 0

    def get_name(self) -> str:
        return "player"

    def get_namespace(self) -> str:
        return "/"

    def get_publishers_info_by_topic(self, topic: str) -> list[Any]:
        self.reads += 1
        named = self.reads > self.unnamed_calls
        other = (
            SimpleNamespace(node_name="driver", node_namespace="/car")
            if named
            else SimpleNamespace(
                node_name="_NODE_NAME_UNKNOWN_", node_namespace="_NODE_NAMESPACE_UNKNOWN_"
            )
        )
        return [SimpleNamespace(node_name="player", node_namespace="/"), other]


def _outputs() -> list[Any]:
    return [SimpleNamespace(name="/imu")]


def test_a_late_name_is_awaited() -> None:
    graph = _Graph(unnamed_calls=3)
    assert other_publishers(graph, _outputs()) == {"/imu": ["/car/driver"]}  # type: ignore[arg-type]
    assert graph.reads == 4


def test_a_name_that_never_arrives_is_said_so(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(publishers, "NODE_NAME_WAIT_S", 0.05)
    graph = _Graph(unnamed_calls=10**9)
    assert other_publishers(graph, _outputs()) == {"/imu": [UNKNOWN_NODE]}  # type: ignore[arg-type]
