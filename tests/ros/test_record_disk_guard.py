"""The free-space guard on a small filesystem: the recording stops cleanly before it is full."""

from __future__ import annotations

import os
import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from std_msgs.msg import String
from test_record_cli import STARTUP_TIMEOUT_S, lost_in_error_line, record, report_json
from waiting import wait_for

from bagkit.bag import BagReader

pytestmark = pytest.mark.ros


@pytest.fixture
def small_filesystem(tmp_path: Path) -> Iterator[Path]:
    """A 3 MiB tmpfs (root only); skipped where mounting is refused, except under CI."""
    mount = tmp_path / "small"
    mount.mkdir()
    done = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", "size=3m", "tmpfs", str(mount)],
        capture_output=True,
        text=True,
        check=False,
    )
    if done.returncode:
        reason = f"cannot mount a tmpfs here: {done.stderr.strip()}"
        if os.environ.get("CI", "").lower() == "true":
            pytest.fail(reason)
        pytest.skip(reason)
    try:
        yield mount
    finally:
        subprocess.run(["umount", "-l", str(mount)], check=False)


def test_min_free_space_stops_with_one_error_line(
    node: Node, processes: object, small_filesystem: Path
) -> None:
    publisher = node.create_publisher(
        String, "/guard/flood", QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
    )
    bag = small_filesystem / "guarded"
    proc = record(
        processes,
        "/guard/flood",
        "-o",
        str(bag),
        "--compression-mode",
        "none",
        "--min-free-space",
        "1MiB",
        "--format",
        "json",
    )
    wait_for(lambda: publisher.get_subscription_count() > 0, STARTUP_TIMEOUT_S)
    payload = os.urandom(5000).hex()
    while proc.poll() is None:
        publisher.publish(String(data=payload))
    stdout, stderr = proc.communicate(timeout=30)
    assert proc.returncode == 1, stderr.decode()
    errors = [line for line in stderr.decode().splitlines() if line.startswith("error")]
    assert len(errors) == 1 and "less than 1MiB free: stopped before the disk fills" in errors[0]
    report = report_json(stdout)
    assert lost_in_error_line(stderr) == report["lost"] > 0
    # Stopped with room to spare: the bag is finished and readable.
    with BagReader(bag) as reader:
        assert reader.message_count == report["messages"] > 0
    assert (bag / "metadata.yaml").is_file()
