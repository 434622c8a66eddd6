"""``bagkit stats summary`` (in this process, tests/bagkit_runs.py): table, JSON and CSV output;
bad input."""

from __future__ import annotations

import csv
import io
import json
import sqlite3
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from bagkit_runs import bagkit_in_process
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from bagkit.bag import BagWriter, TopicInfo
from bagkit.stats import summarize

TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
T0 = 1_750_000_000_000_000_000


def _run(*args: str | Path) -> subprocess.CompletedProcess[str]:
    """``bagkit stats summary ARGS`` in this process (tests/bagkit_runs.py)."""
    return bagkit_in_process(["stats", "summary", *args])


@pytest.fixture(scope="module")
def temperatures() -> np.ndarray:
    values = np.random.default_rng(7).normal(21.5, 0.3, 400)
    values[[5, 77]] = np.nan
    return values


@pytest.fixture(scope="module")
def bag(tmp_path_factory: pytest.TempPathFactory, temperatures: np.ndarray) -> Path:
    """A bag written by bagkit's writer: /temperature at 2 Hz, /pressure at 1 Hz."""
    path = tmp_path_factory.mktemp("cli") / "drive"
    temperature = TYPESTORE.types["sensor_msgs/msg/Temperature"]
    pressure = TYPESTORE.types["sensor_msgs/msg/FluidPressure"]
    header = TYPESTORE.types["std_msgs/msg/Header"]
    stamp = TYPESTORE.types["builtin_interfaces/msg/Time"]
    with BagWriter(path) as writer:
        writer.add_topic(TopicInfo("/temperature", "sensor_msgs/msg/Temperature"))
        writer.add_topic(TopicInfo("/pressure", "sensor_msgs/msg/FluidPressure"))
        for i, value in enumerate(temperatures):
            t = T0 + i * 500_000_000
            msg = temperature(
                header=header(stamp=stamp(sec=t // 10**9, nanosec=t % 10**9), frame_id="thermo"),
                temperature=float(value),
                variance=0.0,
            )
            writer.write(
                "/temperature", bytes(TYPESTORE.serialize_cdr(msg, msg.__msgtype__)), log_time=t
            )
            if i % 2 == 0:
                msg = pressure(
                    header=header(stamp=stamp(sec=t // 10**9, nanosec=0), frame_id="baro"),
                    fluid_pressure=101325.0 - i,
                    variance=4.0,
                )
                writer.write(
                    "/pressure",
                    bytes(TYPESTORE.serialize_cdr(msg, msg.__msgtype__)),
                    log_time=t + 1000,
                )
    return path


def test_json_output_is_the_library_result(bag: Path, temperatures: np.ndarray) -> None:
    proc = _run(bag, "--format", "json")
    assert proc.returncode == 0, proc.stderr
    document = json.loads(proc.stdout)
    assert document == json.loads(json.dumps(summarize([bag]).to_dict()))
    topics = {t["topic"]: t for t in document["topics"]}
    assert topics["/temperature"]["count"] == len(temperatures)
    assert topics["/temperature"]["rate_hz"] == pytest.approx(2.0)
    assert topics["/pressure"]["rate_hz"] == pytest.approx(1.0)
    fields = {f["field"]: f for f in topics["/temperature"]["fields"]}
    value = fields["temperature"]
    assert value["nan_count"] == 2
    assert value["mean"] == pytest.approx(np.nanmean(temperatures), rel=1e-9)
    assert value["std"] == pytest.approx(np.nanstd(temperatures, ddof=1), rel=1e-9)
    assert "header.frame_id" not in fields  # strings are not numeric


def test_csv_output_has_a_row_per_field(bag: Path) -> None:
    proc = _run(bag, "--format", "csv", "--topics", "/pressure")
    assert proc.returncode == 0, proc.stderr
    rows = list(csv.DictReader(io.StringIO(proc.stdout)))
    assert [r["field"] for r in rows] == [
        "header.stamp.sec",
        "header.stamp.nanosec",
        "fluid_pressure",
        "variance",
    ]
    pressure = next(r for r in rows if r["field"] == "fluid_pressure")
    assert pressure["topic"] == "/pressure" and int(pressure["topic_count"]) == 200
    assert float(pressure["max"]) == 101325.0 and float(pressure["min"]) == 101325.0 - 398


def test_table_output_and_window(bag: Path, temperatures: np.ndarray) -> None:
    proc = _run(bag, "--start", "10", "--end", "20", "--fields", "temperature")
    assert proc.returncode == 0, proc.stderr
    assert "/temperature" in proc.stdout and "temperature" in proc.stdout
    assert "/pressure" not in proc.stdout  # no field of /pressure matches
    document = json.loads(
        _run(bag, "--start", "10", "--end", "20", "--format", "json", "-f", "temperature").stdout
    )
    (topic,) = document["topics"]
    window = temperatures[20:40]  # 2 Hz: [10 s, 20 s) after the first message
    assert topic["count"] == 20
    assert topic["fields"][0]["mean"] == pytest.approx(np.nanmean(window), rel=1e-9)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["/definitely/not/here"], "no such file"),
        (["--topics", "/nope"], "/nope"),
        (["--start", "nan"], "bad --start 'nan': not a time"),
        (["--end", "1e300"], "bad --end '1e300': beyond int64"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(bag: Path, args: list[str], message: str) -> None:
    full = args if args[0].startswith("/") else [str(bag), *args]
    proc = _run(*full)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:") and message in lines[0]
    assert "Traceback" not in proc.stderr


def test_not_a_bag(tmp_path: Path) -> None:
    junk = tmp_path / "junk.mcap"
    junk.write_text("hello")
    proc = _run(junk)
    assert proc.returncode == 2 and proc.stderr.startswith("error:")


def test_undecodable_topics_are_named(interop_dir: Path) -> None:
    wrong = _run(interop_dir / "rosbag2_tests/resources/mcap/wrong_rmw_test")
    assert wrong.returncode == 2
    assert "wrong_format" in wrong.stderr and len(wrong.stderr.strip().splitlines()) == 1


def _rosbags_service_events(db3: Path, topic: str) -> list[Any]:
    """The events of ``topic`` decoded by rosbags from the ``.srv`` text the file stores, the
    event type written out as rosidl generates it (rosbags cannot read the ``.srv`` itself)."""
    db = sqlite3.connect(f"file:{db3}?mode=ro&immutable=1", uri=True)
    ((srv,),) = db.execute(
        "SELECT encoded_message_definition FROM message_definitions "
        "WHERE topic_type = 'test_msgs/srv/BasicTypes'"
    )
    request, response = srv.split("---")
    store = get_typestore(Stores.ROS2_JAZZY)
    event = (
        "service_msgs/ServiceEventInfo info\n"
        "test_msgs/BasicTypes_Request[<=1] request\ntest_msgs/BasicTypes_Response[<=1] response\n"
    )
    types: dict[str, Any] = {}
    for name, text in (("Request", request), ("Response", response), ("Event", event)):
        types.update(get_types_from_msg(text, f"test_msgs/msg/BasicTypes_{name}"))
    store.register(types)
    rows = db.execute(
        "SELECT data FROM messages JOIN topics ON topics.id = topic_id WHERE name = ? "
        "ORDER BY timestamp",
        (topic,),
    )
    events = [store.deserialize_cdr(data, "test_msgs/msg/BasicTypes_Event") for (data,) in rows]
    db.close()
    return events


def test_sqlite3_service_events_decode(interop_dir: Path) -> None:
    """rosbag2's db3 stores the .srv text under pkg/srv/Name, not under the event type."""
    bag = interop_dir / "rosbag2_tests/resources/sqlite3/bag_with_topics_and_service_events"
    proc = _run(bag, "--format", "json")
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr
    topics = {t["topic"]: t for t in json.loads(proc.stdout)["topics"]}
    topic = "/test_service1/_service_event"
    events = _rosbags_service_events(bag / "bag_with_topics_and_service_events.db3", topic)
    fields = {f["field"]: f for f in topics[topic]["fields"]}
    for field, values in (
        ("info.stamp.nanosec", [e.info.stamp.nanosec for e in events]),
        ("info.sequence_number", [e.info.sequence_number for e in events]),
    ):
        assert fields[field]["count"] == len(events) == topics[topic]["count"]
        assert (fields[field]["min"], fields[field]["max"]) == (min(values), max(values))


def test_json_is_strict_with_infinite_values(tmp_path: Path) -> None:
    """JSON has no inf/NaN literals: they are written as strings, the document stays strict."""
    path = tmp_path / "inf"
    temperature = TYPESTORE.types["sensor_msgs/msg/Temperature"]
    header = TYPESTORE.types["std_msgs/msg/Header"]
    stamp = TYPESTORE.types["builtin_interfaces/msg/Time"]
    with BagWriter(path) as writer:
        writer.add_topic(TopicInfo("/temperature", "sensor_msgs/msg/Temperature"))
        for i, variance in enumerate([0.5, float("inf"), 0.25]):
            msg = temperature(
                header=header(stamp=stamp(sec=i, nanosec=0), frame_id="t"),
                temperature=20.0 + i,
                variance=variance,
            )
            writer.write(
                "/temperature",
                bytes(TYPESTORE.serialize_cdr(msg, msg.__msgtype__)),
                log_time=T0 + i * 10**9,
            )
    proc = _run(path, "--format", "json", "-f", "variance")
    assert proc.returncode == 0, proc.stderr

    def reject(constant: str) -> None:
        raise AssertionError(f"non-standard JSON constant {constant}")

    document = json.loads(proc.stdout, parse_constant=reject)
    (field,) = document["topics"][0]["fields"]
    assert (field["count"], field["min"], field["max"]) == (3, 0.25, "inf")
    assert (field["mean"], field["std"]) == ("inf", "NaN")


def test_a_topic_none_of_whose_messages_decode_is_an_error(tmp_path: Path) -> None:
    """Its stored definition wants more bytes than each payload has: the other topic is
    summarized, and one error line says the first decodes nothing (exit 2, as echo)."""
    with BagWriter(tmp_path / "bag") as bag:
        bag.add_topic(
            TopicInfo("/r", "my_msgs/msg/Reading"), definition="float64 value\nuint32 n\n"
        )
        bag.add_topic(TopicInfo("/ok", "my_msgs/msg/Value"), definition="float64 value\n")
        payload = b"\x00\x01\x00\x00" + np.float64(2.5).tobytes()  # CDR header, one float64
        for i in range(5):
            bag.write("/r", payload, log_time=T0 + i)
            bag.write("/ok", payload, log_time=T0 + i)
    done = _run(tmp_path / "bag", "--format", "json")
    assert done.returncode == 2, done.stderr
    assert done.stderr.strip().splitlines()[-1] == "error: none of the 5 messages of /r decode"
    (ok,) = [t for t in json.loads(done.stdout)["topics"] if t["topic"] == "/ok"]
    assert ok["fields"][0]["mean"] == 2.5
    # The table: /r's heading, no field table of zero counts under it (nothing to summarize).
    table = _run(tmp_path / "bag").stdout.splitlines()
    heading = next(i for i, line in enumerate(table) if line.startswith("/r "))
    assert "5 msgs" in table[heading]
    block = table[heading : table.index("", heading) if "" in table[heading:] else None]
    assert block == [table[heading]]
    assert sum(line.lstrip().startswith("field") for line in table) == 1  # /ok's
