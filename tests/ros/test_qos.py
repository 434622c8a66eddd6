"""QoS helpers: rosbag2 YAML in both encodings, adapted profiles, override files."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
import yaml
from rclpy.duration import Duration
from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    LivelinessPolicy,
    QoSCompatibility,
    QoSProfile,
    ReliabilityPolicy,
    qos_check_compatible,
    qos_profile_sensor_data,
)

from bagkit.bag import TopicInfo
from bagkit.ros.errors import QosProfileError
from bagkit.ros.qos import (
    HISTORY_BUDGET_BYTES,
    HISTORY_WINDOW_S,
    INFINITE_NS,
    REPLAY_DEPTH,
    adapt_publisher_qos,
    adapt_subscription_qos,
    dump_offered_qos_profiles,
    load_qos_overrides,
    parse_offered_qos_profiles,
    publisher_qos,
    replay_publisher_qos,
)


def _offer(**policies: object) -> QoSProfile:
    """A profile as the graph reports it: every policy resolved, none "system default"."""
    return QoSProfile(liveliness=LivelinessPolicy.AUTOMATIC, **policies)


RELIABLE = _offer(history=HistoryPolicy.KEEP_LAST, depth=7)
BEST_EFFORT = _offer(depth=5, reliability=ReliabilityPolicy.BEST_EFFORT)
LATCHED = _offer(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)


def test_jazzy_string_form_round_trips() -> None:
    profiles = [RELIABLE, qos_profile_sensor_data, LATCHED]
    text = dump_offered_qos_profiles(profiles)
    items = yaml.safe_load(text)
    assert [i["reliability"] for i in items] == ["reliable", "best_effort", "reliable"]
    assert [i["durability"] for i in items] == ["volatile", "volatile", "transient_local"]
    assert parse_offered_qos_profiles(text) == profiles


def test_integer_form_round_trips() -> None:
    text = dump_offered_qos_profiles([BEST_EFFORT, LATCHED], version=8)
    items = yaml.safe_load(text)
    assert items[0]["reliability"] == int(ReliabilityPolicy.BEST_EFFORT)
    assert items[1]["durability"] == int(DurabilityPolicy.TRANSIENT_LOCAL)
    parsed = parse_offered_qos_profiles(text)
    assert parsed[0].reliability == ReliabilityPolicy.BEST_EFFORT
    assert parsed[1].durability == DurabilityPolicy.TRANSIENT_LOCAL


def test_rosbag2_metadata_profiles_parse(interop_dir: Path) -> None:
    """Every offered_qos_profiles string in the rosbag2 test bags parses."""
    parsed = 0
    for metadata in sorted(interop_dir.rglob("metadata.yaml")):
        info = yaml.safe_load(metadata.read_text())["rosbag2_bagfile_information"]
        for topic in info.get("topics_with_message_count", []):
            text = topic["topic_metadata"].get("offered_qos_profiles", "")
            for profile in parse_offered_qos_profiles(text):
                parsed += 1
                assert profile.reliability in {
                    ReliabilityPolicy.RELIABLE,
                    ReliabilityPolicy.BEST_EFFORT,
                    ReliabilityPolicy.SYSTEM_DEFAULT,
                }
    assert parsed > 10


def test_infinite_durations_from_foxy_and_jazzy() -> None:
    text = """
- history: 1
  depth: 10
  reliability: 1
  durability: 2
  deadline: {sec: 2147483647, nsec: 4294967295}
  lifespan: {sec: 9223372036, nsec: 854775807}
  liveliness: 1
  liveliness_lease_duration: {sec: 2147483647, nsec: 2147483647}
  avoid_ros_namespace_conventions: false
