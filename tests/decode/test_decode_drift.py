"""Drift between a stored and the installed definition, named per field; ``doctor
--against-installed`` on bags whose definitions were edited in the test."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from bagkit.bag import BagWriter, TopicInfo, message_definition
from bagkit.decode.drift import DriftStatus, bag_drift, definition_changes
from bagkit.decode.message_types import MessageTypes

BAGKIT = str(Path(sys.executable).with_name("bagkit"))


def _fielddefs(name: str, text: str) -> dict[str, object]:
    types = MessageTypes()
    types.add(name, text)
    assert name not in types.problems, types.problems
    return dict(types.typestore.fielddefs)


def _changes(old: str, new: str, name: str = "my_msgs/msg/Battery") -> list[str]:
    return definition_changes(name, _fielddefs(name, old), _fielddefs(name, new))


BATTERY = "uint8 FULL=100\nfloat32 voltage\nfloat32[3] cells\nstring<=8 label\n"


@pytest.mark.parametrize(
    ("new", "expected"),
    [
        (BATTERY, []),
        (BATTERY + "float32 current\n", ["added: current (float32)"]),
        (BATTERY.replace("string<=8 label\n", ""), ["removed: label (string<=8)"]),
        (
            BATTERY.replace("float32 voltage", "float64 voltage"),
            ["type changed: voltage (float32 -> float64)"],
        ),
        (BATTERY.replace("[3]", "[4]"), ["type changed: cells (float32[3] -> float32[4])"]),
        (BATTERY.replace("[3]", "[]"), ["type changed: cells (float32[3] -> float32[])"]),
        (BATTERY.replace("<=8", "<=16"), ["type changed: label (string<=8 -> string<=16)"]),
        (
            BATTERY.replace("FULL=100", "FULL=99"),
            ["constant changed: FULL (uint8 100 -> uint8 99)"],
        ),
        (BATTERY.replace("uint8 FULL=100\n", ""), ["constant removed: FULL"]),
        (
            "uint8 FULL=100\nfloat32[3] cells\nfloat32 voltage\nstring<=8 label\n",
            ["order changed: my_msgs/msg/Battery (voltage, cells, label -> cells, voltage, label)"],
        ),
    ],
)  # fmt: skip
def test_each_kind_of_change_is_named(new: str, expected: list[str]) -> None:
    assert _changes(BATTERY, new) == expected


def test_nested_changes_are_named_by_their_path() -> None:
    sep = "=" * 80
    old = f"my_msgs/Cell[] cells\n{sep}\nMSG: my_msgs/Cell\nfloat32 voltage\n"
    new = f"my_msgs/Cell[] cells\n{sep}\nMSG: my_msgs/Cell\nfloat32 voltage\nfloat32 temp\n"
    assert _changes(old, new, "my_msgs/msg/Pack") == ["added: cells[*].temp (float32)"]


def _range_bag(path: Path, definition: str) -> Path:
    with BagWriter(path) as bag:
        bag.add_topic(TopicInfo("/range", "sensor_msgs/msg/Range"), definition)
        bag.add_topic(TopicInfo("/temperature", "sensor_msgs/msg/Temperature"))
    return path


def _without_variance() -> str:
    """Jazzy's Range as Humble defined it: the same text without the ``variance`` line."""
    lines = message_definition("sensor_msgs/msg/Range").splitlines(keepends=True)
    kept = [line for line in lines if not line.startswith("float32 variance")]
    assert len(kept) == len(lines) - 1
    return "".join(kept)


def test_a_humble_range_drifts_by_its_variance(tmp_path: Path) -> None:
    drifts = {d.topic: d for d in bag_drift(_range_bag(tmp_path / "bag", _without_variance()))}
    assert drifts["/range"].status == DriftStatus.DRIFTED
    assert drifts["/range"].changes == ["added: variance (float32)"]
    assert drifts["/temperature"].status == DriftStatus.SAME


def test_doctor_against_installed_lists_the_drift(tmp_path: Path) -> None:
    bag = _range_bag(tmp_path / "bag", _without_variance())
    done = subprocess.run(
        [BAGKIT, "doctor", str(bag), "--against-installed", "--format", "json"],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert done.returncode == 1, done.stderr
    topics = {t["topic"]: t for t in json.loads(done.stdout)["topics"]}
    assert topics["/range"]["changes"] == ["added: variance (float32)"]
    assert topics["/temperature"]["status"] == "same"
    assert done.stderr.strip() == (
        f"{bag}: 1 of 2 topics drifted from the installed definitions: /range"
    )


def test_doctor_against_installed_passes_an_unchanged_bag(tmp_path: Path) -> None:
    bag = _range_bag(tmp_path / "bag", message_definition("sensor_msgs/msg/Range"))
    done = subprocess.run(
        [BAGKIT, "doctor", str(bag), "--against-installed"],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines() == [
        "/range (sensor_msgs/msg/Range): same",
        "/temperature (sensor_msgs/msg/Temperature): same",
    ]


def test_a_type_that_is_not_installed_is_said(tmp_path: Path) -> None:
    with BagWriter(tmp_path / "bag") as bag:
        bag.add_topic(TopicInfo("/battery", "my_msgs/msg/Battery"), BATTERY)
    (drift,) = bag_drift(tmp_path / "bag")
    assert drift.status == DriftStatus.NOT_INSTALLED
    assert "my_msgs" in drift.changes[0]
