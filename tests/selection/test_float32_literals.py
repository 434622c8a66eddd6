"""A number written in a condition against a float32 field: every command matches the same
messages, those whose value (a float32, exactly as decoded: rosbags, rclpy) compares so with
it. The bulk match compared the value rounded to float32 instead: ``range <= 1.6`` held for
the float32 just above 1.6 in find, filter, export and stats, not in echo or ``--no-bulk``."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from bagkit_runs import bagkit_in_process
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

JAZZY = get_typestore(Stores.ROS2_JAZZY)
RANGE = "sensor_msgs/msg/Range"
CONDITIONS = ["range >= 1.5 and range <= 1.6", "range > 1.6", "range == 1.6", "range < 1.1"]


@pytest.fixture(scope="module")
def bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("f32") / "sonar"
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        sonar = writer.add_connection("/sonar", RANGE, typestore=JAZZY)
        for i in range(100):
            msg = JAZZY.types[RANGE](
                header=JAZZY.types["std_msgs/msg/Header"](
                    stamp=JAZZY.types["builtin_interfaces/msg/Time"](sec=i, nanosec=0),
                    frame_id="sonar",
                ),
                radiation_type=0,
                field_of_view=0.5,
                min_range=0.1,
                max_range=4.0,
                range=1.0 + i * 0.01,
                variance=0.0,
            )
            writer.write(sonar, 10**18 + i * 10**8, bytes(JAZZY.serialize_cdr(msg, RANGE)))
    return path


def _expected(bag: Path, condition: str) -> int:
    """The messages whose range, as rosbags decodes it (a Python float), satisfies it."""
    low, high = {
        CONDITIONS[0]: (1.5, 1.6),
        CONDITIONS[1]: (1.6, None),
        CONDITIONS[2]: (1.6, 1.6),
        CONDITIONS[3]: (None, 1.1),
    }[condition]
    with AnyReader([bag]) as reader:
        values = [reader.deserialize(raw, c.msgtype).range for c, _, raw in reader.messages()]  # type: ignore[attr-defined]
    if condition == CONDITIONS[1]:
        return sum(v > low for v in values)
    if condition == CONDITIONS[3]:
        return sum(v < high for v in values)
    return sum(low <= v <= high for v in values)


def _count(args: list[str | Path]) -> str:
    done = bagkit_in_process(args)
    assert done.returncode == 0, done.stderr
    return done.stdout


@pytest.mark.parametrize("condition", CONDITIONS)
def test_every_command_matches_the_same_messages(bag: Path, condition: str) -> None:
    expected = _expected(bag, condition)
    echoed = _count(["echo", bag, "/sonar", "--where", condition, "--format", "json"])
    found = json.loads(
        _count(
            ["find", bag, "--when", f"/sonar: {condition}", "--format", "json", "--workers", "0"]
        )
    )
    counts = {"echo": len(echoed.splitlines()), "find": sum(e["count"] for e in found)}
    for bulk in ("--bulk", "--no-bulk"):
        stats = json.loads(
            _count(
                [
                    "stats",
                    "summary",
                    bag,
                    "-f",
                    "range",
                    "--where",
                    condition,
                    "--format",
                    "json",
                    "--workers",
                    "0",
                    bulk,
                ]
            )
        )
        counts[bulk] = stats["topics"][0]["count"] if stats["topics"] else 0
    assert counts == dict.fromkeys(counts, expected)
