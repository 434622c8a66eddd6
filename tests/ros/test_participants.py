"""The participant census: a Fast DDS participant of an exited process; readers and node names
still to come; a participant on this host that never answers."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from typing import Any

import pytest
from domains import silent_participant

from bagkit.ros.participants import (
    Endpoint,
    _process_may_live,
    all_discovered,
    heard_the_answers,
    live_participant_gids,
    settled,
)

FAST_DDS_PREFIX = bytes([1, 15, 0x78, 0xFD])


def _gid(pid: int, vendor_prefix: bytes = FAST_DDS_PREFIX) -> bytes:
    """A 16-byte endpoint gid as Fast DDS makes it for a participant of process ``pid``."""
    return vendor_prefix + (pid & 0xFFFF).to_bytes(2, "little") + bytes(10)


def test_a_participant_of_a_live_process_counts() -> None:
    assert _process_may_live(_gid(os.getpid()))


def test_a_participant_of_an_exited_process_does_not() -> None:
    done = subprocess.run(
        [sys.executable, "-c", "import os; print(os.getpid())"],
        check=True,
        capture_output=True,
        text=True,
    )
    pid = int(done.stdout)
    same_bits = [p for p in os.listdir("/proc") if p.isdigit() and int(p) & 0xFFFF == pid & 0xFFFF]
    if same_bits:
        pytest.skip(f"process {same_bits[0]} has the exited pid's low 16 bits")
    assert not _process_may_live(_gid(pid))


def test_another_vendor_always_counts() -> None:
    # RTI's vendor id: its prefix does not hold a process id that we know of.
    assert _process_may_live(_gid(pid=0xFFFE, vendor_prefix=bytes([1, 1, 0, 0])))


OTHER = FAST_DDS_PREFIX + bytes(range(8))
LISTENER = ("replay_listener", "/")


def _endpoint(entity: int, node: tuple[str, str] | None, *, reader: bool) -> Endpoint:
    return Endpoint(OTHER + entity.to_bytes(4, "big"), node, reader=reader)


# What the player's graph showed when a census ended the wait before the listener's two
# subscriptions arrived: its participant's discovery writer and reader, nothing of its node.
DISCOVERY_ONLY = [_endpoint(0x0103, None, reader=False), _endpoint(0x0204, None, reader=True)]
NODE_WRITERS = [
    _endpoint(0x0303, LISTENER, reader=False),
    _endpoint(0x0503, LISTENER, reader=False),
]
NODE_READERS = [_endpoint(0x1304, LISTENER, reader=True), _endpoint(0x1404, LISTENER, reader=True)]


def test_a_participant_whose_node_is_not_named_yet_is_not_settled() -> None:
    assert not settled({OTHER[:12]}, DISCOVERY_ONLY, set())


def test_a_node_whose_readers_have_not_arrived_is_not_settled() -> None:
    assert not settled({OTHER[:12]}, DISCOVERY_ONLY + NODE_WRITERS, {LISTENER})


def test_a_named_node_with_its_readers_is_settled() -> None:
    endpoints = DISCOVERY_ONLY + NODE_WRITERS + NODE_READERS
    assert settled({OTHER[:12]}, endpoints, {LISTENER})


def test_a_node_of_a_participant_not_yet_found_keeps_the_census() -> None:
    # A node named in the graph with no reader there yet, wherever its participant is.
    stranger = ("stranger", "/")
    endpoints = DISCOVERY_ONLY + NODE_WRITERS + NODE_READERS
    assert not settled({OTHER[:12]}, endpoints, {LISTENER, stranger})


# A participant in another process with a node that subscribes.
_WITH_READER = """
import time, rclpy
from std_msgs.msg import String
rclpy.init()
node = rclpy.create_node("census_with_reader")
node.create_subscription(String, "/census", lambda m: None, 10)
print("ready", flush=True)
time.sleep(60)
"""


def _census_after_other(node: Any, script: str) -> tuple[bool, int, int]:
    """(census, subscribers on /census, participants new in the graph) once the other
    process's participant is in ``node``'s graph (or the census said yes, or 30 s passed).

    New against the graph before the other process started: a participant that an earlier
    test of this worker made may still be announced in its domain, and this process lives.
    """
    from std_msgs.msg import String

    node.create_publisher(String, "/census", 10)
    census = all_discovered(node, {"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"})
    assert census is not None
    before = set(live_participant_gids(node))
    other = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True)
    try:
        assert other.stdout is not None and other.stdout.readline().strip() == "ready"
        deadline = time.monotonic() + 30
        found = False
        while not found and time.monotonic() < deadline:
            found = census() or bool(set(live_participant_gids(node)) - before)
            time.sleep(0.02)
        # Read the graph the moment the census answered, before more can arrive.
        said = census()
        new = set(live_participant_gids(node)) - before
        return said, node.count_subscribers("/census"), len(new)
    finally:
        other.kill()
        other.wait()


@pytest.mark.ros
def test_the_census_waits_for_a_participants_readers(node: Any) -> None:
    said, subscribers, participants = _census_after_other(node, _WITH_READER)
    if said:
        assert subscribers == 1
    assert participants == 1  # the other process's


@pytest.mark.ros
def test_a_participant_on_this_host_that_never_answers_is_not_heard(node: Any) -> None:
    with silent_participant(node.context.get_domain_id()):
        assert not heard_the_answers(node, within_s=0.05)
    # Without it, this process's participant is every participant there is to hear.
    assert heard_the_answers(node, within_s=5.0)
