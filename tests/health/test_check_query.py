"""``bagkit check`` with a query: only the contracts of its topics, only the messages of its
window (library and CLI subprocesses). The expected places come from the whole bag's check."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from bagkit.bag import BagReader
from bagkit.health import HealthSpec, check_bags
from bagkit.health.verdicts import HealthReport
from bagkit.selection.errors import UnknownTopicError
from bagkit.selection.query import Query
from bagkit.selection.times import format_ns

BAGKIT = str(Path(sys.executable).with_name("bagkit"))
BAG = Path(__file__).parents[2] / "fixtures" / "faults" / "golden"
BOUND = "linear_acceleration.z < 9.0 or linear_acceleration.z > 10.6"
CONTRACT = """\
topics:
  /imu/data:
    values:
      linear_acceleration.z: {min: 9.0, max: 10.6}
  /gps/fix: {}
forbidden: [/nope]
"""


@pytest.fixture
def spec(tmp_path: Path) -> Path:
    path = tmp_path / "health.yaml"
    path.write_text(CONTRACT)
    return path


def _report(spec: Path, query: Query | None = None) -> HealthReport:
    (report,) = check_bags([BAG], HealthSpec.load(spec), query=query).reports
    return report


def _spans(report: HealthReport) -> list[tuple[int, int]]:
    (bound,) = [a for a in report.assertions if a.what == BOUND]
    return [(start, end) for start, end, _ in bound.spans.tolist()]


def test_topics_choose_the_contracts_evaluated(spec: Path) -> None:
    whole = _report(spec)
    only = _report(spec, Query.create("imu/data"))
    assert {a.topic for a in whole.assertions} == {"/imu/data", "/gps/fix", "/nope"}
    expected = [(a.what, a.passed) for a in whole.assertions if a.topic == "/imu/data"]
    assert [(a.what, a.passed) for a in only.assertions] == expected
    assert _spans(only) == _spans(whole)
    with pytest.raises(UnknownTopicError, match=r"/imu/dat not in the contract .*did you mean"):
        check_bags([BAG], HealthSpec.load(spec), query=Query.create("/imu/dat"))


def test_a_window_checks_only_its_messages(spec: Path) -> None:
    whole = _spans(_report(spec))
    assert len(whole) >= 2
    (_, first_end), (second_start, _) = whole[0], whole[1]
    # Between the two breaks: the bound holds.
    between = Query.create(start=f"{first_end + 1}ns", end=f"{second_start - 1}ns")
    report = _report(spec, between)
    assert report.passed and not report.problems
    # From after the first: only the later breaks, none before the window's start.
    later = _report(spec, Query.create(start=f"{first_end + 1}ns"))
    assert [s for s, _ in _spans(later)] == [s for s, _ in whole[1:]]


def _run(*args: str | Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [BAGKIT, *map(str, args)], capture_output=True, text=True, timeout=120, check=False
    )


def test_cli_topics_and_window(spec: Path) -> None:
    whole = _spans(_report(spec))
    (_, first_end), (second_start, _) = whole[0], whole[1]
    healthy = _run(
        "check", BAG, "--spec", spec, "-t", "/imu/data",
        "--start", f"{first_end + 1}ns", "--end", f"{second_start - 1}ns",
    )  # fmt: skip
    assert healthy.returncode == 0, healthy.stderr
    assert healthy.stdout.splitlines()[0].endswith("2 assertions, healthy")
    misspelt = _run("check", BAG, "--spec", spec, "-t", "/imu/dat")
    assert misspelt.returncode == 2 and misspelt.stdout == ""
    (line,) = misspelt.stderr.splitlines()
    assert line.startswith("error: ") and "did you mean /imu/data?" in line


def test_cli_window_outside_the_bag_is_the_one_warning(spec: Path) -> None:
    with BagReader(BAG) as reader:
        start, end = reader.start_ns, reader.end_ns
    result = _run("check", BAG, "--spec", spec, "--start", "1000", "--end", "1010")
    assert result.returncode == 1, result.stderr  # the required topics have no message there
    (line,) = [x for x in result.stderr.splitlines() if "the time window" in x]
    assert line.startswith(f"warning: {BAG}: the time window [")
    assert line.endswith(f"holds no message (the bag spans {format_ns(start)} to {format_ns(end)})")
    assert "/imu/data: present (no message in the window)" in result.stdout
