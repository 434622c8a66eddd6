"""``--where`` on export, plot and stats: the messages kept are the ones an oracle keeps.

The oracle reads every payload with the mcap library, decodes it with rosbags and evaluates
the condition written out by hand in Python; bagkit's bulk path (fixed layouts), its decoded
path (sequences, ``--no-bulk``) and the CLI must keep exactly those messages.
"""

from __future__ import annotations

import subprocess
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
from bagkit_runs import bagkit_in_process, bagkit_subprocess
from oracle import raw_messages
from samples import JAZZY, SAMPLE_TYPES, random_message

from bagkit.bag import BagWriter, TopicInfo
from bagkit.data.export import export
from bagkit.data.series import load_series
from bagkit.selection.errors import SelectionError, UnknownFieldError
from bagkit.selection.query import Query
from bagkit.stats import summarize

Check = Callable[[Any], bool]

# (topic, condition, the same condition on a rosbags message). Values are random: NaN and
# infinities among floats, octets as rosbags' signed bytes (masked back to 0-255 here).
CONDITIONS: dict[str, tuple[str, str, Check]] = {
    "bulk float": ("/imu", "linear_acceleration.z < 0", lambda m: m.linear_acceleration.z < 0),
    "bulk and/or/not, text": (
        "/imu",
        "linear_acceleration.z >= -500 and not "
        "(angular_velocity.x > 0 or header.frame_id == 'imu')",
        lambda m: (
            m.linear_acceleration.z >= -500
            and not (m.angular_velocity.x > 0 or m.header.frame_id == "imu")
        ),
    ),
    "bulk fixed array, unicode text": (
        "/imu",
        "orientation_covariance[4] != 0 and header.frame_id != 'odom_ü'",
        lambda m: m.orientation_covariance[4] != 0 and m.header.frame_id != "odom_ü",
    ),
    "bulk bool and uint32": (
        "/roi",
        "do_rectify == true or width > 3000000000",
        lambda m: bool(m.do_rectify) or m.width > 3_000_000_000,
    ),
    "bulk int8": ("/fix", "status.status < -100", lambda m: m.status.status < -100),
    "decoded: any element of a sequence of messages, octets": (
        "/diagnostics",
        "status[*].level >= 200",
        lambda m: any((s.level & 0xFF) >= 200 for s in m.status),
    ),
    "decoded: an index into a sequence": (
        "/joints",
        "position[1] > 0 or name[0] == 'a'",
        lambda m: (len(m.position) > 1 and m.position[1] > 0) or (m.name[:1] == ["a"]),
    ),
    "decoded: a string message": ("/text", "data < 'm'", lambda m: m.data < "m"),
}


def _oracle_times(bag: Path, topic: str, check: Check) -> list[int]:
    typename = SAMPLE_TYPES[topic]
    found = [
        log_time
        for name, log_time, _, data in raw_messages(bag)
        if name == topic and check(JAZZY.deserialize_cdr(data, typename))
    ]
    return sorted(found)


@pytest.mark.parametrize("case", CONDITIONS, ids=str)
def test_export_stats_and_plot_keep_what_the_oracle_keeps(
    case: str, sample_bag: Path, tmp_path: Path
) -> None:
    topic, condition, check = CONDITIONS[case]
    expected = _oracle_times(sample_bag, topic, check)
    assert 0 < len(expected) < 300, "the condition must select some messages, not all"

    out = tmp_path / "out.parquet"
    report = export(sample_bag, out, query=Query.create(topic, where=condition))
    assert report.rows[topic] == len(expected)
    assert pd.read_parquet(out)["log_time"].tolist() == expected

    for bulk in (True, False):
        result = summarize([sample_bag], Query.create(topic, where=condition), bulk=bulk)
        (stats,) = result.topics
        assert stats.count == len(expected), f"bulk={bulk}"

    numeric = "header.stamp.sec" if topic not in ("/text", "/flag") else None
    if numeric is not None and topic != "/roi":
        (series,) = load_series(
            [sample_bag], [f"{topic}:{numeric}"], query=Query.create(where=condition)
        )
        start_ns = min(log_time for _, log_time, _, _ in raw_messages(sample_bag))
        assert (np.rint(series.times * 1e9).astype(np.int64) + start_ns).tolist() == expected


