"""The recorder's live health check (:class:`bagkit.health.live.LiveHealth`), fed the messages
of fusion's faults bag one batch at a time, breaks and clears where ``bagkit check`` (the bulk
evaluator over the whole bag) finds the contract broken."""

from __future__ import annotations

import itertools
import json
from pathlib import Path

import pytest

from bagkit.bag import BagReader, BagWriter, TopicInfo
from bagkit.health import HealthSpec, SpecError, check_bag
from bagkit.health.live import LiveHealth
from bagkit.recording.health_watch import HealthEvent

FAULTS = Path(__file__).parents[2] / "fixtures" / "faults" / "golden"
CONTRACT = """\
forbidden: [/alerts]
topics:
  /imu/data:
    type: sensor_msgs/msg/Imu
    rate: {min: 8, over: 2s}
    max_gap: 300ms
    never: [unchanged(linear_acceleration) for 1s]
  /gps/fix:
    never: [isnan(*)]
  /temperature:
    values:
      temperature: {min: -40, max: 50}
  /barometer/pressure:
    type: sensor_msgs/msg/Temperature
  /fusion/odometry:
    never:
      - delta(pose.pose.position.z) > 0.5
      - latency(/imu/data -> /fusion/odometry, header.stamp) > 1ms
      - age(header.stamp) > 1ms
  /not/recorded: {}
"""
# A dropout cut out of the IMU's stream: seconds after the bag's start.
SILENT = (24.0, 25.5)


def without_dropout(source: Path, target: Path) -> None:
    """``source`` with no /imu/data message inside SILENT (a sensor that fell silent)."""
    with BagReader(source) as reader, BagWriter(target) as writer:
        start = reader.start_ns
        silent = [start + int(s * 1e9) for s in SILENT]
        for info in reader.topics.values():
            writer.add_topic(info, definition=reader.definitions.get(info.type))
        for message in reader.messages():
            if message.topic == "/imu/data" and silent[0] <= message.log_time < silent[1]:
                continue
            writer.write(
                message.topic,
                message.data,
                log_time=message.log_time,
                publish_time=message.publish_time,
                sequence=message.sequence,
            )


