"""Live replay over DDS with the Player: a bag with known stamps, a real rclpy subscriber."""

from __future__ import annotations

import dataclasses
import itertools
import statistics
import time
from pathlib import Path

import pytest
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from replay_harness import (
    BAG_SPAN_NS,
    BAG_START_NS,
    NO_WAITS,
    SCHEDULE,
    STRING_TOPICS,
    Listener,
    clock_ns,
    known,
    payload,
    play,
    recorded,
)
from rosgraph_msgs.msg import Clock
from std_msgs.msg import String
from waiting import wait_for

from bagkit.bag import BagWriter, TopicInfo
from bagkit.bag.clock import clock_message
from bagkit.playback.options import PlayOptions
from bagkit.ros.qos import dump_offered_qos_profiles
from bagkit.ros.replay.player import Player
from bagkit.selection.times import NS_PER_S

pytestmark = pytest.mark.ros

# What the middleware adds to a message's way from the player's publish to the listener's
# reception, beyond the player's own lateness (a fraction of a millisecond measured here).
DELIVERY_JITTER_MS = 5.0


@pytest.mark.parametrize("rate", [1.0, 2.0, 0.5])
def test_every_message_in_order_with_the_recorded_pacing(
    test_bag: Path, listener_factory: type[Listener], rate: float
) -> None:
    expected = recorded(test_bag)
    listener = listener_factory(STRING_TOPICS)
    report = play(test_bag, rate=rate, waits=known(*SCHEDULE))
    got = listener.wait_for_count(len(expected))

    # Every message, first one included, in log-time order (one process, one writer: DDS keeps
    # the order per topic; across topics the arrival order follows the schedule).
    assert [(r.topic, r.data) for r in got] == [(t, d) for t, d, _ in expected]
    assert report.messages == len(expected)
    assert {t.topic: t.messages for t in report.topics} == {
        topic: sum(1 for t, _, _ in expected if t == topic) for topic in SCHEDULE
    }
    # Inter-arrival times follow the recorded gaps divided by the rate, as far as the player
    # kept its schedule: a loaded machine preempts it (its lateness rose with the load while
    # the arrivals followed it to the tenth of a millisecond), and its deadlines are absolute,
    # so a stall delays a few messages and the schedule does not drift.
    # benchmarks/bench_replay.py holds the sub-millisecond bounds on a quiet machine.
    log_times = [log for _, _, log in expected]
    errors_ms = [
        ((b.received_ns - a.received_ns) - (tb - ta) / rate) / 1e6
        for (a, b), (ta, tb) in zip(
            itertools.pairwise(got), itertools.pairwise(log_times), strict=True
        )
    ]
    kept_ms = report.lateness.max_ms + DELIVERY_JITTER_MS
    assert max(abs(e) for e in errors_ms) <= kept_ms, (errors_ms, report.lateness)
    span_s = (got[-1].received_ns - got[0].received_ns) / 1e9
    expected_span_s = (expected[-1][2] - expected[0][2]) / 1e9 / rate
    assert abs(span_s - expected_span_s) * 1e3 <= kept_ms, (span_s, report.lateness)
    assert report.wall_duration_s >= expected_span_s  # the last message was not early


def test_start_offset_and_duration_select_a_window_of_bag_time(
    test_bag: Path, listener_factory: type[Listener]
) -> None:
    window = (BAG_START_NS + 300_000_000, BAG_START_NS + 700_000_000)
    expected = [(t, d) for t, d, log in recorded(test_bag) if window[0] <= log < window[1]]
    listener = listener_factory(STRING_TOPICS)
    report = play(
        test_bag, rate=4.0, start_offset=0.3, duration_ns=400_000_000, waits=known(*SCHEDULE)
    )
    got = listener.wait_for_count(len(expected))
    assert [(r.topic, r.data) for r in got] == expected
    assert report.bag_duration_s == pytest.approx(0.35)  # last message at +650 ms