def test_stats_values_under_where_equal_pandas_over_the_kept_rows(sample_bag: Path) -> None:
    frame = pd.DataFrame(
        [
            {"z": m.linear_acceleration.z, "x": m.linear_acceleration.x}
            for m in (
                JAZZY.deserialize_cdr(data, SAMPLE_TYPES["/imu"])
                for name, _, _, data in raw_messages(sample_bag)
                if name == "/imu"
            )
        ]
    )
    kept = frame[(frame["z"] < 0) & np.isfinite(frame["x"])]
    result = summarize(
        [sample_bag],
        Query.create(
            "/imu",
            ["linear_acceleration.x"],
            where="linear_acceleration.z < 0 and linear_acceleration.x > -1e308 and "
            "linear_acceleration.x < 1e308",
        ),
    )
    (field,) = result.topics[0].fields
    assert field.count == len(kept)
    assert field.min == kept["x"].min() and field.max == kept["x"].max()
    assert field.mean == pytest.approx(kept["x"].mean(), rel=1e-12)
    assert field.std == pytest.approx(kept["x"].std(), rel=1e-9)


def test_a_dataframe_read_with_a_query_keeps_what_pandas_keeps(sample_bag: Path) -> None:
    """``read_dataframe(bag, topic, query=...)``: the query's fields, window and condition,
    against pandas over the whole topic."""
    from bagkit.data.frames import read_dataframe

    whole = read_dataframe(sample_bag, "/imu")
    start = whole.index[len(whole) // 4]
    query = Query.create(
        fields=["linear_acceleration.x"], start=start, where="linear_acceleration.z < 0"
    )
    got = read_dataframe(sample_bag, "/imu", query=query)
    expected = whole[(whole.index >= start) & (whole["linear_acceleration.z"] < 0)]
    assert 0 < len(got) < len(whole)
    np.testing.assert_array_equal(got["linear_acceleration.x"], expected["linear_acceleration.x"])
    assert list(got.columns) == ["log_time", "publish_time", "linear_acceleration.x"]
    with pytest.raises(TypeError):
        read_dataframe(sample_bag, "/imu", ["x"], query=query)


def test_several_topics_keep_those_with_the_fields(sample_bag: Path, tmp_path: Path) -> None:
    report = export(
        sample_bag, tmp_path / "all", query=Query.create(where="header.frame_id == 'imu'")
    )
    with_header = {
        t for t, typename in SAMPLE_TYPES.items() if "header" in dict(JAZZY.fielddefs[typename][1])
    }
    assert set(report.rows) == with_header
    for topic in with_header:
        expected = _oracle_times(sample_bag, topic, lambda m: m.header.frame_id == "imu")
        assert report.rows[topic] == len(expected)


def test_one_topic_without_the_field_or_of_another_kind_is_an_error(
    sample_bag: Path, tmp_path: Path
) -> None:
    with pytest.raises(UnknownFieldError, match="no field"):
        export(
            sample_bag,
            tmp_path / "x.parquet",
            query=Query.create("/imu", where="status[*].level > 1"),
        )
    with pytest.raises(SelectionError, match="cannot compare str with int"):
        summarize([sample_bag], Query.create("/imu", where="header.frame_id > 2"))
    with pytest.raises(SelectionError, match="cannot compare a number with str"):
        load_series(
            [sample_bag],
            ["/imu:header.stamp.sec"],
            query=Query.create(where="header.stamp.sec == 'x'"),
        )


def _damaged_bag(path: Path) -> tuple[Path, list[int], int]:
    """Imu messages, every fifth one cut short: (bag, log times of intact ones with z < 0,
    how many are cut)."""
    rng = np.random.default_rng(7)
    kept, cut = [], 0
    with BagWriter(path) as bag:
        bag.add_topic(TopicInfo("/imu", SAMPLE_TYPES["/imu"]))
        for i in range(200):
            msg: Any = random_message(JAZZY, SAMPLE_TYPES["/imu"], rng)
            data = bytes(JAZZY.serialize_cdr(msg, SAMPLE_TYPES["/imu"]))
            t = 1_700_000_000_000_000_000 + i * 1_000_000
            if i % 5 == 0:
                data, cut = data[:40], cut + 1
            elif msg.linear_acceleration.z < 0:
                kept.append(t)
            bag.write("/imu", data, log_time=t, publish_time=t)
    return path, kept, cut


def test_undecodable_messages_are_counted_not_matched(tmp_path: Path) -> None:
    bag, kept, cut = _damaged_bag(tmp_path / "damaged")
    report = export(
        bag, tmp_path / "x.parquet", query=Query.create("/imu", where="linear_acceleration.z < 0")
    )
    assert pd.read_parquet(tmp_path / "x.parquet")["log_time"].tolist() == kept
    assert any(f"{cut} messages could not be decoded" in p for p in report.problems)
    for bulk in (True, False):
        result = summarize([bag], Query.create(where="linear_acceleration.z < 0"), bulk=bulk)
        assert result.topics[0].count == len(kept)
        assert any(f"{cut} messages could not be decoded" in p for p in result.problems)


def _bagkit(
    *args: str | Path, cwd: Path, in_subprocess: bool = True
) -> subprocess.CompletedProcess[str]:
    """``bagkit ARGS`` in ``cwd``: as a shell runs it, or in this process (tests/bagkit_runs.py)."""
    return (bagkit_subprocess if in_subprocess else bagkit_in_process)(list(args), cwd)


def _commands(bag: Path, condition: str) -> dict[str, list[str | Path]]:
    return {
        "echo": ["echo", bag, "/imu", "--where", condition],
        "export": ["export", bag, "-t", "/imu", "-o", "out.parquet", "--where", condition],
        "stats": ["stats", "summary", bag, "-t", "/imu", "--where", condition],
        "plot": ["plot", bag, "/imu:header.stamp.sec", "-o", "p.png", "--where", condition],
    }


@pytest.mark.parametrize(
    ("condition", "error"),
    [
        ("linear_acceleration.w < 0", "error: /imu has no field linear_acceleration.w"),
        ("header.frame_id >= 3", "error: header.frame_id >= 3: cannot compare str with int"),
        ("linear_acceleration.z <", "error: bad condition 'linear_acceleration.z <': expected"),
    ],
)
@pytest.mark.parametrize("command", ["echo", "export", "stats", "plot"])
def test_bad_conditions_are_one_error_line(
    command: str, condition: str, error: str, sample_bag: Path, tmp_path: Path
) -> None:
    args = _commands(sample_bag, condition)[command]
    result = _bagkit(*args, cwd=tmp_path, in_subprocess=command == "echo")
    assert result.returncode == 2, result.stderr
    assert result.stderr.startswith(error), result.stderr
    assert result.stderr.count("\n") == 1 and result.stdout == ""


@pytest.mark.parametrize("command", ["echo", "export", "stats", "plot"])
def test_an_empty_match_is_one_warning_line(command: str, sample_bag: Path, tmp_path: Path) -> None:
    condition = "header.frame_id == 'nowhere'"
    args = _commands(sample_bag, condition)[command]
    result = _bagkit(*args, cwd=tmp_path, in_subprocess=command == "echo")
    assert result.returncode == 0, result.stderr
    said = (result.stderr + result.stdout).count("no message satisfies")
    assert said == 1, result.stderr + result.stdout


INJECTIONS = [
    "__import__('os').system('touch PWNED') == 0",
    'exec(\'open("PWNED", "w")\') == 1',
    "header.frame_id == '' or __import__('os').system('touch PWNED')",
    "$(touch PWNED) == 1",
    "`touch PWNED` == 1",
    "header.frame_id == 1; touch PWNED",
    "header.frame_id == '' && touch PWNED",
    "header.__class__ == 1",
    "header._frame_id == 1",
    "header.frame_id == '$(touch PWNED)' or header.frame_id == \"`touch PWNED`\"",
]


@pytest.mark.parametrize("condition", INJECTIONS)
def test_a_condition_is_data_not_code(condition: str, sample_bag: Path, tmp_path: Path) -> None:
    # One command per string: every command parses the condition with the same parser.
    command = ["echo", "export", "stats", "plot"][INJECTIONS.index(condition) % 4]
    result = _bagkit(*_commands(sample_bag, condition)[command], cwd=tmp_path)
    assert not (tmp_path / "PWNED").exists()
    assert "Traceback" not in result.stderr
    if "'$(touch PWNED)'" in condition:  # a valid condition on text: no message has it
        assert result.returncode == 0, result.stderr
    else:
        assert result.returncode == 2 and result.stderr.startswith("error: "), result.stderr
        assert result.stderr.count("\n") == 1
