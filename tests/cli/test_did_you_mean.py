"""A misspelt topic, field, service or time is the same answer from every command.

One ``error:`` line naming what was typed and the closest names the bag has, exit 2, nothing on
stdout. The guesses expected are the bag's own names, read with the bag reader and the
decoder's leaf paths, not written out here. A window outside the bag is the one warning and an
empty result where a result can be empty, the same line as an error where it cannot (golden
add, play). The commands run in this process (tests/bagkit_runs.py); ``play`` (which loads
rclpy), echo's error and its warning run as subprocesses, as a shell sees them. ``record``
needs a ROS graph: its missing topic is tests/ros' (the wording, selection's
``missing_on_graph``, is tested in tests/selection/test_query.py).
"""

from __future__ import annotations

import difflib
import json
import subprocess
from collections.abc import Callable
from pathlib import Path

import pytest
from bagkit_runs import bagkit_in_process, bagkit_subprocess

from bagkit.bag import BagReader
from bagkit.decode import MessageTypes, leaf_fields
from bagkit.selection.times import format_ns

BAG = Path(__file__).resolve().parents[2] / "fixtures" / "faults" / "golden"
SERVICES = "rosbag2_tests/resources/mcap/bag_with_topics_and_service_events"

# Each case: the command line (given the bag and a scratch directory), what was misspelt,
# and the name the error must guess (a topic of the bag, or a field of /imu/data).
Args = Callable[[Path, Path], list[str | Path]]
TOPIC_CASES: dict[str, Args] = {
    "echo": lambda b, t: ["echo", b, "/imu/dat"],
    "export": lambda b, t: ["export", b, "-t", "/imu/dat", "-o", t / "x.csv"],
    "stats": lambda b, t: ["stats", "summary", b, "-t", "/imu/dat"],
    "filter": lambda b, t: ["filter", b, "-o", t / "f", "--topics", "/imu/dat"],
    "filter --around": lambda b, t: ["filter", b, "-o", t / "f", "--around", "/imu/dat: x > 1"],
    "plot": lambda b, t: ["plot", b, "/imu/dat:header.stamp.sec", "-o", t / "p.png"],
    "compare": lambda b, t: ["compare", b, b, "-t", "/imu/dat"],
    "compare --ignore-fields": lambda b, t: ["compare", b, b, "--ignore-fields", "/imu/dat:x"],
    "find": lambda b, t: ["find", b, "--when", "/imu/dat: linear_acceleration.z > 12"],
    "golden add": lambda b, t: [
        "golden",
        "add",
        t / "fx",
        "--from",
        b,
        "--around",
        "/imu/dat: x > 1",
    ],
    "merge --latched-topics": lambda b, t: [
        "merge",
        b,
        b,
        "-o",
        t / "m",
        "--latched-topics",
        "/imu/dat",
    ],
    "play --topics": lambda b, t: ["play", b, "--topics", "/imu/dat", "--no-wait-for-subscribers"],
    "play --topics (beside a known one)": lambda b, t: [
        *("play", b, "--topics", "/gps/fix", "/imu/dat", "--no-wait-for-subscribers")
    ],
}
FIELD_CASES: dict[str, Args] = {
    "echo --fields": lambda b, t: ["echo", b, "/imu/data", "-f", "linear_accel.z"],
    "echo --where": lambda b, t: ["echo", b, "/imu/data", "--where", "linear_accel.z > 1"],
    "export --fields": lambda b, t: [
        *("export", b, "-t", "/imu/data", "-f", "linear_accel.z", "-o", t / "x.csv")
    ],
    "stats -t -f": lambda b, t: ["stats", "summary", b, "-t", "/imu/data", "-f", "linear_accel.z"],
    "stats -f": lambda b, t: ["stats", "summary", b, "-f", "linear_accel.z"],
    "plot": lambda b, t: ["plot", b, "/imu/data:linear_accel.z", "-o", t / "p.png"],
    "compare --ignore-fields": lambda b, t: [
        *("compare", b, b, "--ignore-fields", "/imu/data:linear_accel.z")
    ],
    "find": lambda b, t: ["find", b, "--when", "/imu/data: linear_accel.z > 12"],
    "filter --where": lambda b, t: [
        *("filter", b, "-o", t / "f", "--topics", "/imu/data", "--where", "linear_accel.z > 1")
    ],
    "filter --around": lambda b, t: [
        *("filter", b, "-o", t / "f", "--around", "/imu/data: linear_accel.z > 1")
    ],
    "golden add --around": lambda b, t: [
        *("golden", "add", t / "fx", "--from", b, "--around", "/imu/data: linear_accel.z > 1")
    ],
    "check": lambda b, t: ["check", b, "--spec", _spec(t, "/imu/data", "linear_accel.z")],
}
TIME_CASES: dict[str, Args] = {
    "echo": lambda b, t: ["echo", b, "/imu/data", "--start", "1O"],
    "stats": lambda b, t: ["stats", "summary", b, "--end", "1O"],
    "filter": lambda b, t: ["filter", b, "-o", t / "f", "--start", "1O"],
    "find": lambda b, t: ["find", b, "--when", "/imu/data: header.stamp.sec > 0", "--start", "1O"],
    "export": lambda b, t: ["export", b, "-o", t / "x.csv", "-t", "/imu/data", "--start", "1O"],
    "golden add": lambda b, t: ["golden", "add", t / "fx", "--from", b, "--start", "1O"],
}


