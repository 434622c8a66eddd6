"""Which topics the action options select, as rosbag2 Kilted selects an action's parts."""

from __future__ import annotations

from bagkit.recording.options import RecordOptions
from bagkit.selection.actions import action_topic_part

FEEDBACK = ["test_msgs/action/Fibonacci_FeedbackMessage"]
STATUS = ["action_msgs/msg/GoalStatusArray"]


def test_action_options() -> None:
    selection = RecordOptions(actions=("fib",)).selection
    assert selection.matches("/fib/_action/feedback", FEEDBACK)
    assert selection.matches("/fib/_action/status", STATUS)
    assert not selection.matches("/other/_action/status", STATUS)
    assert not selection.matches("/fib", ["std_msgs/msg/String"])
    everything = RecordOptions(all_actions=True, exclude_actions=("/other",)).selection
    assert everything.matches("/a/b/_action/feedback", FEEDBACK)
    assert not everything.matches("/other/_action/feedback", FEEDBACK)
    excluded = RecordOptions(all_actions=True, exclude_regex="fi").selection
    assert not excluded.matches("/fib/_action/status", STATUS)


def test_topic_and_service_options_never_select_action_topics() -> None:
    topics = RecordOptions(all_topics=True, include_hidden=True, all_services=True).selection
    assert not topics.matches("/fib/_action/status", STATUS)
    cancel = ["action_msgs/srv/CancelGoal_Event"]
    assert not topics.matches("/fib/_action/cancel_goal/_service_event", cancel)
    assert RecordOptions(actions=("/fib",)).selection.matches(
        "/fib/_action/cancel_goal/_service_event", cancel
    )
    named = RecordOptions(topics=("/fib/_action/status",)).selection
    assert named.matches("/fib/_action/status", STATUS)


def test_parts() -> None:
    assert action_topic_part("/ns/fib/_action/feedback", FEEDBACK) == ("/ns/fib", "feedback")
    assert action_topic_part("/fib/_action/status") == ("/fib", "status")
    assert action_topic_part("/fib/_action/feedback", ["std_msgs/msg/String"]) is None
    assert action_topic_part("/_action/status", STATUS) is None
    assert action_topic_part("/fib/_action/other", STATUS) is None
