"""The same topics and times mean one thing in every command.

Each selection runs through echo, export, stats summary, filter and plot's series; what each
selected is compared with what the bag holds in that window, read with the bag reader alone.
The edges (unknown topic, window outside the bag, missing path) are checked once for all. The
commands run in this process (tests/bagkit_runs.py); echo's edges as subprocesses, the
process boundary once.
"""

from __future__ import annotations

import csv
import datetime as dt
import json
import subprocess
from collections.abc import Callable
from pathlib import Path

import pytest
from bagkit_runs import bagkit_in_process, bagkit_subprocess

from bagkit.bag import BagReader
from bagkit.data.series import load_series
from bagkit.selection.query import Query

BAG = Path(__file__).resolve().parents[2] / "fixtures" / "faults" / "golden"
S = 1_000_000_000


def _bagkit(
    *args: str | Path, cwd: Path | None = None, in_subprocess: bool = False
) -> subprocess.CompletedProcess[str]:
    run = bagkit_subprocess if in_subprocess else bagkit_in_process
    return run(list(args), cwd or Path.cwd())


@pytest.fixture(scope="module")
def span() -> tuple[int, int]:
    with BagReader(BAG) as reader:
        return reader.start_ns, reader.end_ns


def _iso(ns: int) -> str:
    stamp = dt.datetime.fromtimestamp(ns // S, tz=dt.timezone.utc)
    return stamp.strftime("%Y-%m-%dT%H:%M:%S") + f".{ns % S:09d}Z"


# (topic as typed, --start, --end) given as functions of the bag's span, and the window in ns.
Times = Callable[[int, int], tuple[str | None, str | None, int | None, int | None]]
SELECTIONS: dict[str, tuple[str, Times]] = {
    "offsets": ("imu/data", lambda s, e: ("10", "20", s + 10 * S, s + 20 * S)),
    "from the end": ("/imu/data", lambda s, e: ("-5", None, e - 5 * S, None)),
    "durations": ("imu/data", lambda s, e: ("12s", "20500ms", s + 12 * S, s + 20_500_000_000)),
    "epoch seconds": ("gps/fix", lambda s, e: (f"{(s + 12 * S) / S:.9f}", None, s + 12 * S, None)),
    "iso 8601": (
        "/gps/fix",
        lambda s, e: (_iso(s + 3 * S), _iso(s + 33 * S), s + 3 * S, s + 33 * S),
    ),
    "nanoseconds": (
        "temperature",
        lambda s, e: (f"{7 * S}ns", f"{s + 40 * S}ns", s + 7 * S, s + 40 * S),
    ),
}


def _expected(topic: str, start: int | None, end: int | None) -> list[int]:
    with BagReader(BAG) as reader:
        return [m.log_time for m in reader.messages([topic], start, end)]


def _options(start: str | None, end: str | None) -> list[str]:
    return [*(["--start", start] if start else []), *(["--end", end] if end else [])]


def _echo(topic: str, times: list[str], tmp: Path) -> list[int]:
    result = _bagkit("echo", BAG, topic, "--format", "json", *times)
    assert result.returncode == 0, result.stderr
    return [json.loads(line)["log_time"] for line in result.stdout.splitlines()]


def _export(topic: str, times: list[str], tmp: Path) -> list[int]:
    out = tmp / "out.csv"
    result = _bagkit("export", BAG, "-t", topic, "-o", out, "--format", "csv", *times)
    assert result.returncode == 0, result.stderr
    with out.open() as f:
        return [int(row["log_time"]) for row in csv.DictReader(f)]


def _stats(topic: str, times: list[str], tmp: Path) -> list[int]:
    result = _bagkit("stats", "summary", BAG, "-t", topic, "--format", "json", *times)
    assert result.returncode == 0, result.stderr
    (found,) = json.loads(result.stdout)["topics"]
    return [found["count"]]  # stats gives counts, compared with the count below


def _filter(topic: str, times: list[str], tmp: Path) -> list[int]:
    out = tmp / "cut"
    result = _bagkit("filter", BAG, "-o", out, "--topics", topic, *times, cwd=tmp)
    assert result.returncode == 0, result.stderr
    with BagReader(out) as reader:
        return [m.log_time for m in reader.messages()]


COMMANDS = {"echo": _echo, "export": _export, "stats": _stats, "filter": _filter}


@pytest.mark.parametrize("command", COMMANDS)
@pytest.mark.parametrize("name", SELECTIONS)
def test_one_selection_selects_the_same_messages_everywhere(
    command: str, name: str, span: tuple[int, int], tmp_path: Path
) -> None:
    topic, times = SELECTIONS[name]
    start, end, start_ns, end_ns = times(*span)
    expected = _expected("/" + topic.lstrip("/"), start_ns, end_ns)
    assert 0 < len(expected) < BagReader(BAG).open().topic_counts["/" + topic.lstrip("/")]
    got = COMMANDS[command](topic, _options(start, end), tmp_path)
    assert got == ([len(expected)] if command == "stats" else expected)


@pytest.mark.parametrize("name", SELECTIONS)
def test_plot_series_select_the_same_window(name: str, span: tuple[int, int]) -> None:
    topic, times = SELECTIONS[name]
    start, end, start_ns, end_ns = times(*span)
    field = "header.stamp.sec"
    (series,) = load_series(
        [BAG], [f"{topic}:{field}"], query=Query.create(start=start, end=end), absolute=True
    )
    assert len(series.values) == len(_expected("/" + topic.lstrip("/"), start_ns, end_ns))


EDGE_COMMANDS = {
    "echo": lambda bag, topic, tmp: ["echo", bag, topic],
    "export": lambda bag, topic, tmp: ["export", bag, "-t", topic, "-o", tmp / "x.csv"],
    "stats": lambda bag, topic, tmp: ["stats", "summary", bag, "-t", topic],
    "filter": lambda bag, topic, tmp: ["filter", bag, "-o", tmp / "f", "--topics", topic],
    "plot": lambda bag, topic, tmp: ["plot", bag, f"{topic}:header.stamp.sec", "-o", tmp / "p.png"],
    "compare": lambda bag, topic, tmp: ["compare", bag, bag, "-t", topic],
}


@pytest.mark.parametrize("command", EDGE_COMMANDS)
def test_an_unknown_topic_is_one_error_naming_the_closest(command: str, tmp_path: Path) -> None:
    args = EDGE_COMMANDS[command](BAG, "/imu/dat", tmp_path)
    result = _bagkit(*args, cwd=tmp_path, in_subprocess=command == "echo")
    assert result.returncode == 2, result.stderr
    assert result.stderr.count("\n") == 1
    assert result.stderr.startswith("error: topic /imu/dat not in ")
    assert "did you mean /imu/data?" in result.stderr


@pytest.mark.parametrize("command", EDGE_COMMANDS)
def test_a_missing_path_is_one_error(command: str, tmp_path: Path) -> None:
    missing = tmp_path / "no_such_bag"
    args = EDGE_COMMANDS[command](missing, "/imu/data", tmp_path)
    result = _bagkit(*args, cwd=tmp_path, in_subprocess=command == "echo")
    assert result.returncode == 2
    assert result.stderr == f"error: {missing}: no such file or directory\n"


WINDOW_COMMANDS = {
    **EDGE_COMMANDS,
    "find": lambda bag, topic, tmp: ["find", bag, "--when", f"{topic}: header.stamp.sec > 0"],
}


@pytest.mark.parametrize("command", ["echo", "export", "stats", "filter", "plot", "find"])
def test_a_window_outside_the_bag_is_one_warning_and_an_empty_result(
    command: str, tmp_path: Path
) -> None:
    args = [*WINDOW_COMMANDS[command](BAG, "/imu/data", tmp_path), "--start", "1h"]
    result = _bagkit(*args, cwd=tmp_path, in_subprocess=command == "echo")
    warnings = [line for line in result.stderr.splitlines() if line.startswith("warning:")]
    assert len(warnings) == 1, result.stderr
    assert warnings[0].startswith(f"warning: {BAG}: the time window [")
    assert result.returncode == 0, result.stderr
    if command == "echo":
        assert result.stdout == ""
    if command == "find":
        assert result.stdout.startswith("0 episodes")


@pytest.mark.parametrize("window", [["--start", "1000", "--end", "1010"], ["--end", "-1h"]])
def test_golden_add_of_a_window_outside_the_bag_fails_and_leaves_nothing(
    window: list[str], tmp_path: Path
) -> None:
    """Its latched state alone would make a fixture that passes any test."""
    result = _bagkit("golden", "add", tmp_path / "fixtures" / "new", "--from", BAG, *window)
    assert result.returncode == 2
    assert result.stderr.startswith(f"error: {BAG}: the time window [")
    assert result.stderr.count("\n") == 1
    assert not (tmp_path / "fixtures").exists()


def test_golden_add_of_a_missing_bag_leaves_no_folder(tmp_path: Path) -> None:
    result = _bagkit("golden", "add", "fixtures/new", "--from", "nope_bag", cwd=tmp_path)
    assert (result.returncode, result.stderr) == (2, "error: nope_bag: no such file or directory\n")
    assert list(tmp_path.iterdir()) == []


def test_echo_where_keeps_the_messages_the_condition_holds_for() -> None:
    everything = _bagkit("echo", BAG, "/alerts", "--format", "json")
    records = [json.loads(line) for line in everything.stdout.splitlines()]
    expected = [r["log_time"] for r in records if any(s["level"] >= 2 for s in r["data"]["status"])]
    assert 0 < len(expected) < len(records)
    kept = _bagkit("echo", BAG, "alerts", "--format", "json", "--where", "status[*].level >= 2")
    assert kept.returncode == 0, kept.stderr
    assert [json.loads(line)["log_time"] for line in kept.stdout.splitlines()] == expected


@pytest.mark.parametrize(
    ("condition", "error"),
    [
        ("status[*].lvl >= 2", "error: /alerts has no field status[*].lvl (did you mean"),
        ("status[*].level >=", "error: bad condition 'status[*].level >=': expected a value"),
        ("status[*].name > 2", "error: status[*].name > 2: cannot compare str with int"),
        ("__import__('os').system('true') == 0", "error: bad condition"),
    ],
)
def test_echo_where_errors_are_one_line(condition: str, error: str) -> None:
    result = _bagkit("echo", BAG, "/alerts", "--where", condition)
    assert result.returncode == 2 and result.stdout == ""
    assert result.stderr.startswith(error) and result.stderr.count("\n") == 1
