"""The filter's selection rules (pure)."""

from __future__ import annotations

import pytest

from bagkit.surgery.errors import SurgeryError
from bagkit.surgery.select import Selection, parse_time

TOPICS = ["/imu/data", "/imu/raw", "/gps/fix", "/camera/image", "/rosout"]


@pytest.mark.parametrize(
    ("selection", "kept"),
    [
        (Selection(), TOPICS),
        (Selection(topics=frozenset({"/gps/fix"})), ["/gps/fix"]),
        (Selection(regex="^/imu"), ["/imu/data", "/imu/raw"]),
        (
            Selection(regex="imu", topics=frozenset({"/rosout"})),
            ["/imu/data", "/imu/raw", "/rosout"],
        ),
        (Selection(exclude_topics=frozenset({"/rosout"})), TOPICS[:4]),
        (Selection(exclude_regex="raw|image"), ["/imu/data", "/gps/fix", "/rosout"]),
        (Selection(regex="^/imu", exclude_topics=frozenset({"/imu/raw"})), ["/imu/data"]),
        (Selection(topics=frozenset({"/gps/fix"}), exclude_regex="gps"), []),
    ],
)
def test_topic_rules(selection: Selection, kept: list[str]) -> None:
    assert [t for t in TOPICS if selection.topic_passes(t)] == kept


def test_time_range_is_half_open() -> None:
    selection = Selection(start_ns=10, end_ns=20)
    assert [t for t in range(5, 25) if selection.time_passes(t)] == list(range(10, 20))
    assert selection.covers(10, 19)
    assert not selection.covers(9, 19)
    assert not selection.covers(10, 20)


def test_bad_input_is_refused() -> None:
    with pytest.raises(SurgeryError, match="bad regex"):
        Selection(regex="(")
    with pytest.raises(SurgeryError, match="empty time range"):
        Selection(start_ns=5, end_ns=5)
    with pytest.raises(SurgeryError, match="bad time"):
        parse_time("yesterday")


def test_times() -> None:
    assert parse_time("1700000000.25") == 1_700_000_000_250_000_000
    assert parse_time("1700000000250000001ns") == 1_700_000_000_250_000_001
    assert parse_time("2023-11-14T22:13:20Z") == 1_700_000_000_000_000_000
    assert parse_time("2023-11-14T22:13:20.5") == 1_700_000_000_500_000_000