def live_events(bag: Path, spec: HealthSpec) -> tuple[LiveHealth, list[HealthEvent]]:
    """Feed ``bag`` to a LiveHealth as the recorder does: per topic, batches of up to 5
    messages in log-time order, the clock advanced between batches."""
    told: list[HealthEvent] = []
    health = LiveHealth(spec, on_event=told.append)
    with BagReader(bag) as reader:
        for info in reader.topics.values():
            health.add_topic(info, reader.definitions[info.type])
        messages = list(reader.messages())
        end = reader.end_ns
    batches = itertools.groupby(enumerate(messages), key=lambda m: (m[1].topic, m[0] // 5))
    for (topic, _), group in batches:
        batch = [m for _, m in group]
        health.observe(topic, [m.data for m in batch], [m.log_time for m in batch])
        health.advance(batch[-1].log_time)
    health.finish(end)
    return health, told


@pytest.fixture(scope="module")
def dropout_bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    bag = tmp_path_factory.mktemp("live") / "dropout"
    without_dropout(FAULTS, bag)
    return bag


def test_breaks_and_clears_where_check_finds_the_episodes(dropout_bag: Path) -> None:
    spec = HealthSpec.parse(CONTRACT)
    health, told = live_events(dropout_bag, spec)
    bulk = check_bag(dropout_bag, spec)
    by_assertion = {(c.topic, c.assertion): c for c in health.counts}
    checked = 0
    for assertion in bulk.assertions:
        if assertion.what in ("present", "forbidden") or assertion.what.startswith("type"):
            continue
        episodes = [(int(s), int(e)) for s, e, _ in assertion.spans.tolist()]
        breaks = [e.at_ns for e in told if e.broken and e.assertion == assertion.what]
        clears = [e.at_ns for e in told if not e.broken and e.assertion == assertion.what]
        assert breaks == [s for s, _ in episodes], assertion.what
        # An episode still going on at the end is broken then, not cleared.
        assert clears == [e for _, e in episodes][: len(clears)], assertion.what
        count = by_assertion[(assertion.topic, assertion.what)]
        assert (count.breaks, count.clears) == (len(breaks), len(clears))
        checked += len(episodes)
    assert checked >= 5  # the dropout's gap and rate, stuck IMU, GPS NaN, temperature spike


def test_the_dropout_breaks_gap_and_rate_while_silent(dropout_bag: Path) -> None:
    _, told = live_events(dropout_bag, HealthSpec.parse(CONTRACT))
    with BagReader(dropout_bag) as reader:
        start = reader.start_ns
    gap = [e for e in told if e.assertion == "gap > 300ms"]
    assert [e.broken for e in gap] == [True, False]
    # From the last sample before the silence to the first after it (10 Hz IMU).
    assert SILENT[0] - 0.1 <= (gap[0].at_ns - start) / 1e9 <= SILENT[0]
    assert SILENT[1] <= (gap[1].at_ns - start) / 1e9 <= SILENT[1] + 0.1
    assert any(e.broken for e in told if e.assertion.startswith("rate < 8"))


def test_presence_type_and_forbidden_topics_break_and_stay_broken(dropout_bag: Path) -> None:
    health, told = live_events(dropout_bag, HealthSpec.parse(CONTRACT))
    broken_at_end = {(c.topic, c.assertion) for c in health.counts if c.broken_since_ns is not None}
    assert broken_at_end == {
        ("/alerts", "forbidden"),
        ("/barometer/pressure", "type sensor_msgs/msg/Temperature"),
        ("/not/recorded", "present"),
    }
    summary = json.loads(json.dumps([c.to_dict() for c in health.counts]))
    assert {(s["topic"], s["assertion"]) for s in summary if s["broken"]} == broken_at_end
    assert all(e.line().startswith("health: ") for e in told)


def test_a_field_the_type_lacks_is_a_spec_error() -> None:
    spec = HealthSpec.parse("topics:\n  /imu/data:\n    never: [isnan(linear_accel.z)]\n")
    health = LiveHealth(spec)
    with BagReader(FAULTS) as reader:
        info: TopicInfo = reader.topics["/imu/data"]
        with pytest.raises(SpecError, match="linear_accel"):
            health.add_topic(info, reader.definitions[info.type])


def test_a_value_out_of_bounds_to_the_last_message_is_broken_at_the_end(tmp_path: Path) -> None:
    """The recording ends (later than the last message) while every GPS stamp is out of
    bounds: the check stays broken, it is not told as cleared."""
    spec = HealthSpec.parse("topics:\n  /gps/fix:\n    values:\n      header.stamp.sec: {max: 0}\n")
    told: list[HealthEvent] = []
    health = LiveHealth(spec, on_event=told.append)
    with BagReader(FAULTS) as reader:
        info = reader.topics["/gps/fix"]
        health.add_topic(info, reader.definitions[info.type])
        gps = [m for m in reader.messages() if m.topic == "/gps/fix"]
        end = reader.end_ns + 2_000_000_000  # Ctrl-C two seconds after the bag's last message
    health.observe("/gps/fix", [m.data for m in gps], [m.log_time for m in gps])
    health.finish(end)
    assert [(e.broken, e.at_ns) for e in told] == [(True, gps[0].log_time)]
    (count,) = [c for c in health.counts if c.assertion.startswith("header")]
    assert (count.breaks, count.clears, count.broken_since_ns) == (1, 0, gps[0].log_time)


def test_messages_that_do_not_decode_go_on_as_check_reads_them(tmp_path: Path) -> None:
    """A publisher's payloads that do not decode (cut short) do not stop the live check (it
    raised, and the recorder stopped the recording): never matched, no silence, and the same
    episodes as ``bagkit check`` finds in the bag."""
    from rosbags.typesys import Stores, get_typestore

    store, kind = get_typestore(Stores.ROS2_JAZZY), "sensor_msgs/msg/Temperature"
    t = store.types
    bag = tmp_path / "cut"
    with BagWriter(bag) as writer:
        writer.add_topic(TopicInfo("/temp", kind))
        for i in range(40):  # 10 Hz; payloads cut short from 1.0 to 2.0 s, a spike at 3.0 s
            ns = 1_700_000_000_000_000_000 + i * 100_000_000
            stamp = t["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9)
            header = t["std_msgs/msg/Header"](stamp=stamp, frame_id="t")
            value = 500.0 if i == 30 else 20.0 + i
            data = bytes(store.serialize_cdr(t[kind](header, value, 0.0), kind))
            writer.write("/temp", data[:10] if 10 <= i < 20 else data, log_time=ns)
    spec = HealthSpec.parse(
        "topics:\n  /temp:\n    max_gap: 150ms\n"
        "    never: [temperature > 100, unchanged(temperature) for 1s, delta(temperature) > 50]\n"
    )
    _, told = live_events(bag, spec)
    bulk = check_bag(bag, spec)
    for assertion in bulk.assertions[1:]:
        breaks = [e.at_ns for e in told if e.broken and e.assertion == assertion.what]
        assert breaks == [int(s) for s, _, _ in assertion.spans.tolist()], assertion.what
    spike = 1_700_000_000_000_000_000 + 30 * 100_000_000
    assert sorted((e.assertion, e.at_ns) for e in told if e.broken) == [
        ("delta(temperature) > 50", spike),  # and the message after it: one episode
        ("temperature > 100", spike),
    ]
