"""The replay tests' known-stamp bag and a listener that keeps the middleware's reception times."""

from __future__ import annotations

import subprocess
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import rclpy
from rclpy.context import Context
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message, serialize_message
from rosgraph_msgs.msg import Clock
from std_msgs.msg import String

from bagkit.bag import BagReader, BagWriter, TopicInfo
from bagkit.playback.options import PlayOptions, SubscriberWaits
from bagkit.playback.report import PlayReport
from bagkit.ros.replay.player import Player

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

    def clear(self) -> None:
        """Forget what arrived: the next replay's messages are counted alone."""
        with self._lock:
            self.received.clear()

    def wait_for_publisher(self, topic: str, timeout: float = 30.0) -> None:
        """Until a publisher of ``topic`` is matched: what it sends before is lost (volatile)."""
        subscription = next(s for t, _, s in self.subscriptions if t == topic)
        deadline = time.monotonic() + timeout
        while not subscription.get_publisher_count():
            assert time.monotonic() < deadline, f"no publisher of {topic} within {timeout:g} s"
            time.sleep(0.02)

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


def payload(topic: str, index: int) -> bytes:
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
            writer.write(topic, payload(topic, index[topic]), log_time=log_time)
            index[topic] += 1
            for extra in extra_topics or {}:
                writer.write(extra, b"\x00\x01\x00\x00\x07\x00\x00\x00", log_time=log_time)
    return path


def recorded(bag: Path, topics: list[str] | None = None) -> list[tuple[str, bytes, int]]:
    """(topic, data, log_time) of every message of ``bag``, read back with the reader."""
    with BagReader(bag) as reader:
        return [(m.topic, m.data, m.log_time) for m in reader.messages(topics=topics)]


STRING_TOPICS = dict.fromkeys(SCHEDULE, String)


# The listeners are known: wait for them instead of watching the graph for 3 s (a subscription
# in this process is discovered at once; one in another process takes up to 3 s).
def known(*topics: str) -> SubscriberWaits:
    """Wait for a subscriber on each of ``topics``, without watching the graph first."""
    return SubscriberWaits(topics=topics, discovery_ns=0)


NO_WAITS = SubscriberWaits(before_start=False)


CLI_KNOWN = ["--discovery-time", "0"]


def play(bag: Path, **options: Any) -> PlayReport:
    """Replay ``bag`` once with these :class:`PlayOptions` and return the report."""
    return Player(PlayOptions(bag, **options)).run()


def clock_ns(data: bytes) -> int:
    stamp = deserialize_message(data, Clock).clock
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def bagkit_cli(*args: str, timeout: float = 60.0) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [str(Path(sys.executable).with_name("bagkit")), *args],
        capture_output=True,
        text=True,
        timeout=timeout,
        check=False,
    )


def stamp_ns(stamp: Any) -> int:
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


# fusion's nominal flight: the sensor topics at their rates, 37 s.
NOMINAL_BAG = Path(__file__).resolve().parents[2] / "fixtures" / "nominal" / "golden"
