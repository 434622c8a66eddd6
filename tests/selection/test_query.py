"""The one query: parsed once, resolved against each bag once (names, window, warning)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import pytest

from bagkit.selection.conditions import Condition
from bagkit.selection.errors import SelectionError, UnknownTopicError
from bagkit.selection.query import Query, resolve_names
from bagkit.selection.topics import missing_on_graph
from bagkit.selection.windows import Window

S = 1_000_000_000


@dataclass(frozen=True)
class Topic:
    type: str


@dataclass(frozen=True)
class Outline:
    """A bag as a query sees it: topics with types and a span (no file anywhere)."""

    topics: Mapping[str, Topic] = field(default_factory=dict)
    start_ns: int = 100 * S
    end_ns: int = 200 * S
    message_count: int = 10


BAG = Outline(
    {
        "/imu/data": Topic("sensor_msgs/msg/Imu"),
        "/gps/fix": Topic("sensor_msgs/msg/NavSatFix"),
        "/reset/_service_event": Topic("std_srvs/srv/Trigger_Event"),
        "/fib/_action/feedback": Topic("example/action/Fib_FeedbackMessage"),
        "/fib/_action/status": Topic("action_msgs/msg/GoalStatusArray"),
        "relative/name": Topic("std_msgs/msg/String"),
    }
)


def test_a_query_parses_its_times_and_condition_once() -> None:
    query = Query.create("/imu/data", ["linear_acceleration.*"], "10", "-5", "header.stamp.sec > 0")
    assert query.topics == ("/imu/data",) and query.fields == ("linear_acceleration.*",)
    assert isinstance(query.where, Condition) and query.where.text == "header.stamp.sec > 0"
    assert query.span.bounded and Query().span.bounded is False
    with pytest.raises(SelectionError, match="bad start"):
        Query.create(start="1O", prefix="")
    with pytest.raises(SelectionError):
        Query.create(where="x >")


def test_resolution_gives_the_window_in_the_bags_log_times() -> None:
    resolved = Query.create(start="10", end="-5").resolve(BAG)
    assert resolved.window == Window(BAG.start_ns + 10 * S, BAG.end_ns - 5 * S)
    assert resolved.outside is None and resolved.topics == ()
    assert resolved.selects("/anything")


def test_names_resolve_to_what_the_bag_stores() -> None:
    topic_types = {name: info.type for name, info in BAG.topics.items()}
    assert resolve_names(["imu/data", "/relative/name"], topic_types) == (
        "/imu/data",
        "relative/name",
    )
    assert resolve_names(["/reset"], topic_types) == ("/reset/_service_event",)
    assert resolve_names(["fib", "/imu/data", "/imu/data"], topic_types) == (
        "/fib/_action/feedback",
        "/fib/_action/status",
        "/imu/data",
    )
    resolved = Query.create(["/reset", "/gps/fix"]).resolve(BAG)
    assert resolved.selects("/reset/_service_event") and not resolved.selects("/imu/data")


@pytest.mark.parametrize(
    ("typed", "guess"),
    [("/imu/dat", "/imu/data"), ("/rest", "/reset"), ("/fibb", "/fib"), ("/gps/fx", "/gps/fix")],
)
def test_an_unknown_name_names_the_closest_topic_service_or_action(typed: str, guess: str) -> None:
    with pytest.raises(UnknownTopicError) as caught:
        Query.create(typed).resolve(BAG)
    message = str(caught.value)
    assert message.startswith(f"topic {typed} not in the bag (did you mean {guess}")


def test_a_window_outside_the_bag_is_the_one_warning() -> None:
    resolved = Query.create(start="1000", end="1010").resolve(BAG, label="flight1")
    assert resolved.outside is not None
    assert resolved.outside.startswith("flight1: the time window [")
    assert "holds no message (the bag spans" in resolved.outside
    empty = Outline(BAG.topics, message_count=0)
    assert Query.create(start="1000").resolve(empty).outside is None  # nothing to miss


def test_with_topics_keeps_the_rest() -> None:
    query = Query.create(["/a"], ["x"], "1", None, "x > 1")
    moved = query.with_topics("/imu/data")
    assert moved.topics == ("/imu/data",) and (moved.fields, moved.span, moved.where) == (
        query.fields,
        query.span,
        query.where,
    )


def test_a_topic_that_never_appeared_names_the_closest_on_the_graph() -> None:
    line = missing_on_graph(["/imu/dat"], ["/rosout", "/imu/data", "/parameter_events"])
    assert line.startswith("topic /imu/dat never appeared on the graph (did you mean /imu/data?")
