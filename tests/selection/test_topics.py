"""Topic selection for record and replay, as `ros2 bag` does it: names, --all, --regex,
--exclude, hidden (pure: no middleware involved)."""

from __future__ import annotations

import pytest

from bagkit.selection.errors import SelectionError
from bagkit.selection.topics import TopicSelection, is_hidden

TOPICS = ["/imu/data", "/fusion/odometry", "/fusion/_debug", "/_internal/state", "/rosout"]


def selected(**options: object) -> list[str]:
    selection = TopicSelection.create(**options)  # type: ignore[arg-type]
    return [t for t in TOPICS if selection.matches(t)]


def test_named_topics_only_and_relative_names() -> None:
    assert selected(topics=["imu/data", "/_internal/state"]) == ["/imu/data", "/_internal/state"]


def test_all_leaves_hidden_topics_out_unless_asked() -> None:
    assert selected(all_topics=True) == ["/imu/data", "/fusion/odometry", "/rosout"]
    assert selected(all_topics=True, include_hidden=True) == TOPICS


def test_regex_searches_and_exclude_applies_to_it() -> None:
    assert selected(regex="fusion") == ["/fusion/odometry"]
    assert selected(regex="fusion", include_hidden=True) == ["/fusion/odometry", "/fusion/_debug"]
    assert selected(all_topics=True, exclude="^/(rosout|imu)") == ["/fusion/odometry"]
    # As ros2 bag's --exclude-regex: it works on top of named topics too.
    assert selected(topics=["/rosout"], regex="imu", exclude="rosout|imu") == []
    assert selected(topics=["/rosout", "/imu/data"], exclude="imu") == ["/rosout"]


def test_hidden_is_any_component_starting_with_underscore() -> None:
    assert [t for t in TOPICS if is_hidden(t)] == ["/fusion/_debug", "/_internal/state"]
    assert not is_hidden("/a_b/c_")


def test_missing_named_topics() -> None:
    selection = TopicSelection.create(["/imu/data", "gps/fix"], regex="x")
    assert selection.missing(TOPICS) == ["/gps/fix"]
    assert not selection.empty
    assert TopicSelection.create().empty


@pytest.mark.parametrize(
    ("options", "field"),
    [
        ({"regex": "("}, "regex"),
        ({"all_topics": True, "exclude": "["}, "exclude_regex"),
    ],
)
def test_bad_selection(options: dict[str, object], field: str) -> None:
    with pytest.raises(SelectionError) as raised:
        TopicSelection.create(**options)  # type: ignore[arg-type]
    assert raised.value.field == field and "--" not in str(raised.value)
