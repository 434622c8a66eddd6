"""``bagkit info`` groups an action's feedback and status topics under the action's name."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

from action_msgs.msg import GoalStatus, GoalStatusArray
from rclpy.serialization import serialize_message
from test_msgs.action import Fibonacci

from bagkit.bag import BagWriter, TopicInfo
from bagkit.bag.action_info import action_summaries
from bagkit.bag.info import TopicSummary

BAGKIT = str(Path(sys.executable).with_name("bagkit"))
FEEDBACK_TYPE = "test_msgs/action/Fibonacci_FeedbackMessage"
STATUS_TYPE = "action_msgs/msg/GoalStatusArray"


def _summary(topic: str, type_name: str, count: int) -> TopicSummary:
    return TopicSummary(topic, type_name, count, None, "cdr", "")


def test_parts_are_grouped_by_action() -> None:
    topics = [
        _summary("/fib/_action/feedback", FEEDBACK_TYPE, 5),
        _summary("/fib/_action/status", STATUS_TYPE, 3),
        _summary("/fib/_action/send_goal/_service_event", "test_msgs/action/X_SendGoal_Event", 2),
        _summary("/nav/_action/status", STATUS_TYPE, 1),
        _summary("/imu", "sensor_msgs/msg/Imu", 9),
        _summary("/x/_action/feedback", "std_msgs/msg/String", 4),
    ]
    by_name = {a.action: a for a in action_summaries(topics)}
    assert set(by_name) == {"/fib", "/nav"}
    fib = by_name["/fib"]
    assert (fib.type, fib.feedback, fib.status, fib.service_events) == (
        "test_msgs/action/Fibonacci",
        5,
        3,
        2,
    )
    assert (by_name["/nav"].type, by_name["/nav"].feedback, by_name["/nav"].status) == ("", 0, 1)


def test_info_lists_actions(tmp_path: Path) -> None:
    path = tmp_path / "action"
    feedback = Fibonacci.Impl.FeedbackMessage()
    status = GoalStatusArray(status_list=[GoalStatus(status=GoalStatus.STATUS_EXECUTING)])
    with BagWriter(path) as bag:
        bag.add_topic(TopicInfo("/fib/_action/feedback", FEEDBACK_TYPE))
        bag.add_topic(TopicInfo("/fib/_action/status", STATUS_TYPE))
        for i in range(4):
            feedback.feedback.sequence = list(range(i + 1))
            bag.write("/fib/_action/feedback", serialize_message(feedback), log_time=10 + i)
        bag.write("/fib/_action/status", serialize_message(status), log_time=9)
    env = {**os.environ, "COLUMNS": "200"}
    run = [BAGKIT, "info", str(path)]
    done = subprocess.run(
        [*run, "--format", "json"], capture_output=True, text=True, env=env, check=False
    )
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout)["actions"] == [
        {
            "action": "/fib",
            "type": "test_msgs/action/Fibonacci",
            "feedback": 4,
            "status": 1,
            "service_events": 0,
        }
    ]
    table = subprocess.run(run, capture_output=True, text=True, env=env, check=True).stdout
    actions = table[table.index("Actions") :]
    assert "/fib" in actions and "test_msgs/action/Fibonacci " in actions
