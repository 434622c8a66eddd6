"""``bagkit play`` of a bag in storage: read by range requests from an HTTP server on
127.0.0.1, published over DDS, received as the bag on disk holds it."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest
from rclpy.serialization import deserialize_message
from replay_harness import CLI_KNOWN, STRING_TOPICS, Listener, bagkit_cli, recorded
from std_msgs.msg import String

from tests.storage.servers import HttpStore, start_http

pytestmark = pytest.mark.ros


@pytest.fixture
def served(test_bag: Path) -> Iterator[str]:
    """The known-stamp bag's files under ``URL/known`` (its prefix holds metadata.yaml)."""
    store = HttpStore()
    for file in test_bag.iterdir():
        store.objects[f"/known/{file.name}"] = file.read_bytes()
    server = start_http(store)
    try:
        yield f"{store.url}/known"
    finally:
        server.shutdown()
        server.server_close()


def test_play_of_a_url(served: str, test_bag: Path, listener_factory: type[Listener]) -> None:
    topics = sorted(STRING_TOPICS)
    expected = recorded(test_bag)
    listener = listener_factory(STRING_TOPICS)
    waits = [a for t in topics for a in ("--wait-for", t)]
    result = bagkit_cli("play", served, "--rate", "10", *CLI_KNOWN, *waits)
    assert result.returncode == 0, result.stderr
    got = listener.wait_for_count(len(expected))
    assert len(got) == len(expected) == 30
    sent = [(t, deserialize_message(d, String).data) for t, d, _ in expected]
    assert sorted((r.topic, r.text) for r in got) == sorted(sent)
