"""``bagkit play`` of a topic whose stored definition is an older version of the installed type:
nothing is published on it unless ``--on-drift raw`` says so; real subscribers of today's type."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
from rclpy.serialization import deserialize_message, serialize_message
from replay_harness import Listener
from sensor_msgs.msg import Range, Temperature
from waiting import wait_for

from bagkit.bag import BagWriter, TopicInfo, message_definition

BAGKIT = str(Path(sys.executable).with_name("bagkit"))
START_NS = 1_700_000_000_000_000_000
COUNT = 20


def _humble_range_bag(path: Path) -> Path:
    """/range as Humble recorded it (Jazzy's Range without ``variance``, its last field) and an
    unchanged /temperature, 20 messages each at 20 Hz."""
    text = "".join(
        line
        for line in message_definition("sensor_msgs/msg/Range").splitlines(keepends=True)
        if not line.startswith("float32 variance")
    )
    with BagWriter(path) as writer:
        writer.add_topic(TopicInfo("/range", "sensor_msgs/msg/Range"), text)
        writer.add_topic(TopicInfo("/temperature", "sensor_msgs/msg/Temperature"))
        for i in range(COUNT):
            t = START_NS + i * 50_000_000
            jazzy = bytes(serialize_message(Range(range=float(i))))
            writer.write("/range", jazzy[:-4], log_time=t)  # without the trailing float32
            writer.write("/temperature", bytes(serialize_message(Temperature())), log_time=t)
    return path


def _play(bag: Path, *extra: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [BAGKIT, "play", str(bag), "--wait-for", "/temperature", "--disable-keyboard-controls",
         "--format", "json", *extra],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )  # fmt: skip


def test_a_drifted_topic_is_skipped_unless_raw(
    tmp_path: Path, listener_factory: type[Listener]
) -> None:
    bag = _humble_range_bag(tmp_path / "bag")
    listener = listener_factory({"/range": Range, "/temperature": Temperature})

    skipped = _play(bag)
    assert skipped.returncode == 0, skipped.stderr
    assert (
        "warning: /range: its definition differs from the installed one (added: variance "
        "(float32)): not replayed" in skipped.stderr
    )
    report: dict[str, Any] = json.loads(skipped.stdout)
    assert report["drifted"] == {"/range": ["added: variance (float32)"]}
    wait_for(lambda: len(listener.messages("/temperature")) == COUNT, 15.0)
    assert listener.messages("/range") == []

    raw = _play(bag, "--on-drift", "raw")
    assert raw.returncode == 0, raw.stderr
    assert "/range: its definition differs" in raw.stderr and "published as recorded" in raw.stderr
    wait_for(lambda: len(listener.messages("/range")) == COUNT, 15.0)
    assert [len(m.data) for m in listener.messages("/range")] == [
        len(bytes(serialize_message(Range()))) - 4
    ] * COUNT


def test_a_drifted_topic_is_migrated_on_the_fly(
    tmp_path: Path, listener_factory: type[Listener]
) -> None:
    """--on-drift migrate: today's Range, its ``variance`` at the default, every recorded
    value kept; the rules file of --drift-rules applies (here: variance from the range)."""
    bag = _humble_range_bag(tmp_path / "bag")
    listener = listener_factory({"/range": Range, "/temperature": Temperature})
    migrated = _play(bag, "--on-drift", "migrate")
    assert migrated.returncode == 0, migrated.stderr
    assert "/range: its definition differs" in migrated.stderr
    assert "each message migrated to the installed definition" in migrated.stderr
    wait_for(lambda: len(listener.messages("/range")) == COUNT, 15.0)
    received = [deserialize_message(m.data, Range) for m in listener.messages("/range")]
    assert [(m.range, m.variance) for m in received] == [(float(i), 0.0) for i in range(COUNT)]

    rules = tmp_path / "rules.yaml"
    rules.write_text("sensor_msgs/msg/Range:\n  compute: {variance: range / 100}\n")
    with_rules = _play(bag, "--on-drift", "migrate", "--drift-rules", str(rules))
    assert with_rules.returncode == 0, with_rules.stderr
    wait_for(lambda: len(listener.messages("/range")) == 2 * COUNT, 15.0)
    second = listener.messages("/range")[COUNT:]
    variances = [deserialize_message(m.data, Range).variance for m in second]
    assert variances == [float(np.float32(i / 100)) for i in range(COUNT)]
