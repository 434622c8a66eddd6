"""Actions as rosbag2 records them: the hidden topics under ``<action>/_action/``.

An action ``/name`` publishes its feedback on ``/name/_action/feedback``
(``pkg/action/Name_FeedbackMessage``) and its goals' states on ``/name/_action/status``
(``action_msgs/msg/GoalStatusArray``); its goal, result and cancel services are
``/name/_action/send_goal``, ``get_result`` and ``cancel_goal``, whose introspection events
(``.../_service_event``) exist from Kilted on. All of these are an action's parts: selected by the
action options (``--actions``, ``--all-actions``, ``-a``), never by the topic or service options.
No rclpy import.
"""

from __future__ import annotations

from collections.abc import Iterable

from bagkit.selection.topics import ACTION_INFIX, SERVICE_EVENT_SUFFIX

FEEDBACK_TOPIC = "feedback"
STATUS_TOPIC = "status"
STATUS_TYPE = "action_msgs/msg/GoalStatusArray"
ACTION_SERVICES = ("send_goal", "get_result", "cancel_goal")


def is_action_type(type_name: str) -> bool:
    """Whether ``type_name`` is derived from an action, ``pkg/action/Name_Part``."""
    return type_name.split("/")[1:2] == ["action"]


# Each part's name under ``_action/`` and whether a type fits it.
_PART_TYPES = {
    FEEDBACK_TOPIC: lambda t: is_action_type(t) and t.endswith("_FeedbackMessage"),
    STATUS_TOPIC: lambda t: t == STATUS_TYPE,
    **{f"{s}{SERVICE_EVENT_SUFFIX}": lambda t: t.endswith("_Event") for s in ACTION_SERVICES},
}


def action_topic_part(name: str, types: Iterable[str] = ()) -> tuple[str, str] | None:
    """``/fib/_action/feedback`` -> ``("/fib", "feedback")``: the action and part of a topic.

    None when ``name`` (of ``types``, where known) is not one of an action's parts.
    """
    action, infix, part = name.rpartition(ACTION_INFIX)
    fits = _PART_TYPES.get(part) if infix and action else None
    if fits is None or not all(fits(t) for t in types):
        return None
    return action, part


def action_part_topics(action: str, topic_types: Iterable[tuple[str, str]]) -> list[str]:
    """The topics of ``(topic, type)`` pairs that are parts of ``action`` (``/fib``, with or
    without its leading slash), sorted."""
    wanted = "/" + action.strip("/")
    found = []
    for topic, type_name in topic_types:
        part = action_topic_part("/" + topic.lstrip("/"), [type_name])
        if part is not None and part[0] == wanted:
            found.append(topic)
    return sorted(found)
