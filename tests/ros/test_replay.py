"""Live replay over DDS: a bag with known stamps, a real rclpy subscriber, the real CLI."""

from __future__ import annotations

import dataclasses
import itertools
import json
import os
import shutil
import signal
import statistics
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
import rclpy
from rclpy.context import Context
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message, serialize_message
from rosgraph_msgs.msg import Clock
from std_msgs.msg import String

from bagkit.bag import BagReader, BagWriter, TopicInfo
from bagkit.ros.clock import clock_message
from bagkit.ros.player import Player, play
from bagkit.ros.qos import REPLAY_DEPTH, dump_offered_qos_profiles

pytestmark = pytest.mark.ros

BAG_START_NS = 1_700_000_000_000_000_000
# Two topics on different grids so that their messages interleave: 20 Hz and 10 Hz for 1 s.
SCHEDULE = {"/replay/fast": 50_000_000, "/replay/slow": 100_000_000}
BAG_SPAN_NS = 1_000_000_000


@dataclass(frozen=True, slots=True)
class Received:
    topic: str
    data: bytes
    received_ns: int
    """Reception time stamped by the middleware (system clock), independent of our GIL."""

    @property
    def text(self) -> str:
        return str(deserialize_message(self.data, String).data)


class Listener:
    """Raw subscriptions in a context of their own; a thread drains them without deserializing."""

    def __init__(self, topics: dict[str, type]) -> None:
        self.context = Context()
        rclpy.init(context=self.context)
        self.node = Node("replay_listener", context=self.context)
        reliable = QoSProfile(depth=10_000, reliability=ReliabilityPolicy.RELIABLE)
        # /clock is offered best effort (as rosbag2 does); subscribe like a use_sim_time node.
        best_effort = QoSProfile(depth=10_000, reliability=ReliabilityPolicy.BEST_EFFORT)
        self.subscriptions = [
            (
                topic,
                message_type,
                self.node.create_subscription(
                    message_type,
                    topic,
                    _ignore,
                    best_effort if topic == "/clock" else reliable,
                    raw=True,
                ),
            )
            for topic, message_type in topics.items()
        ]
        self.received: list[Received] = []
        self._lock = threading.Lock()
        self._running = True
        self._thread = threading.Thread(target=self._drain, daemon=True)
        self._thread.start()

    def _drain(self) -> None:
        while self._running:
            for topic, message_type, subscription in self.subscriptions:
                while (taken := subscription.handle.take_message(message_type, True)) is not None:
                    data, info = taken
                    with self._lock:
                        self.received.append(Received(topic, data, info["received_timestamp"]))
            time.sleep(0.001)

    def messages(self, topic: str | None = None) -> list[Received]:
        """What arrived (on ``topic``), in order of reception across topics."""
        with self._lock:
            received = sorted(self.received, key=lambda r: r.received_ns)
        return [r for r in received if topic is None or r.topic == topic]

    def wait_for_count(self, count: int, timeout: float = 10.0) -> list[Received]:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline and len(self.messages()) < count:
            time.sleep(0.02)
        time.sleep(0.1)  # anything beyond the expected count would show up now
        return self.messages()

    def close(self) -> None:
        self._running = False
        self._thread.join()
        self.node.destroy_node()
        self.context.try_shutdown()


def _ignore(_: object) -> None:
    """Subscriptions are drained by the listener thread, never by an executor."""


@pytest.fixture
def listener_factory() -> Iterator[type[Listener]]:
    listeners: list[Listener] = []

    class Tracked(Listener):
        def __init__(self, topics: dict[str, type]) -> None:
            super().__init__(topics)
            listeners.append(self)

    yield Tracked
    for listener in listeners:
        listener.close()


def _payload(topic: str, index: int) -> bytes:
    return bytes(serialize_message(String(data=f"{topic}#{index}")))


