"""MCAP bags as rosbag2 Rolling (Kilted on) writes them, written with the ``mcap`` library.

Definition texts are built here the way rosbag2's ``LocalMessageDefinitionSource`` builds them
(its dependency regexes, its delimiters), from the interface files the ROS wheels install:
``ros2idl`` for a type recorded from its ``.idl`` (every section after ``IDL: pkg/msg/Name``,
``#include`` lines kept), and ``ACTION: pkg/action/Name`` followed by the ``.action`` text and
its ``MSG:`` dependencies on each of an action's five topics, whatever the topic's type.
Payloads are serialized by mcap_ros2 from ``ros2msg`` texts written out here by hand: an
oracle independent of bagkit's definitions code.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path
from typing import Any

from mcap.writer import CompressionType, Writer
from mcap_ros2._dynamic import serialize_dynamic

SHARE = Path(sys.prefix) / "share"
SEPARATOR = "=" * 80 + "\n"
# rosbag2's MSG_FIELD_TYPE_REGEX and IDL_FIELD_TYPE_REGEX.
_MSG_FIELD_TYPE = re.compile(r"(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+")
_IDL_INCLUDE = re.compile(r'(?:^|\n)#include\s+(?:"|<)([a-zA-Z0-9_/]+)\.idl(?:"|>)')
_PRIMITIVES = {
    "bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16", "uint16", "int32",
    "uint32", "int64", "uint64", "string",
}  # fmt: skip


def _file(type_name: str, suffix: str) -> str:
    parts = type_name.split("/")
    package, kind, name = (parts[0], "msg", parts[1]) if len(parts) == 2 else parts
    return (SHARE / package / kind / f"{name}{suffix}").read_text()


def _msg_dependencies(text: str, package: str) -> list[str]:
    found = {t for t in _MSG_FIELD_TYPE.findall(text) if t not in _PRIMITIVES}
    return sorted(t if "/" in t else f"{package}/{t}" for t in found)  # a std::set


def _full_text(root: str, kind: str, text: str, seen: set[str]) -> str:
    """``text`` followed by its dependencies, each after its delimiter (recursively, once)."""
    package = root.split("/", maxsplit=1)[0]
    dependencies = (
        sorted(set(_IDL_INCLUDE.findall(text)))
        if kind == "IDL"
        else _msg_dependencies(text, package)
    )
    for dependency in dependencies:
        if dependency not in seen:
            seen.add(dependency)
            suffix = ".idl" if kind == "IDL" else ".msg"
            own = _file(dependency, suffix)
            text += f"\n{SEPARATOR}{kind}: {dependency}\n" + _full_text(dependency, kind, own, seen)
    return text


def idl_definition(type_name: str) -> str:
    """rosbag2's ``ros2idl`` text of a message type (its fallback when no ``.msg`` exists)."""
    return f"{SEPARATOR}IDL: {type_name}\n" + _full_text(
        type_name, "IDL", _file(type_name, ".idl"), set()
    )


def action_definition(action: str, text: str | None = None) -> str:
    """rosbag2's text on each topic of an action (``ACTION:``, then ``MSG:`` dependencies)."""
    own = _file(action, ".action") if text is None else text
    return f"{SEPARATOR}ACTION: {action}\n" + _full_text(action, "MSG", own, set())


def msg_definition(type_name: str) -> str:
    """rosbag2's ``ros2msg`` text of an installed message type."""
    return _full_text(type_name, "MSG", _file(type_name, ".msg"), set())


# The types rosidl derives from test_msgs/action/Fibonacci, as ros2msg texts (the oracle).
_UUID = "MSG: unique_identifier_msgs/UUID\nuint8[16] uuid\n"
_TIME = "MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n"
EVENT_INFO = (
    "MSG: service_msgs/ServiceEventInfo\nuint8 event_type\nbuiltin_interfaces/Time stamp\n"
    f"char[16] client_gid\nint64 sequence_number\n{SEPARATOR}{_TIME}"
)
_GOAL_INFO = (
    "MSG: action_msgs/GoalInfo\nunique_identifier_msgs/UUID goal_id\n"
    f"builtin_interfaces/Time stamp\n{SEPARATOR}{_UUID}{SEPARATOR}{_TIME}"
)
ORACLE_TEXTS = {
    "test_msgs/action/Fibonacci_FeedbackMessage": (
        "unique_identifier_msgs/UUID goal_id\ntest_msgs/Feedback feedback\n"
        f"{SEPARATOR}{_UUID}{SEPARATOR}MSG: test_msgs/Feedback\nint32[] sequence\n"
    ),
    "test_msgs/action/Fibonacci_SendGoal_Event": (
        "service_msgs/ServiceEventInfo info\ntest_msgs/Req[<=1] request\n"
        f"test_msgs/Resp[<=1] response\n{SEPARATOR}{EVENT_INFO}{SEPARATOR}MSG: test_msgs/Req\n"
        f"unique_identifier_msgs/UUID goal_id\ntest_msgs/Goal goal\n{SEPARATOR}{_UUID}"
        f"{SEPARATOR}MSG: test_msgs/Goal\nint32 order\n{SEPARATOR}MSG: test_msgs/Resp\n"
        "bool accepted\nbuiltin_interfaces/Time stamp\n"
    ),
    "test_msgs/action/Fibonacci_GetResult_Event": (
        "service_msgs/ServiceEventInfo info\ntest_msgs/Req[<=1] request\n"
        f"test_msgs/Resp[<=1] response\n{SEPARATOR}{EVENT_INFO}{SEPARATOR}MSG: test_msgs/Req\n"
        f"unique_identifier_msgs/UUID goal_id\n{SEPARATOR}{_UUID}{SEPARATOR}MSG: test_msgs/Resp\n"
        f"int8 status\ntest_msgs/Result result\n{SEPARATOR}MSG: test_msgs/Result\n"
        "int32[] sequence\n"
    ),
    "action_msgs/srv/CancelGoal_Event": (
        "service_msgs/ServiceEventInfo info\naction_msgs/Req[<=1] request\n"
        f"action_msgs/Resp[<=1] response\n{SEPARATOR}{EVENT_INFO}{SEPARATOR}MSG: action_msgs/Req\n"
        f"action_msgs/GoalInfo goal_info\n{SEPARATOR}{_GOAL_INFO}{SEPARATOR}"
        "MSG: action_msgs/Resp\nint8 return_code\naction_msgs/GoalInfo[] goals_canceling\n"
    ),
    "action_msgs/msg/GoalStatusArray": (
        "action_msgs/GoalStatus[] status_list\n"
        f"{SEPARATOR}MSG: action_msgs/GoalStatus\naction_msgs/GoalInfo goal_info\nint8 status\n"
        f"{SEPARATOR}{_GOAL_INFO}"
    ),
}


