"""The message texts rosidl generates from an ``.action`` file, in ``ros2msg`` form.

``pkg/action/Name.action`` holds three sections (goal, result, feedback, split by ``---``);
rosidl derives from them ``Name_Goal``, ``Name_Result``, ``Name_Feedback``, the feedback topic's
``Name_FeedbackMessage`` (``goal_id`` + ``feedback``) and the request and response of the
``Name_SendGoal`` and ``Name_GetResult`` services, each a ``pkg/action/...`` type. Pure text work:
finding the file is :mod:`bagkit.bag.definitions`' job.
"""

from __future__ import annotations

import re

_SECTIONS = ("Goal", "Result", "Feedback")
# The services' events (Kilted's action introspection) are defined like any service's event.
_EVENT_OF = {"SendGoal_Event": "SendGoal", "GetResult_Event": "GetResult"}
ACTION_PART_SUFFIXES = (
    *_SECTIONS,
    "FeedbackMessage",
    "SendGoal_Request",
    "SendGoal_Response",
    "GetResult_Request",
    "GetResult_Response",
    *_EVENT_OF,
)
"""The suffixes ``_X`` of the types rosidl derives from an ``.action`` that bagkit defines."""
_PART = re.compile(rf"^(?P<stem>.+?)_(?P<suffix>{'|'.join(ACTION_PART_SUFFIXES)})$")


def split_action_part(name: str) -> tuple[str, str] | None:
    """``Fibonacci_FeedbackMessage`` -> ``("Fibonacci", "FeedbackMessage")``; None for others."""
    match = _PART.match(name)
    return (match["stem"], match["suffix"]) if match else None


def action_part_texts(package: str, stem: str, action_text: str) -> dict[str, str]:
    """The ``ros2msg`` text of every derived type of ``package/action/stem``, by suffix.

    Field types refer to the other parts as ``package/Stem_Suffix`` (read as
    ``package/msg/Stem_Suffix``, the form every ``ros2msg`` reader resolves), as bagkit does
    for a service event's request and response.
    """
    sections = _split_sections(action_text)
    part = f"{package}/{stem}"
    texts = dict(zip(_SECTIONS, sections, strict=True))
    texts["FeedbackMessage"] = f"unique_identifier_msgs/UUID goal_id\n{part}_Feedback feedback\n"
    texts["SendGoal_Request"] = f"unique_identifier_msgs/UUID goal_id\n{part}_Goal goal\n"
    texts["SendGoal_Response"] = "bool accepted\nbuiltin_interfaces/Time stamp\n"
    texts["GetResult_Request"] = "unique_identifier_msgs/UUID goal_id\n"
    texts["GetResult_Response"] = f"int8 status\n{part}_Result result\n"
    for event, service in _EVENT_OF.items():
        texts[event] = (
            "service_msgs/ServiceEventInfo info\n"
            f"{part}_{service}_Request[<=1] request\n"
            f"{part}_{service}_Response[<=1] response\n"
        )
    return texts


def _split_sections(action_text: str) -> tuple[str, str, str]:
    """The goal, result and feedback texts of an ``.action`` file (missing ones empty)."""
    sections = [""]
    for line in action_text.splitlines(keepends=True):
        if line.strip() == "---":
            sections.append("")
        else:
            sections[-1] += line
    sections += [""] * (3 - len(sections))
    return sections[0], sections[1], sections[2]
