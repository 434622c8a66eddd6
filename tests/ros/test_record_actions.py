"""An action over real DDS: ``record --actions`` keeps its feedback and status, info groups them."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from action_msgs.msg import GoalStatus
from rclpy.action import ActionClient, ActionServer
from rclpy.action.server import ServerGoalHandle
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.executors import MultiThreadedExecutor
from rclpy.node import Node
from test_msgs.action import Fibonacci
from waiting import wait_for

from bagkit.cli.common import EXIT_INTERRUPTED

pytestmark = pytest.mark.ros

BAGKIT = str(Path(sys.executable).with_name("bagkit"))
ACTION = "/fibonacci"
FEEDBACK = f"{ACTION}/_action/feedback"
STATUS = f"{ACTION}/_action/status"
ORDER = 6


def _execute(goal: ServerGoalHandle) -> Fibonacci.Result:
    """Fibonacci to ``order``: one feedback per new number, then the sequence as the result."""
    sequence = [0, 1]
    for _ in range(1, goal.request.order):
        sequence.append(sequence[-1] + sequence[-2])
        goal.publish_feedback(Fibonacci.Feedback(sequence=sequence))
        time.sleep(0.05)
    goal.succeed()
    return Fibonacci.Result(sequence=sequence)


@pytest.fixture
def spinning(node: Node) -> Iterator[MultiThreadedExecutor]:
    """``node`` spun by two threads in the background (the server sleeps in its callback)."""
    executor = MultiThreadedExecutor(num_threads=2, context=node.context)
    executor.add_node(node)
    thread = threading.Thread(target=executor.spin, daemon=True)
    thread.start()
    yield executor
    executor.shutdown()
    thread.join(10)


def _recorded(node: Node, topic: str) -> bool:
    """Whether the recorder subscribes to ``topic`` (the action client does too)."""
    subscribers = node.get_subscriptions_info_by_topic(topic)
    return any(s.node_name == "bagkit_recorder" for s in subscribers)


def _bagkit(*args: str) -> str:
    return subprocess.run(
        [BAGKIT, *args], capture_output=True, text=True, check=True, timeout=120
    ).stdout


@pytest.mark.parametrize("selection", [["--actions", ACTION], ["-a"]], ids=["actions", "all"])
def test_record_actions_keeps_feedback_and_status(
    node: Node,
    spinning: MultiThreadedExecutor,
    processes: Any,
    tmp_path: Path,
    selection: list[str],
) -> None:
    group = ReentrantCallbackGroup()
    server = ActionServer(node, Fibonacci, ACTION, _execute, callback_group=group)
    client = ActionClient(node, Fibonacci, ACTION, callback_group=group)
    bag = tmp_path / "fib"
    recorder = processes.start(
        ["bagkit", "record", *selection, "-o", str(bag), "--log-level", "warn"],
        stderr=subprocess.PIPE,
        text=True,
    )
    wait_for(lambda: _recorded(node, FEEDBACK) and _recorded(node, STATUS), 30)
    assert client.wait_for_server(timeout_sec=10)
    received: list[list[int]] = []
    sent = client.send_goal_async(
        Fibonacci.Goal(order=ORDER),
        feedback_callback=lambda m: received.append(list(m.feedback.sequence)),
    )
    wait_for(sent.done, 10)
    goal = sent.result()
    assert goal.accepted
    result_future = goal.get_result_async()
    wait_for(result_future.done, 30)
    assert result_future.result().status == GoalStatus.STATUS_SUCCEEDED
    time.sleep(0.5)  # the last feedback and status reach the recorder
    recorder.send_signal(signal.SIGINT)
    assert recorder.wait(30) == EXIT_INTERRUPTED  # stopped by SIGINT, the bag finished
    assert recorder.stderr is not None
    assert "not recording" not in recorder.stderr.read()
    server.destroy()
    client.destroy()

    assert len(received) == ORDER - 1
    info = json.loads(_bagkit("info", str(bag), "--format", "json"))
    counts = {t["topic"]: t["count"] for t in info["topics"] if "/_action/" in t["topic"]}
    assert set(counts) == {FEEDBACK, STATUS}
    assert info["actions"] == [
        {
            "action": ACTION,
            "type": "test_msgs/action/Fibonacci",
            "feedback": len(received),
            "status": counts[STATUS],
            "service_events": 0,
        }
    ]
    echoed = [
        json.loads(line)
        for line in _bagkit("echo", str(bag), FEEDBACK, "--format", "json").splitlines()
    ]
    assert [m["data"]["feedback"]["sequence"] for m in echoed] == received
    uuid = list(goal.goal_id.uuid)
    assert all(m["data"]["goal_id"]["uuid"] == uuid for m in echoed)
    statuses = [
        json.loads(line)
        for line in _bagkit("echo", str(bag), STATUS, "--format", "json").splitlines()
    ]
    last = statuses[-1]["data"]["status_list"]
    assert [s["status"] for s in last if s["goal_info"]["goal_id"]["uuid"] == uuid] == [
        GoalStatus.STATUS_SUCCEEDED
    ]