# A window after the bag's end: the one warning and an empty result, or the same line as an
# error where an empty result would mislead (a fixture of latched messages, a replay of none).
OUTSIDE = ("--start", "1000", "--end", "1010")
WINDOW_WARNS: dict[str, Args] = {
    "echo": lambda b, t: ["echo", b, "/imu/data", *OUTSIDE],
    "export": lambda b, t: ["export", b, "-t", "/imu/data", "-o", t / "x.csv", *OUTSIDE],
    "plot": lambda b, t: [
        "plot",
        b,
        "/imu/data:linear_acceleration.z",
        "-o",
        t / "p.png",
        *OUTSIDE,
    ],
    "stats": lambda b, t: ["stats", "summary", b, *OUTSIDE],
    "filter": lambda b, t: ["filter", b, "-o", t / "f", *OUTSIDE],
    "merge": lambda b, t: ["merge", b, b, "-o", t / "m", *OUTSIDE],
    "find": lambda b, t: ["find", b, "--when", "/imu/data: linear_acceleration.z > 0", *OUTSIDE],
}
WINDOW_FAILS: dict[str, Args] = {
    "golden add": lambda b, t: ["golden", "add", t / "fx", "--from", b, *OUTSIDE],
    "play": lambda b, t: ["play", b, "--start-offset", "1000", "--no-wait-for-subscribers"],
    "play --playback-until-nsec": lambda b, t: [
        *("play", b, "--playback-until-nsec", "1000", "--no-wait-for-subscribers")
    ],
}
# A service by its name, misspelt (the interop bag of rosbag2's tests, recorded services).
SERVICE_CASES: dict[str, Args] = {
    "echo": lambda b, t: ["echo", b, "/test_servce1"],
    "export": lambda b, t: ["export", b, "-t", "/test_servce1", "-o", t / "x.csv"],
    "stats": lambda b, t: ["stats", "summary", b, "-t", "/test_servce1"],
    "plot": lambda b, t: ["plot", b, "/test_servce1:request", "-o", t / "p.png"],
    "filter": lambda b, t: ["filter", b, "-o", t / "f", "--topics", "/test_servce1"],
    "merge": lambda b, t: ["merge", b, b, "-o", t / "m", "--latched-topics", "/test_servce1"],
    "find": lambda b, t: ["find", b, "--when", "/test_servce1: x > 1"],
    "compare": lambda b, t: ["compare", b, b, "-t", "/test_servce1"],
    "golden add": lambda b, t: [
        "golden",
        "add",
        t / "fx",
        "--from",
        b,
        "--around",
        "/test_servce1: x > 1",
    ],
    "play": lambda b, t: ["play", b, "--topics", "/test_servce1", "--no-wait-for-subscribers"],
}


