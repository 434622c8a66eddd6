"""A misspelt topic, field, service or time is the same answer from every command (subprocesses).

One ``error:`` line naming what was typed and the closest names the bag has, exit 2, nothing on
stdout. The guesses expected are the bag's own names, read with the bag reader and the
decoder's leaf paths, not written out here.
"""

from __future__ import annotations

import difflib
import json
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

from bagkit.bag import BagReader
from bagkit.decode import MessageTypes, leaf_fields

BAGKIT = str(Path(sys.executable).with_name("bagkit"))
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
}
TIME_CASES: dict[str, Args] = {
    "echo": lambda b, t: ["echo", b, "/imu/data", "--start", "1O"],
    "stats": lambda b, t: ["stats", "summary", b, "--end", "1O"],
    "filter": lambda b, t: ["filter", b, "-o", t / "f", "--start", "1O"],
    "find": lambda b, t: ["find", b, "--when", "/imu/data: header.stamp.sec > 0", "--start", "1O"],
    "export": lambda b, t: ["export", b, "-o", t / "x.csv", "-t", "/imu/data", "--start", "1O"],
    "golden add": lambda b, t: ["golden", "add", t / "fx", "--from", b, "--start", "1O"],
}


def _error_line(args: list[str | Path], cwd: Path) -> str:
    result = subprocess.run(
        [BAGKIT, *map(str, args)], capture_output=True, text=True, timeout=120, cwd=cwd, check=False
    )
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
    line = _error_line(TOPIC_CASES[command](BAG, tmp_path), tmp_path)
    assert "/imu/dat " in line and f"did you mean {expected}?" in line
    assert not (tmp_path / "fx").exists()  # golden add leaves nothing behind


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


@pytest.mark.parametrize("command", ["echo", "stats"])
def test_a_misspelt_service_names_the_service(
    command: str, interop_dir: Path, tmp_path: Path
) -> None:
    bag = interop_dir / SERVICES
    with BagReader(bag) as reader:
        services = [t.removesuffix("/_service_event") for t in reader.topics if "_service" in t]
    expected = _close_to("/test_servce1", services)
    args: list[str | Path] = (
        ["echo", bag, "/test_servce1"]
        if command == "echo"
        else ["stats", "summary", bag, "-t", "/test_servce1"]
    )
    line = _error_line(args, tmp_path)
    assert f"did you mean {expected}," in line


def test_stats_takes_a_service_name_as_echo_does(interop_dir: Path) -> None:
    """``stats summary -t /service`` summarizes the service's event topic, as echo prints it."""
    bag = interop_dir / SERVICES
    with BagReader(bag) as reader:
        count = reader.topic_counts["/test_service1/_service_event"]
    result = subprocess.run(
        [BAGKIT, "stats", "summary", str(bag), "-t", "/test_service1", "--format", "json"],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert result.returncode == 0, result.stderr
    (topic,) = json.loads(result.stdout)["topics"]
    assert (topic["topic"], topic["count"]) == ("/test_service1/_service_event", count)
