"""``bagkit control`` against a real ``bagkit play`` and ``bagkit record`` over DDS: each
control reaches the node found on the graph, its answer printed, its exit status meaningful."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest
from rclpy.node import Node
from rclpy.serialization import serialize_message
from std_msgs.msg import String
from waiting import wait_for

from bagkit.bag import BagReader, BagWriter, TopicInfo

BAGKIT = str(Path(sys.executable).with_name("bagkit"))
TOPIC = "/control_test/data"
START_NS = 1_700_000_000_000_000_000
pytestmark = pytest.mark.ros  # every test starts participants, in bagkit subprocesses too


def _control(*args: str, wait: str = "15") -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [BAGKIT, "control", *args, "--timeout", wait],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )


def _bag(path: Path, hz: float, seconds: float) -> Path:
    with BagWriter(path) as writer:
        writer.add_topic(TopicInfo(TOPIC, "std_msgs/msg/String"))
        for index in range(int(hz * seconds)):
            data = bytes(serialize_message(String(data=f"#{index}")))
            writer.write(TOPIC, data, log_time=START_NS + index * int(1e9 / hz))
    return path


def test_controls_of_a_player(tmp_path: Path, processes: Any) -> None:
    bag = _bag(tmp_path / "bag", hz=20, seconds=30)
    player = processes.start(
        [BAGKIT, "play", str(bag), "--disable-keyboard-controls", "--no-wait-for-subscribers",
         "--format", "json"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )  # fmt: skip
    paused = _control("pause")
    assert paused.returncode == 0 and paused.stdout.startswith("/bagkit_player pause: done"), paused
    asked = _control("is_paused", "--format", "json")
    assert json.loads(asked.stdout) == {
        "node": "/bagkit_player",
        "control": "is_paused",
        "success": True,
        "message": "paused",
    }
    refused = _control("rate", "0")
    assert refused.returncode == 1 and "refused (rate must be a positive number)" in refused.stdout
    assert _control("rate", "4").returncode == 0
    assert _control("get_rate").stdout.strip() == "/bagkit_player get_rate: done (4)"
    unknown = _control("rat", "4")
    assert unknown.returncode == 2 and unknown.stderr.startswith("error: no control named 'rat'")
    assert _control("resume").returncode == 0
    assert _control("is_paused").returncode == 1  # playing: the answer is no
    assert _control("stop").returncode == 0
    out, err = player.communicate(timeout=30)
    assert player.returncode == 0, err
    played = json.loads(out)["messages"]
    assert 0 < played < 600  # stopped before the end


def test_controls_of_a_recorder(tmp_path: Path, processes: Any, node: Node) -> None:
    publisher = node.create_publisher(String, TOPIC, 10)
    recorder = processes.start(
        [BAGKIT, "record", "-o", str(tmp_path / "rec"), TOPIC],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    sent = 0

    def publish(seconds: float) -> None:
        nonlocal sent
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            publisher.publish(String(data=f"#{sent}"))
            sent += 1
            time.sleep(0.02)

    wait_for(lambda: publisher.get_subscription_count() > 0, 15.0)
    publish(1.0)
    split = _control("split")
    assert split.returncode == 0, split
    assert split.stdout.startswith("/bagkit_recorder split_bagfile: done (")
    publish(1.0)
    assert _control("pause").returncode == 0
    assert _control("is_paused").stdout.strip() == "/bagkit_recorder is_paused: yes (paused)"
    # A recorder without --snapshot-mode: not "is it running?", but what it offers instead.
    snapshot = _control("snapshot", wait="1")
    assert snapshot.returncode == 2, snapshot
    (line,) = snapshot.stderr.splitlines()
    assert line.startswith("error: no recorder or player offers 'snapshot' on ROS_DOMAIN_ID")
    assert "/bagkit_recorder offers " in line and "split_bagfile" in line
    assert "is it running" not in line and "--snapshot-mode" in line
    recorder.send_signal(2)
    recorder.communicate(timeout=30)
    files = sorted((tmp_path / "rec").glob("*.mcap"))
    assert len(files) == 2, files
    with BagReader(tmp_path / "rec") as reader:
        assert 0 < reader.message_count <= sent


def test_no_node_offers_the_control() -> None:
    done = _control("pause", wait="0.5")
    assert done.returncode == 2
    assert done.stderr.startswith("error: no recorder or player offers 'pause' on ROS_DOMAIN_ID")