def _spec(directory: Path, topic: str, field: str) -> Path:
    """A health contract bounding ``field`` of ``topic`` (bagkit check's spec)."""
    spec = directory / "health.yaml"
    spec.write_text(f"topics:\n  {topic}:\n    values:\n      {field}: {{min: 0, max: 20}}\n")
    return spec


# The cases run as a user's shell runs them: the one error line, exit 2 and the empty stdout
# across the process boundary.
IN_SUBPROCESS = ("play", "echo")


def _bagkit(args: list[str | Path], cwd: Path, case: str = "") -> subprocess.CompletedProcess[str]:
    """``bagkit ARGS``: in a subprocess for ``play`` (it loads rclpy) and for ``case`` in
    IN_SUBPROCESS, in this process otherwise."""
    if args[0] == "play" or case in IN_SUBPROCESS:
        return bagkit_subprocess(args, cwd)
    return bagkit_in_process(args, cwd)


def _error_line(args: list[str | Path], cwd: Path, case: str = "") -> str:
    result = _bagkit(args, cwd, case)
    assert result.returncode == 2, result.stderr
    assert result.stdout == ""
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), result.stderr
    return lines[0]


def _close_to(wrong: str, names: list[str]) -> str:
    """The one name of ``names`` that ``wrong`` is a misspelling of (checked, not assumed)."""
    (best,) = difflib.get_close_matches(wrong, names, n=1, cutoff=0.8)
    return best


@pytest.mark.parametrize("command", TOPIC_CASES)
def test_a_misspelt_topic_names_the_closest_topic(command: str, tmp_path: Path) -> None:
    with BagReader(BAG) as reader:
        expected = _close_to("/imu/dat", list(reader.topics))
    line = _error_line(TOPIC_CASES[command](BAG, tmp_path), tmp_path, command)
    assert "/imu/dat " in line and f"did you mean {expected}?" in line
    assert not (tmp_path / "fx").exists()  # golden add leaves nothing behind
    assert not (tmp_path / "m").exists()  # nor merge


@pytest.mark.parametrize("command", FIELD_CASES)
def test_a_misspelt_field_names_the_closest_field(command: str, tmp_path: Path) -> None:
    with BagReader(BAG) as reader:
        types = MessageTypes.from_definitions(reader.definitions)
        imu_type = types.resolve(reader.topics["/imu/data"].type)
    paths = [leaf.path for leaf in leaf_fields(types.typestore, imu_type)]
    expected = _close_to("linear_accel.z", paths)
    line = _error_line(FIELD_CASES[command](BAG, tmp_path), tmp_path)
    assert "linear_accel.z" in line and f"did you mean {expected}" in line


@pytest.mark.parametrize("command", TIME_CASES)
def test_a_misspelt_time_names_the_grammar(command: str, tmp_path: Path) -> None:
    line = _error_line(TIME_CASES[command](BAG, tmp_path), tmp_path)
    assert "'1O': not a time (" in line
    assert not (tmp_path / "fx").exists()


@pytest.mark.parametrize("command", SERVICE_CASES)
def test_a_misspelt_service_names_the_service(
    command: str, interop_dir: Path, tmp_path: Path
) -> None:
    bag = interop_dir / SERVICES
    with BagReader(bag) as reader:
        services = [t.removesuffix("/_service_event") for t in reader.topics if "_service" in t]
    expected = _close_to("/test_servce1", services)
    line = _error_line(SERVICE_CASES[command](bag, tmp_path), tmp_path)
    assert "/test_servce1 " in line and f"did you mean {expected}," in line
    assert not (tmp_path / "fx").exists() and not (tmp_path / "m").exists()


def _outside_line(line: str, span: tuple[int, int]) -> None:
    """The one line of a window outside the bag: the bag, the window, the bag's span."""
    start, end = (format_ns(ns) for ns in span)
    assert f"{BAG}: the time window [" in line, line
    assert line.endswith(f"holds no message (the bag spans {start} to {end})"), line


