"""``bagkit recover`` on real SIGKILLed recordings: ``bagkit record`` killed while a publisher
runs; the recovered bag opens in rosbags and mcap with every message bagkit salvages."""

from __future__ import annotations

import os
import signal
import subprocess
import time
from pathlib import Path

import pytest
from rclpy.node import Node
from std_msgs.msg import String
from surgery_samples import run
from test_recover import check_recovered, salvaged
from waiting import wait_matched

pytestmark = pytest.mark.ros

STARTUP_TIMEOUT_S = 20.0


def test_sigkilled_recording_is_recovered(node: Node, processes: object, tmp_path: Path) -> None:
    publisher = node.create_publisher(String, "/surgery/killed", 100)
    bag = tmp_path / "killed"
    proc = processes.start(  # type: ignore[attr-defined]
        ["bagkit", "record", "/surgery/killed", "-o", str(bag)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    wait_matched(publisher, timeout=STARTUP_TIMEOUT_S)
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
    # 3: the record being written when the recorder was killed is lost (and said so).
    assert result.returncode == (3 if "lost:" in result.stderr else 0), result.stderr
    check_recovered(out, expected)
    doctor = run("doctor", str(out), "--deep")
    assert doctor.returncode == 0, doctor.stdout
    before = run("doctor", str(bag))
    assert before.returncode == 1
    assert "no usable summary" in before.stdout