def serialize(type_name: str, message: dict[str, Any], text: str | None = None) -> bytes:
    """CDR of ``message`` by mcap_ros2 from an oracle ``ros2msg`` text."""
    own = text if text is not None else ORACLE_TEXTS.get(type_name) or msg_definition(type_name)
    root = type_name.split("/", maxsplit=1)[0] + "/msg/Root"  # mcap_ros2: no "_" in names
    return bytes(serialize_dynamic(root, own)[root](message))


def goal_id(n: int) -> dict[str, Any]:
    return {"uuid": [n] * 16}


def _event(kind: int, n: int, request: list[Any], response: list[Any]) -> dict[str, Any]:
    info = {
        "event_type": kind,
        "stamp": {"sec": n, "nanosec": 0},
        "client_gid": [7] * 16,
        "sequence_number": n,
    }
    return {"info": info, "request": request, "response": response}


def fibonacci_messages(n: int) -> dict[str, list[tuple[int, dict[str, Any]]]]:
    """``n`` goals' worth of messages per part of ``test_msgs/action/Fibonacci``, as
    ``(log time, message)``; the part's type is :func:`action_topics`'."""
    parts: dict[str, list[tuple[int, dict[str, Any]]]] = {
        p: [] for p in ("feedback", "status", "send_goal", "get_result", "cancel_goal")
    }
    for i in range(n):
        t = 1_000_000_000 + i * 100_000_000
        sequence = [0, 1, 1, 2, 3, 5][: i + 2]
        parts["send_goal"].append(
            (t, _event(0, i, [{"goal_id": goal_id(i), "goal": {"order": i}}], []))
        )
        parts["feedback"].append(
            (t + 1, {"goal_id": goal_id(i), "feedback": {"sequence": sequence}})
        )
        status = {
            "goal_info": {"goal_id": goal_id(i), "stamp": {"sec": i, "nanosec": 5}},
            "status": 4,
        }
        parts["status"].append((t + 2, {"status_list": [status]}))
        result = {"status": 4, "result": {"sequence": sequence}}
        parts["get_result"].append((t + 3, _event(2, i, [], [result])))
        cancel = {"return_code": 0, "goals_canceling": []}
        parts["cancel_goal"].append((t + 4, _event(2, i, [], [cancel])))
    return parts


def action_topics(action: str, action_type: str) -> dict[str, tuple[str, str]]:
    """Part -> (topic, type) of an action's five recorded topics."""
    return {
        "feedback": (f"{action}/_action/feedback", f"{action_type}_FeedbackMessage"),
        "status": (f"{action}/_action/status", "action_msgs/msg/GoalStatusArray"),
        "send_goal": (
            f"{action}/_action/send_goal/_service_event",
            f"{action_type}_SendGoal_Event",
        ),
        "get_result": (
            f"{action}/_action/get_result/_service_event",
            f"{action_type}_GetResult_Event",
        ),
        "cancel_goal": (
            f"{action}/_action/cancel_goal/_service_event",
            "action_msgs/srv/CancelGoal_Event",
        ),
    }


class RollingBag:
    """One MCAP file written as rosbag2 Rolling would (profile ros2, one schema per text)."""

    def __init__(self, path: Path, compression: CompressionType = CompressionType.ZSTD) -> None:
        self.handle = open(path, "wb")  # noqa: SIM115 (closed in finish)
        self.writer = Writer(self.handle, compression=compression, chunk_size=4096)
        self.writer.start("ros2", "rosbag2")
        self._schemas: dict[tuple[str, str, str], int] = {}

    def topic(self, topic: str, type_name: str, text: str, encoding: str = "ros2msg") -> int:
        """Register a topic whose schema holds ``text``; returns its channel id."""
        key = (type_name, encoding, text)
        if key not in self._schemas:
            self._schemas[key] = self.writer.register_schema(type_name, encoding, text.encode())
        return self.writer.register_channel(topic, "cdr", self._schemas[key])

    def write(self, channel: int, log_time: int, data: bytes) -> None:
        self.writer.add_message(channel, log_time=log_time, data=data, publish_time=log_time)

    def finish(self) -> None:
        self.writer.finish()
        self.handle.close()