@pytest.mark.parametrize("command", WINDOW_WARNS)
def test_a_window_outside_the_bag_is_the_one_warning(command: str, tmp_path: Path) -> None:
    with BagReader(BAG) as reader:
        span = reader.start_ns, reader.end_ns
    result = _bagkit(WINDOW_WARNS[command](BAG, tmp_path), tmp_path, command)
    assert result.returncode == 0, result.stderr
    (line,) = [x for x in result.stderr.splitlines() if "the time window" in x]
    assert line.startswith("warning: ") and "error" not in result.stderr
    _outside_line(line, span)


@pytest.mark.parametrize("command", WINDOW_FAILS)
def test_a_window_outside_the_bag_fails_where_nothing_is_no_result(
    command: str, tmp_path: Path
) -> None:
    with BagReader(BAG) as reader:
        span = reader.start_ns, reader.end_ns
    line = _error_line(WINDOW_FAILS[command](BAG, tmp_path), tmp_path)
    _outside_line(line, span)
    assert not (tmp_path / "fx").exists()  # golden add writes nothing


def test_stats_takes_a_service_name_as_echo_does(interop_dir: Path, tmp_path: Path) -> None:
    """``stats summary -t /service`` summarizes the service's event topic, as echo prints it."""
    bag = interop_dir / SERVICES
    with BagReader(bag) as reader:
        count = reader.topic_counts["/test_service1/_service_event"]
    result = bagkit_in_process(
        ["stats", "summary", bag, "-t", "/test_service1", "--format", "json"], tmp_path
    )
    assert result.returncode == 0, result.stderr
    (topic,) = json.loads(result.stdout)["topics"]
    assert (topic["topic"], topic["count"]) == ("/test_service1/_service_event", count)


def test_check_names_the_closest_topic_of_a_contract_broken_by_a_misspelling(
    tmp_path: Path,
) -> None:
    """A topic the contract requires and the bag lacks breaks it (exit 1, check's rule); the
    line says which topic the bag has that the contract may have meant."""
    with BagReader(BAG) as reader:
        expected = _close_to("/imu/dat", list(reader.topics))
    spec = _spec(tmp_path, "/imu/dat", "linear_acceleration.z")
    result = bagkit_in_process(["check", BAG, "--spec", spec], tmp_path)
    assert result.returncode == 1, result.stderr
    assert f"/imu/dat: present (not in the bag; did you mean {expected}?)" in result.stdout


def test_filter_takes_a_service_name_as_echo_does(interop_dir: Path, tmp_path: Path) -> None:
    """``filter --topics /service`` keeps the service's event topic, every call of it."""
    bag = interop_dir / SERVICES
    with BagReader(bag) as reader:
        count = reader.topic_counts["/test_service1/_service_event"]
    result = bagkit_in_process(["filter", bag, "-o", "out", "--topics", "/test_service1"], tmp_path)
    assert result.returncode == 0, result.stderr
    with BagReader(tmp_path / "out") as reader:
        assert reader.topic_counts == {"/test_service1/_service_event": count}


def test_filter_where_compiles_for_a_service_named_by_its_name(
    interop_dir: Path, tmp_path: Path
) -> None:
    """``--topics /service --where COND``: the service's name is resolved to its event topic
    before the condition is compiled, so its calls are filtered by their content."""
    bag = interop_dir / SERVICES
    condition = "request[*].int32_value >= 0"
    echoed = bagkit_in_process(
        ["echo", bag, "/test_service1/_service_event", "--format", "json"], tmp_path
    )
    assert echoed.returncode == 0, echoed.stderr
    events = [json.loads(line) for line in echoed.stdout.splitlines()]
    expected = [
        e["log_time"] for e in events if any(r["int32_value"] >= 0 for r in e["data"]["request"])
    ]
    assert 0 < len(expected) < len(events)
    args: list[str | Path] = ["filter", bag, "-o", "out", "--topics", "/test_service1"]
    result = bagkit_in_process([*args, "--where", condition], tmp_path)
    assert result.returncode == 0, result.stderr
    with BagReader(tmp_path / "out") as reader:
        assert [m.log_time for m in reader.messages()] == expected
