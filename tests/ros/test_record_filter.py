"""Topic selection as `ros2 bag record` does it: names, --all, --regex, --exclude, hidden."""

from __future__ import annotations

import pytest

from bagkit.ros.errors import RecorderOptionsError
from bagkit.ros.graph import TopicFilter

TOPICS = ["/imu/data", "/fusion/odometry", "/fusion/_debug", "/_internal/state", "/rosout"]


def selected(**options: object) -> list[str]:
    topic_filter = TopicFilter.create(**options)  # type: ignore[arg-type]
    return [t for t in TOPICS if topic_filter.matches(t)]


def test_named_topics_only_and_relative_names() -> None:
    assert selected(topics=["imu/data", "/_internal/state"]) == ["/imu/data", "/_internal/state"]


def test_all_leaves_hidden_topics_out_unless_asked() -> None:
    assert selected(all_topics=True) == ["/imu/data", "/fusion/odometry", "/rosout"]
    assert selected(all_topics=True, include_hidden=True) == TOPICS


def test_regex_searches_and_exclude_applies_to_it() -> None:
    assert selected(regex="fusion") == ["/fusion/odometry"]
    assert selected(regex="fusion", include_hidden=True) == ["/fusion/odometry", "/fusion/_debug"]
    assert selected(all_topics=True, exclude="^/(rosout|imu)") == ["/fusion/odometry"]
    # A named topic is recorded even when the exclude pattern matches it.
    assert selected(topics=["/rosout"], regex="imu", exclude="rosout|imu") == ["/rosout"]


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({}, "nothing to record"),
        ({"regex": "("}, "--regex"),
        ({"all_topics": True, "exclude": "["}, "--exclude"),
    ],
)
def test_bad_selection(options: dict[str, object], message: str) -> None:
    with pytest.raises(RecorderOptionsError, match=message):
        TopicFilter.create(**options)  # type: ignore[arg-type]
