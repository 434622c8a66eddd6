"""``bagkit check --spec``: fusion's faults bag breaks the contract its nominal bag keeps."""

from __future__ import annotations

import json
import shlex
import shutil
import subprocess
from pathlib import Path

import pytest
from bagkit_runs import bagkit_in_process

from bagkit.bag import BagReader
from bagkit.health import HealthSpec, SpecError, check_bag

FIXTURES = Path(__file__).parents[2] / "fixtures"
CONTRACT = """\
forbidden: [/debug]
topics:
  /imu/data:
    type: sensor_msgs/msg/Imu
    rate: {min: 8, over: 2s}
    max_gap: 300ms
    never:
      - isnan(*)
      - unchanged(linear_acceleration) for 1s
  /gps/fix:
    max_gap: 1500ms
    never: [isnan(*)]
  /temperature:
    values:
      temperature: {min: -40, max: 50}
"""


def bagkit(*args: str | Path) -> subprocess.CompletedProcess[str]:
    """``bagkit ARGS`` in this process (tests/bagkit_runs.py)."""
    return bagkit_in_process(list(args))


@pytest.fixture
def spec(tmp_path: Path) -> Path:
    path = tmp_path / "health.yaml"
    path.write_text(CONTRACT)
    return path


def test_the_faults_bag_breaks_what_its_faults_break(spec: Path) -> None:
    report = check_bag(FIXTURES / "faults" / "golden", HealthSpec.load(spec))
    broken = [(a.topic, a.what) for a in report.assertions if not a.passed]
    # fusion/faults.py: imu_stuck, gps_loss, temperature_spike (+60 C); the pressure spike is
    # not in this contract, and no sensor falls silent.
    assert broken == [
        ("/imu/data", "unchanged(linear_acceleration) for 1s"),
        ("/gps/fix", "isnan(*)"),
        ("/temperature", "temperature < -40 or temperature > 50"),
    ]
    assert len(report.assertions) == 12 and report.exit_code == 1


def test_cli_exit_codes_and_json(spec: Path) -> None:
    nominal = bagkit("check", FIXTURES / "nominal" / "golden", "--spec", spec)
    assert nominal.returncode == 0, nominal.stdout + nominal.stderr
    assert "healthy" in nominal.stdout
    faults = bagkit("check", FIXTURES / "faults" / "golden", "--spec", spec, "--format", "json")
    assert faults.returncode == 1, faults.stderr
    (report,) = json.loads(faults.stdout)
    gps = [a for a in report["assertions"] if a["assertion"] == "isnan(*)" and not a["passed"]]
    (episode,) = gps[0]["episodes"]
    assert episode["count"] == 3  # gps_loss@12+4 at 1 Hz (see test_fusion_fault_conditions)
    assert gps[0]["commands"][1].startswith("bagkit filter ")


def test_hints_fit_80_columns_and_paste_back_as_the_commands_meant(spec: Path) -> None:
    faults = FIXTURES / "faults" / "golden"
    text = bagkit_in_process(["check", faults, "--spec", spec], env={"COLUMNS": "80"})
    assert text.returncode == 1, text.stderr
    lines = text.stdout.splitlines()
    assert max(map(len, lines)) <= 80, text.stdout
    as_json = bagkit("check", faults, "--spec", spec, "--format", "json")
    (report,) = json.loads(as_json.stdout)
    meant = [a["commands"] for a in report["assertions"] if not a["passed"]]
    # What a shell reads: a backslash before a line break joins the lines.
    shell = "\n".join(line.strip() for line in lines).replace("\\\n", "")
    printed = [shlex.split(line) for line in shell.splitlines() if line.startswith("bagkit ")]
    assert printed == [shlex.split(command) for commands in meant for command in commands]
    assert any(line.endswith(" \\") for line in lines)  # a filter command went on


def test_a_missing_topic_breaks_the_contract(tmp_path: Path) -> None:
    spec = tmp_path / "health.yaml"
    spec.write_text("topics:\n  /lidar/points: {max_gap: 1s}\n")
    result = bagkit("check", FIXTURES / "nominal" / "golden", "--spec", spec)
    assert result.returncode == 1
    assert "FAIL /lidar/points: present (not in the bag)" in result.stdout