def test_topic_selection_regex_and_exclude(
    test_bag: Path, listener_factory: type[Listener]
) -> None:
    fast = [(t, d) for t, d, _ in recorded(test_bag, ["/replay/fast"])]
    slow = [(t, d) for t, d, _ in recorded(test_bag, ["/replay/slow"])]
    for options, expected in [
        ({"topics": ("/replay/fast",)}, fast),
        ({"exclude_regex": "fast$"}, slow),
        (
            {"regex": "^/replay/s", "topics": ("/replay/fast",)},
            sorted(fast + slow, key=_order(test_bag)),
        ),
    ]:
        listener = listener_factory(STRING_TOPICS)
        report = play(test_bag, rate=10.0, waits=known(*SCHEDULE), **options)
        got = listener.wait_for_count(len(expected))
        assert [(r.topic, r.data) for r in got] == expected, options
        assert report.messages == len(expected)
        listener.close()


def _order(bag: Path) -> object:
    position = {(t, d): i for i, (t, d, _) in enumerate(recorded(bag))}
    return lambda item: position[item]


def test_remap_publishes_under_the_new_name(
    test_bag: Path, listener_factory: type[Listener]
) -> None:
    fast = [d for _, d, _ in recorded(test_bag, ["/replay/fast"])]
    listener = listener_factory({"/renamed": String, "/replay/fast": String})
    report = play(
        test_bag,
        rate=10.0,
        topics=("/replay/fast",),
        remap={"/replay/fast": "/renamed"},
        waits=known("/renamed", "/replay/fast"),
    )
    got = listener.wait_for_count(len(fast))
    assert [r.data for r in got if r.topic == "/renamed"] == fast
    assert not listener.messages("/replay/fast")
    assert [(t.topic, t.published_as) for t in report.topics] == [("/replay/fast", "/renamed")]


def test_loops_and_delay(test_bag: Path, listener_factory: type[Listener]) -> None:
    expected = [(t, d) for t, d, _ in recorded(test_bag)]
    listener = listener_factory(STRING_TOPICS)
    options = PlayOptions(
        test_bag, rate=5.0, loops=2, delay_ns=NS_PER_S // 2, waits=known(*SCHEDULE)
    )
    with Player(options) as player:
        player.wait_until_matched()
        player.waits = dataclasses.replace(player.waits, before_start=False, topics=())
        started_ns = time.time_ns()
        report = player.play()
    got = listener.wait_for_count(2 * len(expected))
    assert [(r.topic, r.data) for r in got] == expected * 2
    assert report.loops == 2
    # Each pass starts with the delay: the first message 0.5 s after play(), the second pass
    # 0.5 s after the first one ended.
    first_pass_end = got[len(expected) - 1].received_ns
    assert 0.5 <= (got[0].received_ns - started_ns) / 1e9 < 1.0
    assert 0.5 <= (got[len(expected)].received_ns - first_pass_end) / 1e9 < 1.0


def test_clock_runs_in_bag_time_before_each_message(
    test_bag: Path, listener_factory: type[Listener]
) -> None:
    rate = 2.0
    listener = listener_factory({**STRING_TOPICS, "/clock": Clock})
    report = play(test_bag, rate=rate, clock_hz=50.0, waits=known(*SCHEDULE, "/clock"))
    expected = recorded(test_bag)
    listener.wait_for_count(len(expected))
    clock = [(r, clock_ns(r.data)) for r in listener.messages("/clock")]
    stamps = [ns for _, ns in clock]
    assert stamps == sorted(stamps)
    assert stamps[0] == BAG_START_NS
    # Every message's log time was published on /clock just before it.
    assert {log for _, _, log in expected} <= set(stamps)
    # Between messages the clock ticks at ~50 Hz of wall time, advancing by rate x wall time.
    ticks = [(r.received_ns, ns) for r, ns in clock if (ns - BAG_START_NS) % 50_000_000]
    assert len(ticks) >= 0.5 * 50 * (BAG_SPAN_NS / 1e9 / rate)
    # Reception is late by however long the listener was not scheduled (70 ms at load 6, in
    # bursts): the median slope over pairs half the run apart ignores such stalls.
    half = len(ticks) // 2
    pairs = zip(ticks[: len(ticks) - half], ticks[half:], strict=True)
    slopes = [(b1 - b0) / (w1 - w0) for (w0, b0), (w1, b1) in pairs]
    assert statistics.median(slopes) == pytest.approx(rate, rel=0.05)
    assert report.messages == len(expected)