def write_test_bag(path: Path, *, extra_topics: dict[str, str] | None = None) -> Path:
    """The known-stamp bag: SCHEDULE's topics over BAG_SPAN_NS; payload ``topic#index``."""
    with BagWriter(path) as writer:
        for topic in SCHEDULE:
            writer.add_topic(TopicInfo(topic, "std_msgs/msg/String"))
        for topic, type_name in (extra_topics or {}).items():
            writer.add_topic(TopicInfo(topic, type_name), definition="int32 value\n")
        stamps = sorted(
            (BAG_START_NS + offset, topic)
            for topic, period in SCHEDULE.items()
            for offset in range(0, BAG_SPAN_NS, period)
        )
        index = dict.fromkeys(SCHEDULE, 0)
        for log_time, topic in stamps:
            writer.write(topic, _payload(topic, index[topic]), log_time=log_time)
            index[topic] += 1
            for extra in extra_topics or {}:
                writer.write(extra, b"\x00\x01\x00\x00\x07\x00\x00\x00", log_time=log_time)
    return path


def recorded(bag: Path, topics: list[str] | None = None) -> list[tuple[str, bytes, int]]:
    """(topic, data, log_time) of every message of ``bag``, read back with the reader."""
    with BagReader(bag) as reader:
        return [(m.topic, m.data, m.log_time) for m in reader.messages(topics=topics)]


@pytest.fixture(scope="module")
def test_bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_test_bag(tmp_path_factory.mktemp("replay") / "known")


STRING_TOPICS = dict.fromkeys(SCHEDULE, String)
# The listeners are known: wait for them instead of watching the graph for 3 s (a subscription
# in this process is discovered at once; one in another process takes up to 3 s).
KNOWN = {"discovery_time": 0.0}
CLI_KNOWN = ["--discovery-time", "0"]


@pytest.mark.parametrize("rate", [1.0, 2.0, 0.5])
def test_every_message_in_order_with_the_recorded_pacing(
    test_bag: Path, listener_factory: type[Listener], rate: float
) -> None:
    expected = recorded(test_bag)
    listener = listener_factory(STRING_TOPICS)
    report = play(test_bag, rate=rate, wait_for=list(SCHEDULE), **KNOWN)
    got = listener.wait_for_count(len(expected))

    # Every message, first one included, in log-time order (one process, one writer: DDS keeps
    # the order per topic; across topics the arrival order follows the schedule).
    assert [(r.topic, r.data) for r in got] == [(t, d) for t, d, _ in expected]
    assert report.messages == len(expected)
    assert {t.topic: t.messages for t in report.topics} == {
        topic: sum(1 for t, _, _ in expected if t == topic) for topic in SCHEDULE
    }
    # Inter-arrival times follow the recorded gaps divided by the rate. CI-safe tolerances;
    # benchmarks/bench_replay.py holds the sub-millisecond bounds.
    log_times = [log for _, _, log in expected]
    errors_ms = [
        ((b.received_ns - a.received_ns) - (tb - ta) / rate) / 1e6
        for (a, b), (ta, tb) in zip(
            itertools.pairwise(got), itertools.pairwise(log_times), strict=True
        )
    ]
    # A busy 2-core CI box preempts the player now and then for tens of milliseconds; such a
    # stall delays a few arrivals but the schedule does not drift (the span holds).
    absolute = sorted(abs(e) for e in errors_ms)
    assert statistics.median(absolute) < 2.0, errors_ms
    assert absolute[int(0.9 * len(absolute))] < 10.0, errors_ms
    assert absolute[-1] < 150.0, errors_ms
    span_s = (got[-1].received_ns - got[0].received_ns) / 1e9
    expected_span_s = (expected[-1][2] - expected[0][2]) / 1e9 / rate
    assert span_s == pytest.approx(expected_span_s, abs=0.02)
    assert report.wall_duration_s == pytest.approx(expected_span_s, abs=0.05)


