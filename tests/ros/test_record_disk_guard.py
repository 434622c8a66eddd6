"""The free-space guard on a small filesystem: the recording stops cleanly before it is full."""

from __future__ import annotations

import os
import resource
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


def test_disk_full_during_a_snapshot_is_one_error_line_and_earlier_snapshots_stay(
    node: Node, processes: object, tmp_path: Path
) -> None:
    publisher = node.create_publisher(
        String, "/guard/snap", QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
    )
    out = tmp_path / "snaps"
    proc = record(
        processes,
        "/guard/snap",
        "-o",
        str(out),
        "--snapshot-mode",
        "--max-cache-size",
        str(8 << 20),
        "--compression-mode",
        "none",
        "--trigger",
        "/guard/snap: data == 'go'",
        "--format",
        "json",
    )
    wait_for(lambda: publisher.get_subscription_count() > 0, STARTUP_TIMEOUT_S)
    limit = 200_000  # bytes per file: the first snapshot fits, the second does not
    resource.prlimit(proc.pid, resource.RLIMIT_FSIZE, (limit, limit))
    for _ in range(5):
        publisher.publish(String(data="small"))
    publisher.publish(String(data="go"))
    wait_for((out / "snapshot_0" / "metadata.yaml").is_file, 10)
    for _ in range(40):
        publisher.publish(String(data=os.urandom(5000).hex()))
    publisher.publish(String(data="go"))
    stdout, stderr = proc.communicate(timeout=30)
    assert proc.returncode == 1, stderr.decode()
    errors = [line for line in stderr.decode().splitlines() if line.startswith("error")]
    assert len(errors) == 1 and "snapshot_1" in errors[0] and "File too large" in errors[0]
    report = report_json(stdout)
    first, second = report["snapshots"]
    assert first["error"] is None and second["error"] is not None
    assert report["lost"] == 0  # every message was taken; the second snapshot is cut
    with BagReader(out / "snapshot_0") as reader:
        assert reader.topic_counts["/guard/snap"] == first["messages"]["/guard/snap"] == 6