def test_publishers_take_the_recorded_qos_or_the_overrides(node: Node, tmp_path: Path) -> None:
    latched = QoSProfile(
        depth=3, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
    )
    lossy = QoSProfile(depth=7, reliability=ReliabilityPolicy.BEST_EFFORT)
    bag = tmp_path / "qos"
    with BagWriter(bag) as writer:
        for topic, profile in [("/latched", latched), ("/lossy", lossy), ("/plain", lossy)]:
            offered = dump_offered_qos_profiles([profile])
            writer.add_topic(TopicInfo(topic, "std_msgs/msg/String", offered_qos_profiles=offered))
            writer.write(topic, payload(topic, 0), log_time=BAG_START_NS)
    overrides = tmp_path / "overrides.yaml"
    overrides.write_text("/plain:\n  reliability: reliable\n  history: keep_last\n  depth: 42\n")

    def offered_by_the_player(topic: str) -> list[QoSProfile]:
        infos = node.get_publishers_info_by_topic(topic)
        return [i.qos_profile for i in infos if i.node_name == "bagkit_player"]

    with Player(PlayOptions(bag, qos_overrides=overrides, waits=NO_WAITS)):
        # What DDS discovery tells of a publisher: reliability and durability, not the depth
        # (test_qos.py checks the depths replay_publisher_qos and the overrides give).
        wait_for(lambda: all(offered_by_the_player(t) for t in ("/latched", "/lossy", "/plain")))
        offered = {t: offered_by_the_player(t)[0] for t in ("/latched", "/lossy", "/plain")}
    assert offered["/latched"].durability == DurabilityPolicy.TRANSIENT_LOCAL
    assert offered["/latched"].reliability == ReliabilityPolicy.RELIABLE
    assert offered["/lossy"].reliability == ReliabilityPolicy.BEST_EFFORT
    assert offered["/lossy"].durability == DurabilityPolicy.VOLATILE
    # Recorded best effort; the override makes it reliable.
    assert offered["/plain"].reliability == ReliabilityPolicy.RELIABLE


def test_a_recorded_clock_is_not_replayed_with_clock_on(tmp_path: Path) -> None:
    bag = tmp_path / "with_clock"
    with BagWriter(bag) as writer:
        writer.add_topic(TopicInfo("/clock", "rosgraph_msgs/msg/Clock"))
        writer.add_topic(TopicInfo("/replay/fast", "std_msgs/msg/String"))
        writer.write("/clock", clock_message(BAG_START_NS), log_time=BAG_START_NS)
        writer.write("/replay/fast", payload("/replay/fast", 0), log_time=BAG_START_NS)
    for clock_hz, replayed in ((100.0, ["/replay/fast"]), (None, ["/clock", "/replay/fast"])):
        options = PlayOptions(bag, clock_hz=clock_hz, waits=NO_WAITS)
        report = Player(options).run()
        assert sorted(t.topic for t in report.topics) == replayed
        assert report.messages == len(replayed)


def test_looping_keeps_the_lateness_samples_bounded(
    test_bag: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from bagkit.playback import lateness

    kept: list[lateness.LatenessSamples] = []

    class Spied(lateness.LatenessSamples):
        def __init__(self) -> None:
            super().__init__()
            kept.append(self)

    monkeypatch.setattr(lateness, "LATENESS_SAMPLES", 50)
    monkeypatch.setattr(lateness, "LatenessSamples", Spied)  # the player imports it at play()
    per_pass = len(recorded(test_bag))
    report = play(test_bag, rate=100.0, loops=20, waits=NO_WAITS)
    assert report.loops == 20
    assert report.messages == 20 * per_pass > 50
    (samples,) = kept
    assert samples.count == report.messages
    assert len(samples.samples) == 50  # what is retained does not grow with the passes