def test_start_offset_and_duration_select_a_window_of_bag_time(
    test_bag: Path, listener_factory: type[Listener]
) -> None:
    window = (BAG_START_NS + 300_000_000, BAG_START_NS + 700_000_000)
    expected = [(t, d) for t, d, log in recorded(test_bag) if window[0] <= log < window[1]]
    listener = listener_factory(STRING_TOPICS)
    report = play(
        test_bag, rate=4.0, start_offset=0.3, duration=0.4, wait_for=list(SCHEDULE), **KNOWN
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
        ({"topics": ["/replay/fast"]}, fast),
        ({"exclude": "fast$"}, slow),
        (
            {"regex": "^/replay/s", "topics": ["/replay/fast"]},
            sorted(fast + slow, key=_order(test_bag)),
        ),
    ]:
        listener = listener_factory(STRING_TOPICS)
        report = play(test_bag, rate=10.0, wait_for=list(SCHEDULE), **KNOWN, **options)
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
        topics=["/replay/fast"],
        remap={"/replay/fast": "/renamed"},
        wait_for=["/renamed", "/replay/fast"],
        **KNOWN,
    )
    got = listener.wait_for_count(len(fast))
    assert [r.data for r in got if r.topic == "/renamed"] == fast
    assert not listener.messages("/replay/fast")
    assert [(t.topic, t.published_as) for t in report.topics] == [("/replay/fast", "/renamed")]


def test_loops_and_delay(test_bag: Path, listener_factory: type[Listener]) -> None:
    expected = [(t, d) for t, d, _ in recorded(test_bag)]
    listener = listener_factory(STRING_TOPICS)
    with Player(test_bag, rate=5.0, loops=2, delay=0.5, wait_for=list(SCHEDULE), **KNOWN) as player:
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
    report = play(test_bag, rate=rate, clock_hz=50.0, wait_for=[*SCHEDULE, "/clock"], **KNOWN)
    expected = recorded(test_bag)
    listener.wait_for_count(len(expected))
    clock = [(r, _clock_ns(r.data)) for r in listener.messages("/clock")]
    stamps = [ns for _, ns in clock]
    assert stamps == sorted(stamps)
    assert stamps[0] == BAG_START_NS
    # Every message's log time was published on /clock just before it.
    assert {log for _, _, log in expected} <= set(stamps)
    # Between messages the clock ticks at ~50 Hz of wall time, advancing by rate x wall time.
    ticks = [(r.received_ns, ns) for r, ns in clock if (ns - BAG_START_NS) % 50_000_000]
    assert len(ticks) >= 0.5 * 50 * (BAG_SPAN_NS / 1e9 / rate)
    (w0, b0), (w1, b1) = ticks[0], ticks[-1]
    assert (b1 - b0) / (w1 - w0) == pytest.approx(rate, rel=0.05)
    assert report.messages == len(expected)


def _clock_ns(data: bytes) -> int:
    stamp = deserialize_message(data, Clock).clock
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def _bagkit(*args: str, timeout: float = 60.0) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [str(Path(sys.executable).with_name("bagkit")), *args],
        capture_output=True,
        text=True,
        timeout=timeout,
        check=False,
    )


def test_cli_replays_a_rosbag2_recording(
    interop_dir: Path, listener_factory: type[Listener]
) -> None:
    bag = interop_dir / "rosbag2_py/test/resources/mcap/talker"
    expected = [d for _, d, _ in recorded(bag, ["/topic"])]
    listener = listener_factory({"/topic": String})
    result = _bagkit(
        "replay",
        str(bag),
        "--rate",
        "10",
        "--topics",
        "/topic",
        "--format",
        "json",
        *CLI_KNOWN,
        "--wait-for",
        "/topic",
    )
    assert result.returncode == 0, result.stderr
    got = listener.wait_for_count(len(expected))
    texts = [deserialize_message(d, String).data for d in expected]
    assert [r.text for r in got] == texts
    assert texts[0] == "Hello, world! 0"
    report = json.loads(result.stdout)
    assert report["messages"] == len(expected)
    assert report["topics"] == [
        {
            "topic": "/topic",
            "published_as": "/topic",
            "type": "std_msgs/msg/String",
            "messages": 10,
            "unreadable": 0,
        }
    ]


