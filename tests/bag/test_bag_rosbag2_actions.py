"""An action's five topics as rosbag2 (Kilted on) stores their definitions, per its
``LocalMessageDefinitionSource`` and storage plugins:

- MCAP: one schema per type name, named after the topic's type, holding the ``ACTION:`` text;
  the status and cancel topics (``action_msgs`` types) hold it only when another topic of the
  action was recorded first, else encoding ``unknown`` and no text.
- SQLite3: one ``message_definitions`` row per type the text was found for, keyed by the
  action's type (``pkg/action/Name``), not by the topics' types; ``unknown`` rows without text.

Values are compared with the messages the test serialized (mcap_ros2, from oracle texts)."""

from __future__ import annotations

import json
import sqlite3
import subprocess
from pathlib import Path
from typing import Any

import pytest
from bagkit_runs import bagkit_in_process
from rolling_bags import (
    RollingBag,
    action_definition,
    action_topics,
    fibonacci_messages,
    idl_definition,
    serialize,
)
from rosbags.rosbag2 import StoragePlugin, Writer

ACTION = "test_msgs/action/Fibonacci"
# Status and cancel first: rosbag2 does not know the action's type yet when it stores them.
ORDER = ("status", "cancel_goal", "feedback", "send_goal", "get_result")
IDL_TYPE = "test_msgs/msg/Builtins"  # in no rosbags type store: only its stored text decodes
Written = dict[str, list[tuple[int, dict[str, Any]]]]


def _run(*args: str | Path) -> subprocess.CompletedProcess[str]:
    """``bagkit ARGS`` in this process (tests/bagkit_runs.py): the bags' texts are the point."""
    return bagkit_in_process(list(args))


def _echo(bag: Path, topic: str) -> list[tuple[int, Any]]:
    done = _run("echo", bag, topic, "--format", "json")
    assert done.returncode == 0, done.stderr
    return [(r["log_time"], r["data"]) for r in map(json.loads, done.stdout.splitlines())]


def _messages() -> tuple[dict[str, tuple[str, str]], Written]:
    parts = fibonacci_messages(3)
    topics = action_topics("/fibonacci", ACTION)
    return topics, {topics[part][0]: parts[part] for part in ORDER}


def _mcap_status_first(path: Path) -> Written:
    topics, written = _messages()
    bag = RollingBag(path)
    for part in ORDER:
        topic, type_name = topics[part]
        unknown = part in ("status", "cancel_goal")
        text = "" if unknown else action_definition(ACTION)
        channel = bag.topic(topic, type_name, text, "unknown" if unknown else "ros2msg")
        for t, message in written[topic]:
            bag.write(channel, t, serialize(type_name, message))
    bag.finish()
    return written


def _db3(path: Path, *, status_first: bool) -> Written:
    topics, written = _messages()
    order = ORDER if status_first else ORDER[2:] + ORDER[:2]
    with Writer(path, version=9, storage_plugin=StoragePlugin.SQLITE3) as writer:
        connections = {
            part: writer.add_connection(*topics[part], msgdef="-", rihs01="RIHS01_" + "0" * 64)
            for part in order
        }
        builtins = writer.add_connection(
            "/builtins", IDL_TYPE, msgdef="-", rihs01="RIHS01_" + "0" * 64
        )
        for part, connection in connections.items():
            for t, message in written[topics[part][0]]:
                writer.write(connection, t, serialize(topics[part][1], message))
        written["/builtins"] = []
        for i in range(3):
            time = {"sec": i, "nanosec": 1}
            message = {"duration_value": time, "time_value": time}
            writer.write(builtins, 5 + i, serialize(IDL_TYPE, message))
            written["/builtins"].append((5 + i, message))
    rows = [
        (ACTION, "ros2msg", action_definition(ACTION)),
        (IDL_TYPE, "ros2idl", idl_definition(IDL_TYPE)),
    ]
    if status_first:
        rows += [
            (t, "unknown", "")
            for t in ("action_msgs/msg/GoalStatusArray", "action_msgs/srv/CancelGoal_Event")
        ]
    (database,) = path.glob("*.db3")
    with sqlite3.connect(database) as db:
        db.execute("DELETE FROM message_definitions")
        db.executemany(
            "INSERT INTO message_definitions (topic_type, encoding, encoded_message_definition, "
            "type_description_hash) VALUES (?, ?, ?, '')",
            rows,
        )
    return written


@pytest.mark.parametrize("variant", ["mcap_status_first", "db3", "db3_status_first"])
def test_action_topics_decode_as_rosbag2_stores_them(tmp_path: Path, variant: str) -> None:
    if variant == "mcap_status_first":
        bag = tmp_path / "bag.mcap"
        written = _mcap_status_first(bag)
    else:
        bag = tmp_path / "bag"
        written = _db3(bag, status_first=variant.endswith("first"))
    for topic, messages in written.items():
        assert _echo(bag, topic) == messages, topic
    total = sum(len(m) for m in written.values())
    done = _run("doctor", "--deep", bag)
    assert done.returncode == 0, done.stdout + done.stderr
    assert f"healthy ({total} messages in 1 file, all decoded)" in done.stdout


def test_doctor_names_topics_without_a_definition(tmp_path: Path) -> None:
    """What echo cannot decode, doctor does not call decoded: a note per topic (a bag without
    definitions is not damaged), and the healthy line says so."""
    bag = tmp_path / "bag"
    _db3(bag, status_first=False)
    (database,) = bag.glob("*.db3")
    with sqlite3.connect(database) as db:
        db.execute("DELETE FROM message_definitions WHERE topic_type = ?", (ACTION,))
    done = _run("doctor", "--deep", bag)
    assert done.returncode == 0, done.stdout + done.stderr
    lines = done.stdout.splitlines()
    feedback = f"no message definition stored for {ACTION}_FeedbackMessage"
    assert f"note: bag: /fibonacci/_action/feedback: not decoded ({feedback})" in lines
    assert not any("/status" in line or "/cancel_goal" in line for line in lines), lines
    assert lines[-1].endswith("3 topics not decoded: no definition)"), lines
    assert feedback in _run("echo", bag, "/fibonacci/_action/feedback").stderr