@pytest.mark.parametrize(
    ("text", "line", "words"),
    [
        ("topics:\n  /imu/data:\n    max_gapp: 1s\n", 3, "did you mean max_gap"),
        ("topics:\n  /imu/data:\n    max_gap: 5 Hz\n", 3, "not a duration"),
        ("topics:\n  /imu/data:\n    never: [frozen(x) for 1s]\n", 3, "unknown function"),
        # A condition of a block list: the line of its item, not of never:.
        ("topics:\n  /imu/data:\n    never:\n      - isnan(*)\n      - gap > 5 Hz\n", 5, "Hz"),
        ("topics:\n  /imu/data:\n    rate: {over: 2s}\n", 3, "neither min nor max"),
        ("topics:\n  /imu/data:\n    values:\n      linear_acceleration.z: {}\n", 4, "neither"),
        ("topics:\n  /imu/data:\n    rate: {min: fast}\n", 3, "not a number"),
        ("topics: [a\n", 2, "not YAML"),  # where the parser saw the list unclosed
        # Contracts nothing breaks or nothing keeps: a rate over no window, bounds crossed.
        ("topics:\n  /imu/data:\n    rate: {min: 90, over: 0s}\n", 3, "longer than 0"),
        ("topics:\n  /imu/data:\n    never: ['rate < 5 Hz over 0ms']\n", 3, "longer than 0"),
        # A window beyond int64 ns overflowed numpy's time columns (exit 70).
        ("topics:\n  /imu/data:\n    rate: {min: 5, over: 99999999999999999999s}\n", 3, "int64"),
        ("topics:\n  /imu/data:\n    never: ['rate < 5 Hz over 9999999999s']\n", 3, "duration"),
        (
            "topics:\n  /imu/data:\n    values:\n      linear_acceleration.z: {min: 20, max: 1}\n",
            4,
            "min 20 is above max 1",
        ),
    ],
)
def test_a_bad_spec_is_one_error_naming_its_line(
    tmp_path: Path, text: str, line: int, words: str
) -> None:
    spec = tmp_path / "health.yaml"
    spec.write_text(text)
    with pytest.raises(SpecError, match=words):
        HealthSpec.load(spec)
    result = bagkit("check", FIXTURES / "nominal" / "golden", "--spec", spec)
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:"), lines
    assert f"health.yaml:{line}" in lines[0] and words in lines[0]


def test_a_spec_that_is_not_utf8_is_one_error(tmp_path: Path) -> None:
    spec = tmp_path / "health.yaml"
    spec.write_bytes(b"topics:\n  /x\xff: {}\n")  # was UnicodeDecodeError, exit 70
    result = bagkit("check", FIXTURES / "nominal" / "golden", "--spec", spec)
    assert result.returncode == 2
    assert result.stderr.strip().splitlines() == [f"error: {spec}: not UTF-8 (byte 12)"]


def test_a_field_the_type_lacks_is_a_bad_spec(tmp_path: Path) -> None:
    spec = tmp_path / "health.yaml"
    spec.write_text("topics:\n  /imu/data:\n    values:\n      linear_accel.z: {max: 5}\n")
    result = bagkit("check", FIXTURES / "nominal" / "golden", "--spec", spec)
    assert result.returncode == 2
    assert result.stderr.startswith("error:") and "linear_acceleration" in result.stderr


def test_a_field_the_type_lacks_names_the_line_of_its_condition(tmp_path: Path) -> None:
    spec = tmp_path / "health.yaml"
    spec.write_text("topics:\n  /imu/data:\n    never:\n      - isnan(*)\n      - foo.bar > 3\n")
    result = bagkit("check", FIXTURES / "nominal" / "golden", "--spec", spec)
    assert result.returncode == 2
    assert result.stderr.startswith("error: ")
    assert "health.yaml:5: /imu/data: foo.bar" in result.stderr


@pytest.mark.parametrize(
    "condition", ["status[*].name < 0", "status[*].level > 9 or status[*].name < 0"]
)
def test_a_comparison_the_values_do_not_take_names_its_condition_once(
    tmp_path: Path, condition: str
) -> None:
    """A text field compared with a number: the failing comparison named once, after the
    whole condition when that holds more."""
    spec = tmp_path / "health.yaml"
    spec.write_text(f'topics:\n  /alerts:\n    never: ["{condition}"]\n')
    result = bagkit("check", FIXTURES / "nominal" / "golden", "--spec", spec)
    assert result.returncode == 2
    (line,) = result.stderr.strip().splitlines()
    assert line.startswith("error:") and "health.yaml:3: /alerts: " in line
    failed = "status[*].name < 0: cannot compare str with int"
    said = failed if condition.startswith("status[*].name") else f"{condition}: {failed}"
    assert line.endswith(f"health.yaml:3: /alerts: {said} (/alerts)"), line


