"""Snapshot mode's faults over real DDS, through ``bagkit record``: SIGKILL during a snapshot
write, a trigger topic that never appears, a bad trigger field on a late topic."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rosbags.highlevel import AnyReader
from std_msgs.msg import String
from std_srvs.srv import Trigger
from test_record_cli import report_json
from test_record_snapshot import _spin_until
from waiting import wait_for, wait_matched

from bagkit.bag import BagReader

pytestmark = pytest.mark.ros

STARTUP_TIMEOUT_S = 30.0
BAGKIT = str(Path(sys.executable).with_name("bagkit"))
# Messages of the large snapshot: incompressible, so that writing it takes a while.
BIG_MESSAGE_BYTES = 64 * 1024
BIG_MESSAGES = 1500


def record(processes: Any, out: Path, node_name: str, *args: str) -> subprocess.Popen[bytes]:
    command = ["bagkit", "record", "-e", "^/faults/", "-o", str(out), "--snapshot-mode"]
    return processes.start(  # type: ignore[no-any-return]
        [*command, "--node-name", node_name, "--format", "json", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )


def texts(path: Path) -> list[tuple[str, str]]:
    """(topic, text) of each message, read with rosbags; bagkit reads the same."""
    with AnyReader([path]) as reader:
        found = [
            (c.topic, reader.deserialize(raw, c.msgtype).data) for c, _, raw in reader.messages()
        ]
    with BagReader(path) as bag:
        assert bag.problems == []
        assert bag.message_count == len(found)
    return found


def test_sigkill_during_a_snapshot_write(node: Node, processes: Any, tmp_path: Path) -> None:
    reliable = QoSProfile(depth=BIG_MESSAGES, reliability=ReliabilityPolicy.RELIABLE)
    publisher = node.create_publisher(String, "/faults/big", reliable)
    client = node.create_client(Trigger, "/kill_recorder/snapshot")
    out = tmp_path / "blackbox"
    proc = record(processes, out, "kill_recorder", "--max-cache-size", str(400 << 20))
    wait_matched(publisher, timeout=STARTUP_TIMEOUT_S)
    assert client.wait_for_service(timeout_sec=STARTUP_TIMEOUT_S)
    small = [f"small {i}" for i in range(20)]
    for text in small:
        publisher.publish(String(data=text))
    time.sleep(0.5)
    _spin_until(node, client.call_async(Trigger.Request()))
    wait_for((out / "snapshot_0" / "metadata.yaml").is_file, 10, what="snapshot_0")
    # Hex of random bytes: ASCII (a String) that zstd cannot shrink much.
    big = [f"big {i} " + os.urandom(BIG_MESSAGE_BYTES // 2).hex() for i in range(BIG_MESSAGES)]
    for text in big:
        publisher.publish(String(data=text))
    time.sleep(2.0)  # taken by the recorder: reliable, and it keeps up with 100 MB
    _spin_until(node, client.call_async(Trigger.Request()))
    cut = out / "snapshot_1"
    files = lambda: list(cut.glob("*.mcap"))  # noqa: E731
    wait_for(lambda: any(f.stat().st_size > 8 << 20 for f in files()), 30, what="a write")
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait(timeout=10)
    # The kill landed during the write: no metadata, the file short of what was buffered.
    assert not (cut / "metadata.yaml").exists()
    (cut_file,) = files()
    assert cut_file.stat().st_size < len(big) * BIG_MESSAGE_BYTES
    # The earlier snapshot is intact.
    assert texts(out / "snapshot_0") == [("/faults/big", text) for text in small]
    # The cut one is salvaged like any crashed recording: a prefix of its messages.
    with BagReader(cut, allow_empty=True) as reader:
        salvaged = [bytes(m.data) for m in reader.messages()]
    recovered = tmp_path / "recovered"
    result = subprocess.run(
        [BAGKIT, "recover", str(cut), "-o", str(recovered)],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    # A kill inside a chunk loses its bytes: recover says so and exits 3 (docs/surgery.md).
    lost = "warning: lost:" in result.stderr
    assert result.returncode == (3 if lost else 0), result.stderr
    read_back = texts(recovered)
    assert len(small) < len(read_back) == len(salvaged) < len(small) + len(big)
    assert read_back == [("/faults/big", text) for text in [*small, *big][: len(read_back)]]


def test_a_trigger_topic_that_never_appears_warns_once(
    node: Node, processes: Any, tmp_path: Path
) -> None:
    publisher = node.create_publisher(String, "/faults/chatter", 100)
    client = node.create_client(Trigger, "/absent_recorder/snapshot")
    out = tmp_path / "absent"
    trigger = "/faults/never: level >= 2"
    proc = record(
        processes, out, "absent_recorder", "--max-cache-duration", "60", "--trigger", trigger
    )
    assert proc.stderr is not None
    os.set_blocking(proc.stderr.fileno(), False)
    stderr = b""

    def warned() -> bool:
        nonlocal stderr
        stderr += proc.stderr.read() or b""  # type: ignore[union-attr]
        return b"has not appeared" in stderr

    wait_matched(publisher, timeout=STARTUP_TIMEOUT_S)
    published = [f"chatter {i}" for i in range(30)]
    for text in published:
        publisher.publish(String(data=text))
        time.sleep(0.01)
    # The recorder's wait for a trigger topic (10 s after the start) before it warns.
    wait_for(warned, 30, what="the warning")
    assert proc.poll() is None  # recording goes on
    assert client.wait_for_service(timeout_sec=10)
    _spin_until(node, client.call_async(Trigger.Request()))
    wait_for((out / "snapshot_0" / "metadata.yaml").is_file, 10, what="snapshot_0")
    proc.send_signal(signal.SIGINT)
    os.set_blocking(proc.stderr.fileno(), True)
    stdout, rest = proc.communicate(timeout=30)
    stderr += rest
    assert proc.returncode == 130, stderr.decode()
    warnings = [line for line in stderr.decode().splitlines() if "/faults/never" in line]
    assert warnings == [
        "warning: trigger topic /faults/never has not appeared after 10 s: recording goes on, "
        "it triggers once it appears"
    ]
    report = report_json(stdout)
    assert report["error"] is None and report["lost"] == 0
    (snapshot,) = report["snapshots"]
    assert snapshot["trigger"] == "service"
    assert texts(out / "snapshot_0") == [("/faults/chatter", text) for text in published]


def test_a_bad_trigger_field_on_a_late_topic_is_bad_input(
    node: Node, processes: Any, tmp_path: Path
) -> None:
    chatter = node.create_publisher(String, "/faults/chatter", 100)
    out = tmp_path / "late"
    trigger = "/faults/late: status[*].levle >= 2"
    proc = record(
        processes, out, "late_recorder", "--max-cache-duration", "60", "--trigger", trigger
    )
    wait_matched(chatter, timeout=STARTUP_TIMEOUT_S)
    time.sleep(2.0)  # past the start's check of the trigger topics (1 s)
    assert proc.poll() is None
    late = node.create_publisher(DiagnosticArray, "/faults/late", 10)
    late.publish(DiagnosticArray())
    stdout, stderr = proc.communicate(timeout=30)
    assert proc.returncode == 2, stderr.decode()
    lines = stderr.decode().splitlines()
    errors = [line for line in lines if line.startswith("error:")]
    assert len(errors) == 1 and "levle" in errors[0] and trigger in errors[0], lines
    assert "Traceback" not in stderr.decode()
    assert report_json(stdout)["error"] == errors[0].removeprefix("error: ")
