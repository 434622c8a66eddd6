"""``bagkit migrate``: bags written with an older definition of an installed type, rewritten
to today's; the rules file; bad input (one error line, exit 2, nothing written).

The old bags are real MCAP bags whose schema holds another text for ``sensor_msgs/msg/...``
(the layout an older package version had), their payloads encoded from that text; the
migrated ones are read back with rclpy's own type support (the installed definition).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from bagkit_runs import bagkit_in_process
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import Range, Temperature

from bagkit.bag import BagReader, BagWriter, TopicInfo, message_definition
from bagkit.bag.distro_definitions import distro_definitions
from bagkit.decode import MessageTypes
from bagkit.migrate.errors import DataLossError
from bagkit.surgery.migrate import MigrateOptions, plan_migrations

BAGKIT = str(Path(sys.executable).with_name("bagkit"))
START_NS = 1_700_000_000_000_000_000
COUNT = 30
# Temperature as a team's fork had it: millidegrees as an integer, and a field now gone.
OLD_TEMPERATURE = (
    "std_msgs/Header header\nint32 temp_milli_c\nfloat64 variance\nint32 legacy\n\n"
    + "=" * 80
    + message_definition("sensor_msgs/msg/Temperature").split("=" * 80, 1)[1]
)
QOS = "- history: 1\n  depth: 5\n  reliability: 1\n  durability: 1\n"


def old_values(i: int) -> dict[str, Any]:
    return {"temp_milli_c": 20_000 + 37 * i, "variance": 0.25 * i, "legacy": i - 7}


def _old_bag(path: Path) -> Path:
    """/temperature in the old layout (and an unchanged /range), COUNT messages each."""
    types = MessageTypes.from_definitions({"sensor_msgs/msg/Temperature": OLD_TEMPERATURE})
    store = types.rosbags_typestore()
    name = "sensor_msgs/msg/Temperature"
    header = store.types["std_msgs/msg/Header"]
    stamp = store.types["builtin_interfaces/msg/Time"]
    make = store.types[name]
    with BagWriter(path) as writer:
        writer.custom_data["site"] = "test track"
        writer.add_topic(TopicInfo("/temperature", name, offered_qos_profiles=QOS), OLD_TEMPERATURE)
        writer.add_topic(TopicInfo("/range", "sensor_msgs/msg/Range"))
        for i in range(COUNT):
            t = START_NS + i * 10_000_000
            msg = make(header(stamp(1700000000, i), "thermo"), **old_values(i))
            writer.write("/temperature", bytes(store.serialize_cdr(msg, name)), log_time=t)
            writer.write("/range", bytes(serialize_message(Range(range=float(i)))), log_time=t)
    return path


def _migrate(*args: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    """``bagkit migrate ARGS`` in this process (tests/bagkit_runs.py); a real one with ``env``
    (a PYTHONPATH that its rules' modules are imported from)."""
    if env is None:
        return bagkit_in_process(["migrate", *args])
    return subprocess.run(
        [BAGKIT, "migrate", *args],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
        env=env,
    )


def _rules(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def _messages(bag: Path, topic: str, cls: Any) -> list[Any]:
    with BagReader(bag) as reader:
        return [deserialize_message(m.data, cls) for m in reader.messages([topic])]


RULES = """\
sensor_msgs/msg/Temperature:
  compute:
    temperature: temp_milli_c / 1000
  drop: [legacy]
"""


def test_rules_make_the_old_bag_today_s(tmp_path: Path) -> None:
    old = _old_bag(tmp_path / "old")
    out = tmp_path / "new"
    done = _migrate(str(old), "-o", str(out), "--rules", str(_rules(tmp_path / "r.yaml", RULES)),
                    "--format", "json")  # fmt: skip
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout)
    (migrated,) = report["migrated"]
    assert migrated["topic"] == "/temperature" and migrated["messages"] == COUNT
    assert "removed: temp_milli_c (int32)" in migrated["changes"]
    assert "added: temperature (float64)" in migrated["changes"]
    assert report["unchanged"] == ["/range"]
    temperatures = _messages(out, "/temperature", Temperature)
    assert [m.temperature for m in temperatures] == [
        old_values(i)["temp_milli_c"] / 1000 for i in range(COUNT)
    ]
    assert [m.variance for m in temperatures] == [old_values(i)["variance"] for i in range(COUNT)]
    assert {m.header.frame_id for m in temperatures} == {"thermo"}
    assert [m.range for m in _messages(out, "/range", Range)] == [float(i) for i in range(COUNT)]
    with BagReader(out) as reader:
        assert reader.topics["/temperature"].offered_qos_profiles == QOS
        assert reader.definitions["sensor_msgs/msg/Temperature"] == message_definition(
            "sensor_msgs/msg/Temperature"
        )
        assert reader.metadata is not None
        custom = reader.metadata.custom_data
    assert custom["site"] == "test track"
    (entry,) = json.loads(custom["bagkit.migrate"])
    assert entry["topics"]["/temperature"]["rules"] == [
        "r.yaml: sensor_msgs/msg/Temperature compute temperature",
        "r.yaml: sensor_msgs/msg/Temperature drop legacy",
    ]
    drift = subprocess.run([BAGKIT, "doctor", str(out), "--against-installed"],
                           capture_output=True, text=True, timeout=60, check=False)  # fmt: skip
    assert drift.returncode == 0, drift.stdout


def test_a_function_rule_and_a_rename(tmp_path: Path) -> None:
    module = tmp_path / "my_migrations.py"
    module.write_text(
        "def temperature(old, new):\n"
        "    new.temperature = old.temp_milli_c / 1000.0\n"
        "    new.variance = float(old.legacy)\n"
    )
    rules = _rules(tmp_path / "r.yaml", "sensor_msgs/msg/Temperature:\n"
                   "  function: my_migrations:temperature\n")  # fmt: skip
    env = {**os.environ, "PYTHONPATH": str(tmp_path)}
    out = tmp_path / "new"
    done = _migrate(str(_old_bag(tmp_path / "old")), "-o", str(out), "--rules", str(rules), env=env)
    assert done.returncode == 0, done.stderr
    temperatures = _messages(out, "/temperature", Temperature)
    assert [m.variance for m in temperatures] == [
        float(old_values(i)["legacy"]) for i in range(COUNT)
    ]


def test_data_loss_is_refused_unless_allowed(tmp_path: Path) -> None:
    old = _old_bag(tmp_path / "old")
    refused = _migrate(str(old), "-o", str(tmp_path / "new"))
    assert refused.returncode == 2
    (line,) = refused.stderr.strip().splitlines()
    assert line.startswith("error: /temperature (sensor_msgs/msg/Temperature):")
    assert "temp_milli_c (int32)" in line and "legacy (int32)" in line and "--allow-drop" in line
    assert not (tmp_path / "new").exists()
    with pytest.raises(DataLossError) as raised:  # the library names its own field
        plan_migrations(old, MigrateOptions())
    assert raised.value.field == "allow_drop" and "--allow-drop" not in str(raised.value)

    allowed = _migrate(str(old), "-o", str(tmp_path / "new"), "--allow-drop")
    assert allowed.returncode == 0, allowed.stderr
    assert "dropped: sensor_msgs/msg/Temperature: legacy (int32)" in allowed.stdout
    assert {m.temperature for m in _messages(tmp_path / "new", "/temperature", Temperature)} == {
        0.0
    }


@pytest.mark.parametrize(
    ("rules", "expected"),
    [
        ("sensor_msgs/msg/Temperature: [unclosed", "r.yaml: not YAML"),
        (
            "sensor_msgs/msg/Temperature:\n  compute:\n    temperature: temp_milli_c / \n",
            "r.yaml: sensor_msgs/msg/Temperature compute temperature: bad",
        ),
        (
            "sensor_msgs/msg/Temperature:\n  rename: {temp_c: temperature}\n  drop: [legacy]\n",
            "r.yaml: sensor_msgs/msg/Temperature rename temp_c -> temperature: stored "
            "sensor_msgs/msg/Temperature has no field 'temp_c'",
        ),
        (
            "sensor_msgs/msg/Temperature:\n  compute: {temperature: tmp / 1000}\n"
            "  drop: [legacy]\n",
            "r.yaml: sensor_msgs/msg/Temperature compute temperature: stored "
            "sensor_msgs/msg/Temperature has no field 'tmp'",
        ),
        (
            "sensor_msgs/msg/Temperature:\n  compute: {temperature: header.frame_id}\n"
            "  drop: [legacy, temp_milli_c]\n",
            "r.yaml: sensor_msgs/msg/Temperature compute temperature: 'thermo' is not a number",
        ),
        (
            RULES + "builtin_interfaces/msg/Time:\n  compute: {sec: sec * 1000000}\n",
            "r.yaml: builtin_interfaces/msg/Time compute sec: 1700000000000000 is outside int32's",
        ),
        (
            RULES + "builtin_interfaces/msg/Time:\n"
            "  compute: {nanosec: 'if(nanosec > 20, nanosec - 100, nanosec)'}\n",
            "r.yaml: builtin_interfaces/msg/Time compute nanosec: -79 is outside uint32's",
        ),
    ],
    ids=["yaml", "expression", "rename", "path", "text", "overflow", "late"],
)
def test_bad_rules_are_one_error_line_and_nothing_written(
    tmp_path: Path, rules: str, expected: str
) -> None:
    old = _old_bag(tmp_path / "old")
    out = tmp_path / "new"
    done = _migrate(str(old), "-o", str(out), "--rules", str(_rules(tmp_path / "r.yaml", rules)))
    assert done.returncode == 2, done.stdout + done.stderr
    (line,) = done.stderr.strip().splitlines()
    assert line.startswith("error: ") and expected in line, line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["old", "r.yaml"]


def test_to_a_package_directory(tmp_path: Path) -> None:
    """--to-package: the .msg files of a source directory, its dependencies installed."""
    package = tmp_path / "src" / "sensor_msgs"
    (package / "msg").mkdir(parents=True)
    (package / "package.xml").write_text("<package><name>sensor_msgs</name></package>\n")
    range_text = message_definition("sensor_msgs/msg/Range").split("\n" + "=" * 80, 1)[0]
    (package / "msg" / "Range.msg").write_text(
        range_text + "\nuint8 QUALITY_MAX=100\nuint8 quality\n"
    )
    bag = tmp_path / "bag"
    with BagWriter(bag) as writer:
        writer.add_topic(TopicInfo("/range", "sensor_msgs/msg/Range"))
        for i in range(3):
            writer.write(
                "/range", bytes(serialize_message(Range(range=float(i)))), log_time=START_NS + i
            )
    done = _migrate(str(bag), "-o", str(tmp_path / "out"), "--to-package", str(package))
    assert done.returncode == 0, done.stderr
    assert "added: quality (uint8)" in done.stdout
    with BagReader(tmp_path / "out") as reader:
        stored = reader.definitions["sensor_msgs/msg/Range"]
        assert "uint8 quality" in stored and reader.topics["/range"].type_description_hash == ""
        types = MessageTypes.for_bag(reader)
        decoded = [types.deserialize(m.data, "sensor_msgs/msg/Range") for m in reader.messages()]
    assert [(m.range, m.quality) for m in decoded] == [(float(i), 0) for i in range(3)]


def test_a_humble_range_becomes_jazzy_s(tmp_path: Path) -> None:
    """The definition rosbags ships for Humble's Range (no ``variance``), as a Humble bag
    stores it: migrated to the installed (Jazzy) Range, every recorded value kept."""
    humble = distro_definitions(["sensor_msgs/msg/Range"], "humble")["sensor_msgs/msg/Range"]
    assert "variance" not in humble
    bag = tmp_path / "humble"
    with BagWriter(bag) as writer:
        writer.add_topic(TopicInfo("/range", "sensor_msgs/msg/Range"), humble)
        for i in range(COUNT):
            jazzy = bytes(serialize_message(Range(range=0.5 * i, min_range=0.1, max_range=9.0)))
            writer.write("/range", jazzy[:-4], log_time=START_NS + i)  # without variance
    done = _migrate(str(bag), "-o", str(tmp_path / "jazzy"))
    assert done.returncode == 0, done.stderr
    assert "added: variance (float32)" in done.stdout
    ranges = _messages(tmp_path / "jazzy", "/range", Range)
    assert [(m.range, m.max_range, m.variance) for m in ranges] == [
        (0.5 * i, float(np.float32(9.0)), 0.0) for i in range(COUNT)
    ]


def test_to_another_bag_s_definitions(tmp_path: Path) -> None:
    """--to-bag: the definitions stored in another bag (here one written with today's)."""
    today = tmp_path / "today"
    with BagWriter(today) as writer:
        writer.add_topic(TopicInfo("/temperature", "sensor_msgs/msg/Temperature"))
    rules = _rules(tmp_path / "r.yaml", RULES)
    out = tmp_path / "new"
    done = _migrate(str(_old_bag(tmp_path / "old")), "-o", str(out), "--to-bag", str(today),
                    "--rules", str(rules))  # fmt: skip
    assert done.returncode == 0, done.stderr
    temperatures = _messages(out, "/temperature", Temperature)
    assert [m.temperature for m in temperatures] == [
        old_values(i)["temp_milli_c"] / 1000 for i in range(COUNT)
    ]
    with BagReader(out) as reader:
        assert reader.metadata is not None
        (entry,) = json.loads(reader.metadata.custom_data["bagkit.migrate"])
    assert entry["target"] == f"the definitions of bag {today}"


def test_a_function_rule_that_fails_is_one_error_line(tmp_path: Path) -> None:
    (tmp_path / "broken_rules.py").write_text("def fix(old, new):\n    return 1 / 0\n")
    rules = _rules(
        tmp_path / "r.yaml", "sensor_msgs/msg/Temperature:\n  function: broken_rules:fix\n"
    )
    env = {**os.environ, "PYTHONPATH": str(tmp_path)}
    done = _migrate(str(_old_bag(tmp_path / "old")), "-o", str(tmp_path / "new"), "--rules",
                    str(rules), env=env)  # fmt: skip
    assert done.returncode == 2
    (line,) = done.stderr.strip().splitlines()
    assert line == (
        "error: r.yaml: sensor_msgs/msg/Temperature function broken_rules:fix: "
        "ZeroDivisionError: division by zero (/temperature message 1)"
    )
    assert not (tmp_path / "new").exists()
