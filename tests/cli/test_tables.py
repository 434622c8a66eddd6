"""Every table of the CLI (run in this process, tests/bagkit_runs.py) at 80 columns and narrower:
no name is ever cut."""

from __future__ import annotations

import re
import shlex
import struct
from pathlib import Path

import pytest
from bagkit_runs import bagkit_in_process

from bagkit.bag import BagWriter, TopicInfo
from bagkit.cli.tables import shell_lines

START = 1_763_850_000_000_000_000
LONG_TOPIC = "/a/very/long/namespace/for/the/battery/management/system/of_the_robot/report"
LONG_TYPE = "my_robot_msgs/msg/SomeVeryLongTypeNameForTesting"
LONG_FIELD = "temperature_of_the_battery_pack_in_degrees_celsius"
SHORT_TOPIC = "/diagnostics"
SHORT_TYPE = "my_robot_msgs/msg/BatteryReport"
# One float64 after the CDR header (little endian): the layout of both types.
DEFINITION = f"float64 {LONG_FIELD}\n"
NAMES = (LONG_TOPIC, LONG_TYPE, SHORT_TOPIC, SHORT_TYPE)


def _cdr(value: float) -> bytes:
    return b"\x00\x01\x00\x00" + struct.pack("<d", value)


@pytest.fixture(scope="module")
def long_names_bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Two topics, one with a long name and type, 10 messages each at 10 Hz."""
    path = tmp_path_factory.mktemp("tables") / "long_names"
    with BagWriter(path) as bag:
        bag.add_topic(TopicInfo(LONG_TOPIC, LONG_TYPE), definition=DEFINITION)
        bag.add_topic(TopicInfo(SHORT_TOPIC, SHORT_TYPE), definition=DEFINITION)
        for i in range(10):
            for topic in (LONG_TOPIC, SHORT_TOPIC):
                bag.write(topic, _cdr(20.0 + i), log_time=START + i * 200_000_000)
    return path


def _run(columns: int, *args: str, cwd: Path | None = None) -> str:
    """``bagkit ARGS`` in this process (tests/bagkit_runs.py), ``COLUMNS`` wide."""
    done = bagkit_in_process(list(args), cwd, env={"COLUMNS": str(columns)})
    assert done.returncode in (0, 1), done.stderr
    return done.stdout


def _assert_names_whole(out: str, names: tuple[str, ...], columns: int) -> None:
    """Each name stands whole on a line; a line is over the width only for a name's sake."""
    lines = out.splitlines()
    for name in names:
        whole = re.compile(rf"(^|[\s(]){re.escape(name)}($|[\s,])")
        assert any(whole.search(line) for line in lines), (name, out)
        # A name's head at a line's end is a name cut in two.
        for cut in range(8, len(name)):
            assert not any(line.endswith(name[:cut]) for line in lines), (name, out)
    for line in lines:
        # Over the width only with a name and its label ("      type NAME"): no table row.
        over = len(line) > columns
        assert not over or any(len(line) - len(n) <= 12 for n in names if n in line), out


@pytest.mark.parametrize("columns", [80, 40])
def test_info(long_names_bag: Path, columns: int) -> None:
    out = _run(columns, "info", str(long_names_bag))
    _assert_names_whole(out, NAMES, columns)
    verbose = _run(columns, "info", "-v", str(long_names_bag))
    _assert_names_whole(verbose, NAMES, columns)


def test_info_keeps_a_table_when_it_fits(long_names_bag: Path) -> None:
    """At 200 columns a row holds a topic, its type and its figures."""
    out = _run(200, "info", str(long_names_bag))
    row = next(line for line in out.splitlines() if LONG_TOPIC in line)
    assert row.split() == [LONG_TOPIC, LONG_TYPE, "10", "5.00", "Hz"]


@pytest.mark.parametrize("columns", [80, 40])
def test_stats_summary(long_names_bag: Path, columns: int) -> None:
    out = _run(columns, "stats", "summary", str(long_names_bag))
    _assert_names_whole(out, (*NAMES, LONG_FIELD, f"{long_names_bag}:"), columns)
    # The mean of 20..29 written above, whatever the layout.
    assert re.search(r"(^|\s)24\.5(\s|,|$)", out, re.MULTILINE), out


@pytest.mark.parametrize("columns", [80, 40])
def test_compare(long_names_bag: Path, columns: int) -> None:
    out = _run(columns, "compare", str(long_names_bag), str(long_names_bag))
    _assert_names_whole(out, (LONG_TOPIC, SHORT_TOPIC, LONG_FIELD), columns)
    assert "PASS" in out


@pytest.mark.parametrize("columns", [80, 40])
def test_catalog_query(long_names_bag: Path, tmp_path: Path, columns: int) -> None:
    catalog = tmp_path / "catalog.parquet"
    _run(columns, "catalog", str(long_names_bag.parent), "-o", str(catalog), cwd=tmp_path)
    out = _run(columns, "catalog", "query", str(catalog), cwd=tmp_path)
    _assert_names_whole(out, (*NAMES, str(long_names_bag)), columns)


@pytest.mark.parametrize("columns", [80, 40])
def test_record_report(
    columns: int, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """The end-of-recording report, rendered in process (recording it needs DDS: tests/ros)."""
    from bagkit.cli.record_table import print_record_table
    from bagkit.recording.report import RecordReport, TopicRecord

    monkeypatch.setenv("COLUMNS", str(columns))
    path = Path("/tmp") / ("x" * 90) / "bag"  # longer than the width: a line of its own
    long = TopicRecord(LONG_TOPIC, LONG_TYPE, messages=10, bytes=120, gaps=2)
    short = TopicRecord(SHORT_TOPIC, SHORT_TYPE, messages=5, bytes=60, first_ns=0, last_ns=10**9)
    print_record_table(RecordReport(path, duration_s=3.04, discovery_s=1.93, topics=[long, short]))
    out = capsys.readouterr().out
    _assert_names_whole(out, (*NAMES, str(path)), columns)
    assert out.splitlines()[:2] == [str(path), "(3.0 s, topics subscribed after 1.9 s)"]
    assert f"{LONG_TOPIC}: 2 lost in the middleware" in out.replace("\n    ", " ")


def test_a_long_command_goes_on_over_lines_a_shell_joins() -> None:
    command = "bagkit filter 'my bag' -o out --around '/a: x > 1' --before 5 --after 5"
    lines = shell_lines(command, 30)
    assert lines == [
        "bagkit filter 'my bag' \\",
        "  -o out \\",
        "  --around '/a: x > 1' \\",
        "  --before 5 --after 5",
    ]
    assert shlex.split(" ".join(line.removesuffix("\\") for line in lines)) == shlex.split(command)
    # A word longer than the width stays whole, on its own line.
    assert shell_lines("bagkit play /a/very/long/path/to/a/bag", 12) == [
        "bagkit \\",
        "  play \\",
        "  /a/very/long/path/to/a/bag",
    ]
    assert shell_lines(command, 80) == [command]
