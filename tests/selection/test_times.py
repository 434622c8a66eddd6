"""The one time grammar: offsets from the start or end, epoch times, ISO 8601, NNNns, durations."""

from __future__ import annotations

import datetime as dt

import numpy as np
import pandas as pd
import pytest

from bagkit.selection.errors import SelectionError
from bagkit.selection.times import (
    ABSOLUTE_AFTER_S,
    Anchor,
    format_ns,
    parse_duration,
    parse_time,
)

START, END = 1_763_850_000_000_000_000, 1_763_850_060_000_000_000


@pytest.mark.parametrize(
    ("text", "seconds_after_start"),
    [("10", 10), ("2.5", 2.5), ("1m30s", 90), ("0.5s", 0.5), ("250ms", 0.25), ("1h", 3600)],
)
def test_offsets_count_from_the_bag_start(text: str, seconds_after_start: float) -> None:
    point = parse_time(text)
    assert point.anchor is Anchor.START
    assert point.resolve(START, END) == START + round(seconds_after_start * 1e9)


@pytest.mark.parametrize(("text", "seconds_before_end"), [("-5", 5), ("-1m", 60), ("-0", 0)])
def test_negative_offsets_count_from_the_bag_end(text: str, seconds_before_end: float) -> None:
    point = parse_time(text)
    assert point.anchor is Anchor.END
    assert point.resolve(START, END) == END - round(seconds_before_end * 1e9)


def test_nanoseconds_follow_the_same_rule_as_seconds() -> None:
    assert parse_time("5000000000ns").resolve(START, END) == START + 5_000_000_000
    assert parse_time(f"{START}ns").resolve(0, 1) == START
    assert parse_time(f"-{2 * 10**9}ns").resolve(START, END) == END - 2 * 10**9


def test_epoch_seconds_from_the_threshold_on() -> None:
    assert parse_time(str(ABSOLUTE_AFTER_S)).absolute
    assert not parse_time(str(ABSOLUTE_AFTER_S - 1)).absolute
    assert parse_time("1763850000.25").resolve(0, 0) == 1_763_850_000_250_000_000
    assert parse_time(1763850000.25).resolve(0, 0) == 1_763_850_000_250_000_000
    assert parse_time(10).resolve(START, END) == START + 10**10
    assert parse_time(np.float64(1763850000.25)) == parse_time("1763850000.25")
    assert parse_time(np.int64(-3)).resolve(START, END) == END - 3 * 10**9


def test_iso_8601_and_time_objects_are_absolute_and_naive_is_utc() -> None:
    aware = dt.datetime(2025, 11, 22, 22, 20, 0, 250000, tzinfo=dt.timezone.utc)
    expected = int(aware.timestamp() * 1e6) * 1000
    for value in (
        "2025-11-22T22:20:00.25Z",
        "2025-11-22T22:20:00.25",
        "2025-11-22T23:20:00.25+01:00",
        aware,
        aware.replace(tzinfo=None),
        pd.Timestamp(aware),
        np.datetime64("2025-11-22T22:20:00.250"),
    ):
        point = parse_time(value)
        assert point.absolute, value
        assert point.resolve(START, END) == expected, value
    assert format_ns(expected) == "2025-11-22T22:20:00.250000000Z"


@pytest.mark.parametrize(
    "text", ["nan", "inf", "-inf", "1e400", "abc", "", "--5", "1m-5s", "5 s", "10ns5", "-2e9"]
)
def test_what_is_not_a_time_is_one_error(text: str) -> None:
    with pytest.raises(SelectionError, match=r"^bad --start"):
        parse_time(text, "--start")


@pytest.mark.parametrize(
    ("text", "seconds"), [("90", 90), ("1.5", 1.5), ("90s", 90), ("1m30s", 90), ("2h", 7200)]
)
def test_durations(text: str, seconds: float) -> None:
    assert parse_duration(text) == round(seconds * 1e9)


@pytest.mark.parametrize("text", ["-5", "abc", "nan", "1m-1s", ""])
def test_bad_durations(text: str) -> None:
    with pytest.raises(SelectionError, match=r"^bad --post"):
        parse_duration(text, "--post")


@pytest.mark.parametrize("text", ["99999999999999999999s", "9223372037s", "2562048h", 1e19])
def test_a_duration_beyond_int64_nanoseconds_is_one_error(text: str | float) -> None:
    # An unbounded window reached numpy's int64 time columns: OverflowError, exit 70.
    with pytest.raises(SelectionError, match=r"^bad --post .*int64"):
        parse_duration(text, "--post")


def test_iso_8601_keeps_nanoseconds_and_reads_what_python_3_10_does_not() -> None:
    base = parse_time("2025-11-22T22:20:00Z").ns
    assert parse_time("2025-11-22T22:20:00.123456789Z").ns == base + 123_456_789
    assert parse_time("2025-11-22T23:20:00.5+0100").ns == base + 500_000_000
    assert parse_time("2025-11-22 22:20").ns == base
    assert parse_time(format_ns(base + 7)).ns == base + 7
