"""The filter's selection rules (pure): ros2 bag convert's topic rules, windows per input."""

from __future__ import annotations

import pytest

from bagkit.selection.errors import SelectionError
from bagkit.surgery.select import Selection

TOPICS = ["/imu/data", "/imu/raw", "/gps/fix", "/camera/image", "/rosout", "/_hidden/state"]
S = 1_000_000_000


@pytest.mark.parametrize(
    ("selection", "kept"),
    [
        (Selection(), TOPICS),
        (Selection.create(["gps/fix"]), ["/gps/fix"]),
        (Selection.create(regex="^/imu"), ["/imu/data", "/imu/raw"]),
        (Selection.create(["/rosout"], regex="imu"), ["/imu/data", "/imu/raw", "/rosout"]),
        (Selection.create(exclude_topics=["rosout"]), [t for t in TOPICS if t != "/rosout"]),
        (
            Selection.create(exclude_regex="raw|image|_"),
            ["/imu/data", "/gps/fix", "/rosout"],
        ),
        (Selection.create(regex="^/imu", exclude_topics=["/imu/raw"]), ["/imu/data"]),
        (Selection.create(["/gps/fix"], exclude_regex="gps"), []),
    ],
)
def test_topic_rules(selection: Selection, kept: list[str]) -> None:
    assert [t for t in TOPICS if selection.topic_passes(t)] == kept


def test_times_resolve_against_the_input_and_the_window_is_half_open() -> None:
    selection = Selection.create(start="10", end="-5").resolved(100 * S, 200 * S)
    assert selection.window.start_ns == 110 * S and selection.window.end_ns == 195 * S
    assert selection.time_passes(110 * S) and not selection.time_passes(195 * S)
    assert selection.covers(110 * S, 195 * S - 1)
    assert not selection.covers(110 * S - 1, 120 * S)
    absolute = Selection.create(start=f"{150 * S}ns").resolved(0, 1)
    assert absolute.window.start_ns == 150 * S


def test_bad_input_is_refused() -> None:
    with pytest.raises(SelectionError, match="not a valid regular expression") as bad_regex:
        Selection.create(regex="(")
    assert bad_regex.value.field == "regex"
    with pytest.raises(SelectionError, match="empty time range"):
        Selection.create(start="5", end="5")
    with pytest.raises(SelectionError, match="bad --start"):
        Selection.create(start="yesterday")