def test_cli_loop_until_ctrl_c(
    test_bag: Path, listener_factory: type[Listener], processes: Any
) -> None:
    per_pass = len(recorded(test_bag))
    listener = listener_factory(STRING_TOPICS)
    proc = processes.start(
        [
            "bagkit",
            "replay",
            str(test_bag),
            "--loop",
            "--rate",
            "5",
            *CLI_KNOWN,
            "--wait-for",
            "/replay/fast",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    listener.wait_for_count(2 * per_pass + 1, timeout=20)
    os.killpg(proc.pid, signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=10)
    assert proc.returncode == 130, stderr
    assert "Traceback" not in stderr
    assert len(listener.messages()) > 2 * per_pass
    assert "passes" in stdout  # the report is printed even when interrupted
    progress = [line for line in stderr.splitlines() if line.startswith("bag ")]
    assert progress and "msgs" in progress[-1] and "late" in progress[-1]


@pytest.mark.parametrize("case", ["missing", "not a bag", "unknown types", "not cdr", "bad remap"])
def test_cli_bad_input_is_one_clear_line(
    tmp_path: Path, request: pytest.FixtureRequest, case: str
) -> None:
    options: list[str] = []
    if case == "missing":
        path, expected = tmp_path / "nope", "no such file"
    elif case == "not a bag":
        path = tmp_path / "notes.txt"
        path.write_text("hello\n")
        expected = "not"
    elif case == "unknown types":
        path = tmp_path / "exotic"
        with BagWriter(path) as writer:
            writer.add_topic(TopicInfo("/exotic", "exotic_msgs/msg/Thing"), definition="int32 v\n")
            writer.write("/exotic", b"\x00\x01\x00\x00\x07\x00\x00\x00", log_time=BAG_START_NS)
        expected = "exotic_msgs/msg/Thing"
    elif case == "not cdr":
        interop_dir: Path = request.getfixturevalue("interop_dir")
        path = interop_dir / "rosbag2_tests/resources/mcap/wrong_rmw_test"
        expected = "'wrong_format' is not cdr"
    elif case == "bad remap":
        path, expected = NOMINAL_BAG, "cannot publish /imu/data as '/imu data'"
        options = ["--remap", "/imu/data:=/imu data"]
    else:
        raise AssertionError(case)
    result = _bagkit("replay", str(path), "--no-wait-for-subscribers", *options)
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("error:") and expected in lines[0], lines


def test_cli_skips_unknown_types_with_one_warning(
    tmp_path: Path, listener_factory: type[Listener]
) -> None:
    bag = write_test_bag(tmp_path / "mixed", extra_topics={"/exotic": "exotic_msgs/msg/Thing"})
    expected = recorded(bag, list(SCHEDULE))
    listener = listener_factory(STRING_TOPICS)
    # Every message of both topics is expected: wait for both subscriptions.
    waits = [arg for topic in STRING_TOPICS for arg in ("--wait-for", topic)]
    result = _bagkit("replay", str(bag), "--rate", "10", *CLI_KNOWN, *waits)
    assert result.returncode == 0, result.stderr
    warnings = [line for line in result.stderr.splitlines() if "warning" in line]
    assert len(warnings) == 1, result.stderr
    assert "/exotic (exotic_msgs/msg/Thing)" in warnings[0]
    assert len(listener.wait_for_count(len(expected))) == len(expected), result.stdout


def test_cli_truncated_bag_replays_what_is_intact(
    tmp_path: Path, listener_factory: type[Listener]
) -> None:
    bag = tmp_path / "cut"
    with BagWriter(bag, chunk_size=2_000) as writer:
        writer.add_topic(TopicInfo("/replay/fast", "std_msgs/msg/String"))
        for index in range(200):
            writer.write(
                "/replay/fast",
                _payload("/replay/fast", index),
                log_time=BAG_START_NS + index * 5_000_000,
            )
    (storage,) = sorted(bag.glob("*.mcap"))
    cut = tmp_path / "cut.mcap"
    shutil.copy(storage, cut)
    with cut.open("r+b") as f:
        f.truncate(storage.stat().st_size // 2)
    listener = listener_factory({"/replay/fast": String})
    result = _bagkit(
        "replay",
        str(cut),
        "--rate",
        "10",
        "--format",
        "json",
        *CLI_KNOWN,
        "--wait-for",
        "/replay/fast",
    )
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout)
    assert 0 < report["messages"] < 200
    assert report["problems"]
    got = listener.wait_for_count(report["messages"])
    # Decoded: between processes Fast DDS pads the payload to a multiple of 4 bytes.
    assert [r.text for r in got] == [f"/replay/fast#{i}" for i in range(len(got))]
    assert len(got) == report["messages"]
    assert "damaged" in result.stderr and "Traceback" not in result.stderr


SENSOR_TOPICS = ["/imu/data", "/gps/fix", "/temperature", "/barometer/pressure"]
NOMINAL_BAG = Path(__file__).resolve().parents[2] / "fixtures" / "nominal" / "golden"


def test_sim_time_nodes_follow_the_clock(listener_factory: type[Listener], processes: Any) -> None:
    """At --rate 2 the data logger's 5 s summaries (in bag time) come every 2.5 s of wall time."""
    from diagnostic_msgs.msg import DiagnosticArray

    listener = listener_factory({"/logger/summary": DiagnosticArray})
    processes.start(["fusion", "run", "data_logger", "--use-sim-time"])
    topics = [arg for topic in SENSOR_TOPICS for arg in ("--topics", topic)]
    waits = [arg for topic in ["/clock", *SENSOR_TOPICS] for arg in ("--wait-for", topic)]
    result = _bagkit(
        "replay", str(NOMINAL_BAG), "--rate", "2", "--clock", "--duration", "18",
        *topics, *CLI_KNOWN, *waits, "--wait-timeout", "30",
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    time.sleep(0.3)
    summaries = [
        (r.received_ns, deserialize_message(r.data, DiagnosticArray))
        for r in listener.messages("/logger/summary")
    ]
    with BagReader(NOMINAL_BAG) as reader:
        bag_start, bag_end = reader.start_ns, reader.start_ns + 18_000_000_000
    # Stamped in bag time, 5 s of it apart.
    stamps = [_stamp_ns(s.header.stamp) for _, s in summaries]
    assert all(bag_start <= ns <= bag_end for ns in stamps), stamps
    periodic = [(wall, ns) for (wall, _), ns in zip(summaries, stamps, strict=True)][-3:]
    assert len(periodic) == 3, stamps
    for (wall_a, ns_a), (wall_b, ns_b) in itertools.pairwise(periodic):
        # Stamped with the node's clock when the timer ran: the last /clock value it had, which
        # passes the timer's due time by up to a /clock tick (10 ms of wall, 20 ms of bag time).
        assert (ns_b - ns_a) / 1e9 == pytest.approx(5.0, abs=0.05)
        assert (wall_b - wall_a) / 1e9 == pytest.approx(2.5, abs=0.25)
    # The logger saw the replayed IMU samples: 10 Hz of bag time.
    imu = next(s for s in summaries[-1][1].status if s.hardware_id == "/imu/data")
    count = int(imu.message.split()[0])
    assert count == pytest.approx(10 * (stamps[-1] - bag_start) / 1e9, abs=3)


def _stamp_ns(stamp: Any) -> int:
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def test_publishers_take_the_recorded_qos_or_the_overrides(tmp_path: Path) -> None:
    latched = QoSProfile(
        depth=3, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
    )
    lossy = QoSProfile(depth=7, reliability=ReliabilityPolicy.BEST_EFFORT)
    bag = tmp_path / "qos"
    with BagWriter(bag) as writer:
        for topic, profile in [("/latched", latched), ("/lossy", lossy), ("/plain", lossy)]:
            offered = dump_offered_qos_profiles([profile])
            writer.add_topic(TopicInfo(topic, "std_msgs/msg/String", offered_qos_profiles=offered))
            writer.write(topic, _payload(topic, 0), log_time=BAG_START_NS)
    overrides = tmp_path / "overrides.yaml"
    overrides.write_text("/plain:\n  reliability: reliable\n  history: keep_last\n  depth: 42\n")
    with Player(bag, qos_overrides=overrides) as player:
        offered = player.qos_profiles
    # Transient-local keeps its recorded depth (what a late subscriber gets); volatile topics
    # get a history for the messages in flight, here (one message each) the floor.
    assert offered["/latched"].durability == DurabilityPolicy.TRANSIENT_LOCAL
    assert offered["/latched"].reliability == ReliabilityPolicy.RELIABLE
    assert offered["/latched"].depth == 3
    assert offered["/lossy"].reliability == ReliabilityPolicy.BEST_EFFORT
    assert offered["/lossy"].depth == REPLAY_DEPTH
    assert offered["/plain"].reliability == ReliabilityPolicy.RELIABLE
    assert offered["/plain"].depth == 42


def test_replay_through_the_pipeline_while_recording_its_outputs(
    tmp_path: Path, processes: Any, listener_factory: type[Listener]
) -> None:
    """fusion launch --use-sim-time + bagkit replay --clock + bagkit record of the outputs."""
    outputs = ["/fusion/odometry", "/fusion/baro_altitude", "/logger/summary", "/alerts"]
    recorded_bag = tmp_path / "outputs"
    processes.start(
        ["fusion", "launch", "--use-sim-time", "--only", "data_logger,alert_system,sensor_fusion"]
    )
    recorder = processes.start(
        ["bagkit", "record", "--use-sim-time", "-o", str(recorded_bag), *outputs],
        stdout=subprocess.DEVNULL,
    )
    # The recorder subscribes once it has seen the nodes' publishers (a discovery period can
    # pass first, longer on a loaded machine); wait until this graph shows its subscriptions.
    graph = listener_factory({}).node
    deadline = time.monotonic() + 30
    while not all(
        any(s.node_name == "bagkit_recorder" for s in graph.get_subscriptions_info_by_topic(t))
        for t in ("/fusion/odometry", "/fusion/baro_altitude")
    ):
        assert time.monotonic() < deadline, "the recorder did not subscribe to the outputs"
        time.sleep(0.05)
    topics = [arg for topic in SENSOR_TOPICS for arg in ("--topics", topic)]
    waits = [arg for topic in ["/clock", *SENSOR_TOPICS] for arg in ("--wait-for", topic)]
    # --delay: the nodes' publishers still have to match the recorder's new subscriptions;
    # nothing in the graph shows when that has happened.
    result = _bagkit(
        "replay", str(NOMINAL_BAG), "--rate", "2", "--clock", "--duration", "8", "--delay", "3",
        "--format", "json", *topics, *CLI_KNOWN, *waits, "--wait-timeout", "30",
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    replayed = {t["topic"]: t["messages"] for t in json.loads(result.stdout)["topics"]}
    time.sleep(0.5)
    os.killpg(recorder.pid, signal.SIGINT)
    assert recorder.wait(timeout=20) == 130

    # Every output the golden bag holds for the replayed inputs (its outputs come from the same
    # processors run in lockstep), stamped in bag time, and nothing else.
    stamped = {"/fusion/odometry": "nav_msgs/msg/Odometry",
               "/fusion/baro_altitude": "geometry_msgs/msg/PoseWithCovarianceStamped"}  # fmt: skip
    inputs = {
        "/fusion/odometry": ("/imu/data", "sensor_msgs/msg/Imu"),
        "/fusion/baro_altitude": ("/barometer/pressure", "sensor_msgs/msg/FluidPressure"),
    }
    with BagReader(NOMINAL_BAG) as golden:
        end = golden.start_ns + 8_000_000_000
        replayed_stamps = _header_stamps(golden, dict(inputs.values()), end_ns=end)
        golden_outputs = _header_stamps(golden, stamped)
    expected = {
        topic: [s for s in golden_outputs[topic] if s in set(replayed_stamps[inputs[topic][0]])]
        for topic in stamped
    }
    with BagReader(recorded_bag) as reader:
        got = _header_stamps(reader, stamped)
        summaries = reader.topic_counts["/logger/summary"]
    # Sorted: the order is the recorder's business (log time), the set and count are ours.
    assert {t: sorted(v) for t, v in got.items()} == expected
    assert len(got["/fusion/odometry"]) == replayed["/imu/data"] - 1  # the filter starts at dt
    assert summaries >= 1


def _header_stamps(
    reader: BagReader, types: dict[str, str], end_ns: int | None = None
) -> dict[str, list[int]]:
    """Header stamps per topic of ``reader``, of the messages logged before ``end_ns``."""
    from bagkit.ros.types import import_message_type

    stamps: dict[str, list[int]] = {}
    for topic, type_name in types.items():
        message_type = import_message_type(type_name)
        stamps[topic] = [
            _stamp_ns(deserialize_message(m.data, message_type).header.stamp)
            for m in reader.messages([topic], end_ns=end_ns)
        ]
    return stamps


def test_a_recorded_clock_is_not_replayed_with_clock_on(tmp_path: Path) -> None:
    bag = tmp_path / "with_clock"
    with BagWriter(bag) as writer:
        writer.add_topic(TopicInfo("/clock", "rosgraph_msgs/msg/Clock"))
        writer.add_topic(TopicInfo("/replay/fast", "std_msgs/msg/String"))
        writer.write("/clock", clock_message(BAG_START_NS), log_time=BAG_START_NS)
        writer.write("/replay/fast", _payload("/replay/fast", 0), log_time=BAG_START_NS)
    with Player(bag, clock_hz=100.0, wait_for_subscribers=False) as player:
        assert set(player.published_topics) == {"/replay/fast"}
    with Player(bag, wait_for_subscribers=False) as player:
        assert set(player.published_topics) == {"/clock", "/replay/fast"}


def test_looping_keeps_the_lateness_samples_bounded(
    test_bag: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from bagkit.ros import lateness
    from bagkit.ros import player as player_module

    kept: list[lateness.LatenessSamples] = []

    class Spied(lateness.LatenessSamples):
        def __init__(self) -> None:
            super().__init__()
            kept.append(self)

    monkeypatch.setattr(lateness, "LATENESS_SAMPLES", 50)
    monkeypatch.setattr(player_module, "LatenessSamples", Spied)
    per_pass = len(recorded(test_bag))
    report = play(test_bag, rate=100.0, loops=20, wait_for_subscribers=False)
    assert report.loops == 20
    assert report.messages == 20 * per_pass > 50
    (samples,) = kept
    assert samples.count == report.messages
    assert len(samples.samples) == 50  # what is retained does not grow with the passes


def _corrupt_chunks(bag: Path, which: list[int]) -> tuple[int, int]:
    """Break the zstd frame of chunks ``which`` of ``bag``; return (messages, in those chunks)."""
    from mcap.reader import make_reader

    (storage,) = bag.glob("*.mcap")
    with storage.open("rb") as f:
        reader = make_reader(f)
        chunks = reader.get_summary().chunk_indexes  # type: ignore[union-attr]
        log_times = [message.log_time for _, _, message in reader.iter_messages()]
    broken = [chunks[i] for i in which]
    lost = sum(
        1 for t in log_times for c in broken if c.message_start_time <= t <= c.message_end_time
    )
    with storage.open("r+b") as f:
        for chunk in broken:
            # Past the chunk's opcode, length, times, sizes, CRC and compression name: the frame.
            f.seek(chunk.chunk_start_offset + 1 + 8 * 4 + 4 + 4 + len(chunk.compression) + 8)
            f.write(b"\xff" * 8)
    return len(log_times), lost


@pytest.mark.parametrize("broken", ["one chunk", "every chunk"])
def test_cli_chunk_that_does_not_decompress_is_named_and_counted(
    tmp_path: Path, broken: str
) -> None:
    bag = tmp_path / "broken"
    with BagWriter(bag, chunk_size=2_000) as writer:
        writer.add_topic(TopicInfo("/replay/fast", "std_msgs/msg/String"))
        for index in range(200):
            writer.write(
                "/replay/fast",
                _payload("/replay/fast", index),
                log_time=BAG_START_NS + index * 1_000_000,
            )
    with BagReader(bag) as reader:
        chunk_count = sum(1 for _ in reader.chunks())
    which = [2] if broken == "one chunk" else list(range(chunk_count))
    total, lost = _corrupt_chunks(bag, which)
    result = _bagkit(
        "replay", str(bag), "--rate", "100", "--no-wait-for-subscribers", "--format", "json"
    )
    assert "Traceback" not in result.stderr
    assert "no message of the selected topics" not in result.stderr
    if broken == "every chunk":
        assert result.returncode == 2
        (line,) = result.stderr.strip().splitlines()
        assert line.startswith("error: nothing replayed") and "chunk at byte" in line
        return
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout)
    assert 0 < lost < total
    assert report["messages"] == total - lost
    assert report["unreadable"] == report["topics"][0]["unreadable"] == lost
    (warning,) = [line for line in result.stderr.splitlines() if "damaged" in line]
    assert f"{lost} could not be read" in warning and "chunk at byte" in warning


def test_cli_start_offset_past_the_end_is_one_clear_line(test_bag: Path) -> None:
    result = _bagkit("replay", str(test_bag), "--start-offset", "5", "--no-wait-for-subscribers")
    assert result.returncode == 2
    (line,) = result.stderr.strip().splitlines()
    assert line.startswith("error: --start-offset 5 s is past the end of")
    assert "nan" not in result.stdout + result.stderr


@pytest.mark.parametrize("user_profile", [False, True])
def test_replay_gives_itself_the_large_shared_memory_pool_unless_the_user_has_a_profile(
    test_bag: Path, listener_factory: type[Listener], tmp_path: Path, user_profile: bool
) -> None:
    from test_record_cli import shared_memory_ports

    env = dict(os.environ)
    if user_profile:
        mine = tmp_path / "mine.xml"
        mine.write_text(
            '<?xml version="1.0" encoding="UTF-8"?>\n'
            '<dds xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles"><profiles>'
            '<participant profile_name="mine" is_default_profile="true"><rtps/></participant>'
            "</profiles></dds>\n"
        )
        env["FASTRTPS_DEFAULT_PROFILES_FILE"] = str(mine)
    listener = listener_factory(STRING_TOPICS)
    proc = subprocess.Popen(
        [
            str(Path(sys.executable).with_name("bagkit")),
            "replay",
            str(test_bag),
            *CLI_KNOWN,
            "--wait-for",
            "/replay/fast",
        ],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    try:
        listener.wait_for_count(1)
        ports = shared_memory_ports(proc.pid)  # read while the replay runs (about 1 s)
        _, stderr = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0, stderr.decode()
    assert ports, "the player maps no shared-memory port"
    # Fast DDS sizes a port file by its descriptors: 52 KB for the default 512, 1.3 MB for
    # bagkit's 65536 (the same setting sizes the participant's send pool).
    large = [size for size in ports.values() if size > 1_000_000]
    assert bool(large) is not user_profile, ports