def test_a_bulk_condition_beside_one_that_reads_sequences(tmp_path: Path) -> None:
    # /alerts' isnan(*) reads status[] (no bulk columns); its value bound reads one column in
    # bulk. Each is evaluated on its own, so the columns read must serve each on its own.
    spec = tmp_path / "health.yaml"
    spec.write_text(
        "topics:\n  /alerts:\n    values: {header.stamp.sec: {max: 1}}\n    never: [isnan(*)]\n"
    )
    bag = FIXTURES / "nominal" / "golden"
    report = check_bag(bag, HealthSpec.load(spec))
    outcome = {a.what: a for a in report.assertions}
    assert outcome["isnan(*)"].passed
    (spans,) = [a.spans for what, a in outcome.items() if what.startswith("header.stamp.sec")]
    with BagReader(bag) as reader:  # every alert is stamped after 1970-01-01T00:00:01
        times = [record.log_time for record in reader.messages(topics=["/alerts"])]
        end = reader.end_ns  # /alerts is latched: its last status holds to the end
    assert spans.tolist() == [[times[0], end, len(times)]]


def _relative_topic_bag(path: Path) -> Path:
    """A bag rosbags writes with the relative topic name ``temp`` (as rosbag2's test bags
    store ``topic1``), 10 Hz for 3 s with no message from 1.0 to 2.0 s."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    kind = "sensor_msgs/msg/Temperature"
    t = store.types
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        connection = writer.add_connection("temp", kind, typestore=store)
        for i in [*range(11), *range(20, 31)]:
            ns = 1_700_000_000_000_000_000 + i * 100_000_000
            stamp = t["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9)
            header = t["std_msgs/msg/Header"](stamp=stamp, frame_id="t")
            message = t[kind](header=header, temperature=20.0 + i, variance=0.0)
            writer.write(connection, ns, store.serialize_cdr(message, kind))
    return path


def test_a_relative_topic_name_of_the_bag_is_the_contract_s_absolute_one(tmp_path: Path) -> None:
    """A bag holding ``temp`` keeps a contract on ``/temp`` (topic names are absolute in every
    command), its gap found, and the contract --suggest wrote from it."""
    bag = _relative_topic_bag(tmp_path / "relative")
    spec = tmp_path / "health.yaml"
    spec.write_text("topics:\n  /temp:\n    max_gap: 500ms\n    never: [temperature > 40]\n")
    result = bagkit("check", str(bag), "--spec", str(spec), "--format", "json")
    assert result.returncode == 1, result.stderr
    verdicts = {
        a["assertion"]: [(e["start_s"], e["end_s"]) for e in a["episodes"]]
        for a in json.loads(result.stdout)[0]["assertions"]
    }
    assert verdicts == {
        "present": [],
        "gap > 500ms": [(1.0, 2.0)],
        "temperature > 40": [(2.1, 3.0)],
    }
    suggested = bagkit("check", str(bag), "--suggest")
    assert suggested.returncode == 0, suggested.stderr
    spec.write_text(suggested.stdout)
    assert bagkit("check", str(bag), "--spec", str(spec)).returncode == 0


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_messages_that_do_not_decode_are_no_gap(tmp_path: Path, storage: str) -> None:
    """A gap or rate is of the messages' times, decoded or not: a contract that also reads a
    field (which decodes the topic) must not see a silence where messages did not decode
    (rosbag2's talker.db3, read with Jazzy's Log: one gap over the whole bag)."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store, kind = get_typestore(Stores.ROS2_JAZZY), "sensor_msgs/msg/Temperature"
    t = store.types
    bag = tmp_path / "cut"
    with Writer(bag, version=9, storage_plugin=StoragePlugin[storage.upper()]) as writer:
        connection = writer.add_connection("/temp", kind, typestore=store)
        for i in range(30):  # 10 Hz; from 1.0 to 2.0 s payloads cut short
            ns = 1_700_000_000_000_000_000 + i * 100_000_000
            stamp = t["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9)
            header = t["std_msgs/msg/Header"](stamp=stamp, frame_id="t")
            data = store.serialize_cdr(t[kind](header=header, temperature=20.0, variance=0.0), kind)
            writer.write(connection, ns, data[:10] if 10 <= i < 20 else data)
    spec = tmp_path / "health.yaml"
    spec.write_text(
        "topics:\n  /temp:\n    max_gap: 500ms\n    rate: {min: 5, over: 1s}\n"
        "    never: [temperature > 100, gap > 150ms]\n"
    )
    result = bagkit("check", str(bag), "--spec", str(spec), "--format", "json")
    assert result.returncode == 0, result.stdout
    (report,) = json.loads(result.stdout)
    assert all(a["passed"] for a in report["assertions"]), report
    assert "/temp: 10 messages could not be decoded" in result.stderr


def test_gap_and_rate_need_no_definition_and_fields_need_cdr(
    interop_dir: Path, tmp_path: Path
) -> None:
    """rosbag2's test bags: a gap or rate of a topic whose type the bag does not define is
    read from the messages' times alone; a field of a topic stored in another serialization
    format than CDR is refused as echo refuses it (it was decoded as CDR all the same)."""
    undefined = tmp_path / "convert_a"  # copied: its .db3 would gain -shm/-wal files
    shutil.copytree(interop_dir / "rosbag2_py/test/resources/sqlite3/convert_a", undefined)
    spec = tmp_path / "health.yaml"
    spec.write_text(
        "topics:\n  b_basictypes:\n    max_gap: 10ms\n    rate: {min: 1000, over: 0.05s}\n"
    )
    result = bagkit("check", undefined, "--spec", spec, "--format", "json")
    assert result.returncode == 1, result.stderr
    verdicts = {a["assertion"]: a["passed"] for a in json.loads(result.stdout)[0]["assertions"]}
    # 50 messages over 0.1 s, in bursts: no silence over 10 ms, no 0.05 s of 50 messages.
    assert verdicts == {"present": True, "gap > 10ms": True, "rate < 1000 Hz over 0.05s": False}
    wrong = interop_dir / "rosbag2_tests/resources/mcap/wrong_rmw_test"
    spec.write_text("topics:\n  /array_topic:\n    never: ['bool_values[*] == true']\n")
    result = bagkit("check", wrong, "--spec", spec)
    assert result.returncode == 2
    assert "serialization format 'wrong_format' is not CDR" in result.stderr
    when = "/array_topic: bool_values[*] == true"  # find's per-message matcher alike
    result = bagkit("find", wrong, "--when", when)
    assert result.returncode == 2
    assert "serialization format 'wrong_format' is not CDR" in result.stderr


def test_suggest_asks_no_nan_of_a_topic_none_of_whose_messages_decode(
    interop_dir: Path, tmp_path: Path
) -> None:
    """rosbag2's talker.db3 read with Jazzy's Log: /rosout decodes not at all, so nothing was
    seen of its values and ``isnan(*)`` would assert nothing; /topic's timing is still kept."""
    bag = tmp_path / "talker"  # copied: its .db3 would gain -shm/-wal files
    shutil.copytree(interop_dir / "rosbag2_py/test/resources/sqlite3/talker", bag)
    result = bagkit("check", bag, "--suggest", "--format", "json")
    assert result.returncode == 0, result.stderr
    topics = json.loads(result.stdout)["topics"]
    assert "never" not in topics["/rosout"]
    assert set(topics["/rosout"]) == {"type", "max_gap"}


def test_a_latency_source_a_bag_lacks_breaks_that_bag_s_assertion(tmp_path: Path) -> None:
    """A fleet where one bag has no /imu/data at all: its latency assertion is broken (the
    source is not in the bag), the other bags are still checked; it was one spec error that
    stopped the whole check."""
    faults = FIXTURES / "faults" / "golden"
    without = tmp_path / "without_imu"
    done = bagkit("filter", faults, "-o", without, "--exclude-topics", "/imu/data")
    assert done.returncode == 0, done.stderr
    spec = tmp_path / "health.yaml"
    latency = "latency(/imu/data -> /fusion/odometry, header.stamp) > 1s"
    spec.write_text(f"topics:\n  /fusion/odometry:\n    never: [isnan(*), '{latency}']\n")
    result = bagkit("check", faults, without, "--spec", spec, "--format", "json", "--workers", "0")
    assert result.returncode == 1, result.stderr
    whole, cut = json.loads(result.stdout)
    assert whole["passed"] and not cut["passed"]
    verdicts = {a["assertion"]: (a["passed"], a["reason"]) for a in cut["assertions"]}
    assert verdicts == {
        "present": (True, ""),
        "isnan(*)": (True, ""),
        latency: (False, "/imu/data not in the bag"),
    }
