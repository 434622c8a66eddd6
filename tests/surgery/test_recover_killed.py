"""``bagkit recover`` on real SIGKILLed recordings: ``bagkit record`` killed while a publisher
runs; the recovered bag opens in rosbags and mcap with every message bagkit salvages."""

from __future__ import annotations

import os
import signal
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
import rclpy
from rclpy.context import Context
from rclpy.node import Node
from std_msgs.msg import String
from surgery_samples import run
from test_recover import check_recovered, salvaged

pytestmark = pytest.mark.ros

STARTUP_TIMEOUT_S = 20.0


@pytest.fixture
def node() -> Iterator[Node]:
    context = Context()
    rclpy.init(context=context)
    publisher_node = Node("surgery_test_publisher", context=context)
    try:
        yield publisher_node
    finally:
        publisher_node.destroy_node()
        context.try_shutdown()


def test_sigkilled_recording_is_recovered(node: Node, processes: object, tmp_path: Path) -> None:
    publisher = node.create_publisher(String, "/surgery/killed", 100)
    bag = tmp_path / "killed"
    proc = processes.start(  # type: ignore[attr-defined]
        ["bagkit", "record", "/surgery/killed", "-o", str(bag)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    deadline = time.monotonic() + STARTUP_TIMEOUT_S
    while publisher.get_subscription_count() == 0:
        assert time.monotonic() < deadline, "the recorder did not subscribe"
        time.sleep(0.01)
    start = time.monotonic()
    i = 0
    while time.monotonic() - start < 2.5:
        publisher.publish(String(data=f"killed {i}"))
        i += 1
        time.sleep(0.005)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait(timeout=10)
    assert not (bag / "metadata.yaml").exists()
    expected = salvaged(bag)
    assert len(expected) > 100
    out = tmp_path / "recovered"
    result = run("recover", str(bag), "-o", str(out))
    assert result.returncode == 0, result.stderr
    check_recovered(out, expected)
    doctor = run("doctor", str(out), "--deep")
    assert doctor.returncode == 0, doctor.stdout
    before = run("doctor", str(bag))
    assert before.returncode == 1
    assert "no usable summary" in before.stdout