"""
    (profile,) = parse_offered_qos_profiles(text)
    assert profile.deadline.nanoseconds == INFINITE_NS
    assert profile.lifespan.nanoseconds == INFINITE_NS
    assert profile.liveliness_lease_duration.nanoseconds == INFINITE_NS
    assert profile.depth == 10


def test_bad_yaml_is_a_qos_error() -> None:
    with pytest.raises(QosProfileError):
        parse_offered_qos_profiles("- history: keep_sometimes\n  depth: 1\n")
    with pytest.raises(QosProfileError):
        parse_offered_qos_profiles("just a string")
    assert parse_offered_qos_profiles("") == []


@pytest.mark.parametrize(
    ("offers", "reliability", "durability"),
    [
        ([RELIABLE, RELIABLE], ReliabilityPolicy.RELIABLE, DurabilityPolicy.VOLATILE),
        ([RELIABLE, BEST_EFFORT], ReliabilityPolicy.BEST_EFFORT, DurabilityPolicy.VOLATILE),
        ([LATCHED], ReliabilityPolicy.RELIABLE, DurabilityPolicy.TRANSIENT_LOCAL),
        ([LATCHED, RELIABLE], ReliabilityPolicy.RELIABLE, DurabilityPolicy.VOLATILE),
    ],
)
def test_subscription_matches_every_offer(
    offers: list[QoSProfile], reliability: ReliabilityPolicy, durability: DurabilityPolicy
) -> None:
    request = adapt_subscription_qos(offers)
    assert (request.reliability, request.durability) == (reliability, durability)
    if reliability == ReliabilityPolicy.RELIABLE:
        # Flow control instead of reader-side drops.
        assert request.history == HistoryPolicy.KEEP_ALL
    else:
        assert (request.history, request.depth) == (HistoryPolicy.KEEP_LAST, 1000)
    for offer in offers:
        compatibility, reason = qos_check_compatible(offer, request)
        assert compatibility == QoSCompatibility.OK, reason


def test_publisher_offer_satisfies_every_recorded_subscriber() -> None:
    """The replay publisher is accepted by whatever matched any of the recorded publishers."""
    deadline = _offer(depth=3, deadline=Duration(seconds=0.5))
    offers = [BEST_EFFORT, LATCHED, deadline]
    offer = adapt_publisher_qos(offers)
    assert offer.reliability == ReliabilityPolicy.RELIABLE
    assert offer.durability == DurabilityPolicy.TRANSIENT_LOCAL
    assert offer.deadline.nanoseconds == 500_000_000
    assert offer.depth == 5
    for recorded in offers:
        # Each recorded publisher's own offer stands for the strictest request it accepted.
        request = _offer(
            depth=1,
            reliability=recorded.reliability,
            durability=recorded.durability,
            deadline=recorded.deadline,
        )
        compatibility, reason = qos_check_compatible(offer, request)
        assert compatibility == QoSCompatibility.OK, reason


def test_publisher_qos_from_topic_info_and_override() -> None:
    info = TopicInfo(
        "/t", "std_msgs/msg/String", offered_qos_profiles=dump_offered_qos_profiles([LATCHED])
    )
    profile = publisher_qos(info)
    assert profile.durability == DurabilityPolicy.TRANSIENT_LOCAL
    assert profile.depth == 1
    assert publisher_qos(info, BEST_EFFORT) is BEST_EFFORT
    assert (
        publisher_qos(TopicInfo("/u", "std_msgs/msg/String")).reliability
        == ReliabilityPolicy.RELIABLE
    )
    with pytest.raises(QosProfileError, match="/v"):
        publisher_qos(TopicInfo("/v", "std_msgs/msg/String", offered_qos_profiles="[1, 2]"))


def test_load_overrides_in_ros2_bag_format(tmp_path: Path) -> None:
    path = tmp_path / "overrides.yaml"
    path.write_text(
        """
/camera:
  reliability: best_effort
  history: keep_all
/map:
  durability: TRANSIENT_LOCAL
  depth: 3
  deadline: {sec: 1, nsec: 500}
  liveliness: manual_by_topic
"""
    )
    overrides = load_qos_overrides(path)
    assert overrides["/camera"].reliability == ReliabilityPolicy.BEST_EFFORT
    assert overrides["/camera"].history == HistoryPolicy.KEEP_ALL
    assert overrides["/map"].durability == DurabilityPolicy.TRANSIENT_LOCAL
    assert overrides["/map"].depth == 3
    assert overrides["/map"].deadline.nanoseconds == 1_000_000_500
    assert overrides["/map"].liveliness == LivelinessPolicy.MANUAL_BY_TOPIC
    assert overrides["/map"].reliability == ReliabilityPolicy.RELIABLE


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("/a:\n  reliability: mostly\n", "bad reliability"),
        ("/a:\n  speed: 3\n", "unknown QoS setting"),
        ("/a:\n  deadline: 5\n", "bad deadline"),
        ("- /a\n", "expected a mapping"),
        ("/a: [\n", "not YAML"),
        # Loaded without limits: a RecursionError, exit 70.
        ("/a: " + "[" * 30_000 + "]" * 30_000 + "\n", "nested deeper than 64"),
        ("/a: &x {}\n/b: *x\n", "aliases are not accepted"),
        (b"/a\xff: {}\n", "not UTF-8 \\(byte 2\\)"),  # was UnicodeDecodeError, exit 70
    ],
)
def test_bad_overrides_name_the_problem(tmp_path: Path, text: str | bytes, message: str) -> None:
    path = tmp_path / "overrides.yaml"
    path.write_bytes(text if isinstance(text, bytes) else text.encode())
    with pytest.raises(QosProfileError, match=message):
        load_qos_overrides(path)


def test_missing_overrides_file(tmp_path: Path) -> None:
    with pytest.raises(QosProfileError, match="cannot read"):
        load_qos_overrides(tmp_path / "nope.yaml")


def test_replay_history_covers_the_messages_in_flight_only() -> None:
    def depth(offer: QoSProfile, messages_per_s: float, *, count: int = 50_000) -> QoSProfile:
        info = TopicInfo(
            "/t", "std_msgs/msg/String", offered_qos_profiles=dump_offered_qos_profiles([offer])
        )
        return replay_publisher_qos(info, count=count, mean_size=100, messages_per_s=messages_per_s)

    # A 250 Hz topic: at rate 1 the floor, at rate 10 a window of it, as fast as possible all
    # of it (within the memory budget).
    assert depth(RELIABLE, 250.0).depth == REPLAY_DEPTH
    assert depth(RELIABLE, 2500.0).depth == round(2500 * HISTORY_WINDOW_S) > REPLAY_DEPTH
    assert depth(RELIABLE, math.inf).depth == 50_000
    assert depth(RELIABLE, math.inf, count=10**9).depth == HISTORY_BUDGET_BYTES // 100
    # A deeper recorded history is kept; the rest of the offer is the recorded one.
    deep = depth(_offer(history=HistoryPolicy.KEEP_LAST, depth=5000), 250.0)
    assert (deep.depth, deep.reliability) == (5000, ReliabilityPolicy.RELIABLE)
    assert depth(BEST_EFFORT, 2500.0).reliability == ReliabilityPolicy.BEST_EFFORT
    # What a late subscriber of a latched topic gets is the recorded depth, however fast.
    assert depth(LATCHED, math.inf).depth == 1
    assert depth(_offer(history=HistoryPolicy.KEEP_ALL), 2500.0).history == HistoryPolicy.KEEP_ALL


def test_qos_text_from_a_bag_is_parsed_with_the_untrusted_yaml_limits() -> None:
    bomb = "a: &a [x, x, x, x, x, x, x, x, x]\nb: &b [*a, *a, *a, *a, *a, *a, *a, *a, *a]\n"
    with pytest.raises(QosProfileError, match="alias"):
        parse_offered_qos_profiles(bomb)
    with pytest.raises(QosProfileError, match="nest"):
        parse_offered_qos_profiles("[" * 30_000)
