"""Live replay of a bag over ROS 2: original timing scaled by a rate, /clock, no lost first message.

``Player`` is a context manager: entering opens the bag and creates one publisher per replayed
topic; ``play()`` waits for the subscribers the graph knows about, then publishes every message's
stored bytes when the monotonic clock reaches its scheduled time.
"""

from __future__ import annotations

import itertools
import math
import time
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from contextlib import ExitStack
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import rclpy
from rclpy.context import Context
from rclpy.duration import Duration
from rclpy.exceptions import InvalidTopicNameException
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    QoSCompatibility,
    QoSProfile,
    ReliabilityPolicy,
    qos_check_compatible,
)
from rclpy.signals import SignalHandlerOptions
from rosgraph_msgs.msg import Clock

from bagkit.bag import BagMessage, BagReader, TopicInfo
from bagkit.ros.errors import MessageClassNotFoundError, PlayerError, SubscriberTimeoutError
from bagkit.ros.graph import compile_topic_pattern
from bagkit.ros.qos import load_qos_overrides, replay_publisher_qos
from bagkit.ros.timing import (
    DEFAULT_DISCOVERY_TIME_S,
    LATE_THRESHOLD_NS,
    LatenessSummary,
    Timeline,
    clock_message,
    wait_until,
)
from bagkit.ros.types import import_message_type

CLOCK_TOPIC = "/clock"
CLOCK_TYPE = "rosgraph_msgs/msg/Clock"
# The graph counts as settled when it has not changed for this long.
GRAPH_SETTLE_S = 0.2
# A publisher sees a subscription match before the subscription sees the publisher; the first
# message is only safe once both sides have matched, which we cannot observe from here.
MATCH_GRACE_S = 0.1
# Progress is reported only when the next message is at least this far away (or when it is
# overdue by PROGRESS_FORCE_S), so reporting never delays a message.
PROGRESS_SLACK_NS = 3_000_000
PROGRESS_FORCE_S = 2.0


@dataclass(frozen=True, slots=True)
class PlayProgress:
    """A snapshot of a running replay, for a progress line."""

    bag_time_s: float
    """Bag time played in the current pass, from the start of the replayed window."""
    wall_time_s: float
    """Wall time since the first message of the current pass was scheduled."""
    effective_rate: float
    messages: int
    late: int
    loop: int


@dataclass(frozen=True, slots=True)
class TopicPlayback:
    """What was replayed of one topic."""

    topic: str
    published_as: str
    type: str
    messages: int


@dataclass(slots=True)
class PlayReport:
    """The outcome of a replay."""

    topics: list[TopicPlayback]
    messages: int
    loops: int
    """Passes over the bag that completed."""
    bag_duration_s: float
    """Bag time covered by the replayed messages, summed over passes."""
    wall_duration_s: float
    """Wall time from the start of the first pass (its delay included) to the last message."""
    rate: float
    lateness: LatenessSummary
    skipped_types: dict[str, str] = field(default_factory=dict)
    """Topic -> message type that is not installed (not replayed)."""
    skipped_formats: dict[str, str] = field(default_factory=dict)
    """Topic -> serialization format other than ``cdr`` (not replayed)."""
    missing_topics: list[str] = field(default_factory=list)
    """Topics asked for with ``topics`` that the bag does not have."""
    problems: list[str] = field(default_factory=list)
    """What the reader could not read (a truncated or damaged file)."""
    unacknowledged: list[str] = field(default_factory=list)
    """Reliable topics whose subscribers had not acknowledged every message at the end."""
    interrupted: bool = False

    def to_dict(self) -> dict[str, Any]:
        """The report as plain JSON-ready data."""
        return asdict(self)


@dataclass(slots=True)
class _Output:
    info: TopicInfo
    publisher: Publisher
    publish: Callable[[bytes], None]
    """The publisher's raw publish, without ``Publisher.publish``'s per-call checks."""
    count: int = 0

    @property
    def name(self) -> str:
        return str(self.publisher.topic_name)


class Player:
    """Replays a bag through ROS 2 publishers with the recorded timing.

    Example:
        >>> with Player("drive", rate=2.0, clock_hz=100.0) as player:
        ...     report = player.play()
    """

    def __init__(
        self,
        bag: str | Path,
        *,
        rate: float = 1.0,
        topics: Sequence[str] | None = None,
        regex: str | None = None,
        exclude: str | None = None,
        start_offset: float = 0.0,
        duration: float | None = None,
        loops: int = 1,
        delay: float = 0.0,
        clock_hz: float | None = None,
        remap: Mapping[str, str] | None = None,
        wait_for_subscribers: bool = True,
        wait_for: Sequence[str] = (),
        wait_timeout: float = 10.0,
        discovery_time: float = DEFAULT_DISCOVERY_TIME_S,
        ack_timeout: float = 10.0,
        qos_overrides: str | Path | None = None,
        context: Context | None = None,
        node_name: str = "bagkit_player",
        on_progress: Callable[[PlayProgress], None] | None = None,
        progress_period: float = 0.5,
    ) -> None:
        """Set up a replay; nothing is opened until the player is entered.

        Args:
            bag: bag directory or single ``.mcap`` file.
            rate: playback speed factor (2.0 = twice as fast as recorded).
            topics: replay only these topics (union with ``regex``); None = all.
            regex: replay topics whose name matches this regular expression (``re.search``).
            exclude: do not replay topics whose name matches this regular expression.
            start_offset: skip this many seconds from the start of the bag.
            duration: replay only this many seconds of bag time (after ``start_offset``).
            loops: passes over the bag; 0 = until interrupted.
            delay: seconds to sleep before each pass.
            clock_hz: publish ``/clock`` at this rate (and before each message); None = off.
            remap: topic renames, recorded name -> published name.
            wait_for_subscribers: before the first message, wait until every subscription that
                the graph shows on a replayed topic has matched.
            wait_for: topics that must have at least one subscriber before playback starts
                (for consumers that are still starting up).
            wait_timeout: seconds to wait for subscribers before giving up.
            discovery_time: seconds after the node's creation during which the graph is watched
                for subscriptions that already exist (see ``wait_until_matched``).
            ack_timeout: at the end, seconds to wait for subscribers of reliable topics to
                acknowledge every message (see ``wait_until_acknowledged``).
            qos_overrides: rosbag2 QoS overrides file (``topic: {reliability: ..., ...}``).
            context: rclpy context to use; None = a private one, shut down on exit.
            node_name: name of the player's node.
            on_progress: called with a ``PlayProgress`` about every ``progress_period`` seconds.
            progress_period: seconds between progress reports.
        """
        if not rate > 0:
            raise PlayerError(f"rate must be positive, got {rate}")
        if start_offset < 0:
            raise PlayerError(f"start offset must not be negative, got {start_offset}")
        if duration is not None and not duration > 0:
            raise PlayerError(f"duration must be positive, got {duration}")
        if delay < 0:
            raise PlayerError(f"delay must not be negative, got {delay}")
        if clock_hz is not None and not clock_hz > 0:
            raise PlayerError(f"clock rate must be positive, got {clock_hz}")
        if loops < 0:
            raise PlayerError(f"loops must be 0 (forever) or positive, got {loops}")
        self.bag_path = Path(bag)
        self.rate = rate
        self.topics = list(topics) if topics is not None else None
        self.regex = compile_topic_pattern(regex, "--regex", error=PlayerError)
        self.exclude = compile_topic_pattern(exclude, "--exclude", error=PlayerError)
        self.start_offset_ns = int(start_offset * 1e9)
        self.duration_ns = int(duration * 1e9) if duration is not None else None
        self.loops = loops
        self.delay = delay
        self.clock_hz = clock_hz
        self.remap = dict(remap or {})
        self.wait_for_subscribers = wait_for_subscribers
        self.wait_for = list(wait_for)
        self.wait_timeout = wait_timeout
        self.discovery_time = discovery_time
        self.ack_timeout = ack_timeout
        self.qos_overrides_path = Path(qos_overrides) if qos_overrides is not None else None
        self.on_progress = on_progress
        self.progress_period_ns = int(progress_period * 1e9)
        self._context = context
        self._node_name = node_name
        self._stack = ExitStack()
        self._reader: BagReader | None = None
        self._node: Node | None = None
        self._outputs: dict[str, _Output] = {}
        self._clock: _Output | None = None
        self._node_created = 0.0
        self.skipped_types: dict[str, str] = {}
        self.skipped_formats: dict[str, str] = {}
        self.missing_topics: list[str] = []

    def __enter__(self) -> Player:
        try:
            self._open()
        except BaseException:
            self._stack.close()
            raise
        return self

    def __exit__(self, *exc_info: object) -> None:
        self._stack.close()

    @property
    def node(self) -> Node:
        """The player's rclpy node (exists while the player is entered)."""
        if self._node is None:
            raise PlayerError("the player is not open: use it as a context manager")
        return self._node

    @property
    def published_topics(self) -> dict[str, str]:
        """Recorded topic -> name it is published under, for every replayed topic."""
        return {topic: out.name for topic, out in self._outputs.items()}

    @property
    def qos_profiles(self) -> dict[str, QoSProfile]:
        """Recorded topic -> QoS profile it is published with."""
        return {topic: out.publisher.qos_profile for topic, out in self._outputs.items()}

    def _open(self) -> None:
        overrides = load_qos_overrides(self.qos_overrides_path) if self.qos_overrides_path else {}
        reader = self._stack.enter_context(BagReader(self.bag_path))
        self._reader = reader
        selected = self._select_topics(reader.topics)
        mean_size = reader.uncompressed_size // max(reader.message_count, 1) or 1024
        bag_duration_s = (reader.end_ns - reader.start_ns) / 1e9

        context = self._context
        if context is None:
            context = Context()
            # No signal handlers: Ctrl-C must reach play() as KeyboardInterrupt so that it can
            # stop between two messages and still report.
            rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
            self._stack.callback(context.try_shutdown)
        node = Node(
            self._node_name,
            context=context,
            start_parameter_services=False,
            enable_rosout=False,
        )
        self._stack.callback(node.destroy_node)
        self._node = node
        self._node_created = time.monotonic()

        for info, message_class in selected:
            name = self.remap.get(info.name, info.name)
            qos = overrides.get(name) or overrides.get(info.name)
            if qos is None:
                qos = replay_publisher_qos(
                    info,
                    count=reader.topic_counts.get(info.name, 0),
                    mean_size=mean_size,
                    messages_per_s=self._replay_rate_hz(
                        reader.topic_counts.get(info.name, 0), bag_duration_s
                    ),
                )
            try:
                publisher = node.create_publisher(message_class, name, qos)
            except InvalidTopicNameException as exc:
                # rclpy's message goes on with the name and a caret under the bad character.
                reason = str(exc).splitlines()[0].rstrip(":")
                raise PlayerError(f"cannot publish {info.name} as {name!r}: {reason}") from None
            self._outputs[info.name] = _Output(info, publisher, publisher.handle.publish_raw)
        if self.clock_hz is not None:
            # What rclcpp's ClockQoS offers and what every use_sim_time node subscribes with.
            clock_qos = QoSProfile(
                history=HistoryPolicy.KEEP_LAST,
                depth=1,
                reliability=ReliabilityPolicy.BEST_EFFORT,
                durability=DurabilityPolicy.VOLATILE,
            )
            publisher = node.create_publisher(Clock, CLOCK_TOPIC, clock_qos)
            self._clock = _Output(
                TopicInfo(CLOCK_TOPIC, CLOCK_TYPE), publisher, publisher.handle.publish_raw
            )

    def _replay_rate_hz(self, count: int, bag_duration_s: float) -> float:
        """Messages per second of wall time of a topic with ``count`` messages, at ``rate``."""
        if bag_duration_s <= 0:
            return math.inf
        return count / bag_duration_s * self.rate

    def _select_topics(self, topics: Mapping[str, TopicInfo]) -> list[tuple[TopicInfo, Any]]:
        wanted = set(self.topics) if self.topics is not None else None
        if wanted is not None:
            self.missing_topics = sorted(wanted - topics.keys())
        selected = []
        for name, info in sorted(topics.items()):
            if wanted is not None or self.regex is not None:
                chosen = (wanted is not None and name in wanted) or bool(
                    self.regex is not None and self.regex.search(name)
                )
                if not chosen:
                    continue
            if self.exclude is not None and self.exclude.search(name):
                continue
            if self.clock_hz is not None and name == CLOCK_TOPIC:
                continue
            if info.serialization_format != "cdr":
                self.skipped_formats[name] = info.serialization_format
                continue
            try:
                message_class = import_message_type(info.type)
            except MessageClassNotFoundError:
                self.skipped_types[name] = info.type
                continue
            selected.append((info, message_class))
        if not selected:
            if self.skipped_types or self.skipped_formats:
                reason = "no selected topic can be published: " + "; ".join(
                    [
                        f"{name}: {type_name} not installed"
                        for name, type_name in sorted(self.skipped_types.items())
                    ]
                    + [
                        f"{name}: serialization format {fmt!r} is not cdr"
                        for name, fmt in sorted(self.skipped_formats.items())
                    ]
                )
            else:
                reason = "no topic of the bag matches the topic selection"
            raise PlayerError(f"nothing to replay in {self.bag_path}: {reason}")
        return selected

    def play(self) -> PlayReport:
        """Replay the bag (``loops`` passes); Ctrl-C stops between two messages.

        Returns:
            What was published, the timing error and what the reader could not read.

        Raises:
            SubscriberTimeoutError: known subscribers did not match within ``wait_timeout``.
        """
        if self._reader is None:
            raise PlayerError("the player is not open: use it as a context manager")
        for output in self._outputs.values():
            output.count = 0
        lateness: list[int] = []
        bag_ns = 0
        passes = 0
        interrupted = False
        wall_start = time.monotonic_ns()
        try:
            if self.wait_for_subscribers or self.wait_for:
                self.wait_until_matched()
            wall_start = time.monotonic_ns()
            while self.loops == 0 or passes < self.loops:
                if self.delay > 0:
                    time.sleep(self.delay)
                before = len(lateness)
                bag_ns += self._play_pass(passes, lateness)
                passes += 1
                if len(lateness) == before:
                    break  # an empty window: looping would only spin
            wall_ns = time.monotonic_ns() - wall_start
            unacknowledged = self.wait_until_acknowledged()
        except KeyboardInterrupt:
            interrupted = True
            wall_ns = time.monotonic_ns() - wall_start
            unacknowledged = []
        return PlayReport(
            topics=[
                TopicPlayback(topic, out.name, out.info.type, out.count)
                for topic, out in self._outputs.items()
            ],
            messages=len(lateness),
            loops=passes,
            bag_duration_s=bag_ns / 1e9,
            wall_duration_s=wall_ns / 1e9,
            rate=self.rate,
            lateness=LatenessSummary.from_samples(lateness),
            skipped_types=dict(self.skipped_types),
            skipped_formats=dict(self.skipped_formats),
            missing_topics=list(self.missing_topics),
            problems=list(dict.fromkeys(self._reader.problems)),
            unacknowledged=unacknowledged,
            interrupted=interrupted,
        )

    def _play_pass(self, loop: int, lateness: list[int]) -> int:
        """Publish one pass over the window; return the bag time it covered (ns)."""
        assert self._reader is not None
        reader = self._reader
        window_start = reader.start_ns + self.start_offset_ns
        window_end = window_start + self.duration_ns if self.duration_ns is not None else None
        outputs = self._outputs
        messages = iter(
            reader.messages(topics=list(outputs), start_ns=window_start, end_ns=window_end)
        )
        # The first chunk is read before the clock starts, so the first message is on time.
        # Later chunks are read inline, right after a publication: a read-ahead thread was
        # measured to do worse, its GIL hand-offs delaying the publishing loop.
        first = next(messages, None)
        if first is None:
            return 0
        return self._publish(itertools.chain([first], messages), loop, window_start, lateness)

    def _publish(
        self, messages: Iterator[BagMessage], loop: int, window_start: int, lateness: list[int]
    ) -> int:
        """Publish ``messages`` on schedule; return the bag time they covered (ns)."""
        outputs = self._outputs
        clock = self._clock
        timeline = Timeline(window_start, time.monotonic_ns(), self.rate)
        tick_ns = int(1e9 / self.clock_hz) if self.clock_hz else 0
        next_tick = timeline.wall_start_ns + tick_ns
        if clock is not None:
            clock.publish(clock_message(window_start))
        next_progress = timeline.wall_start_ns + self.progress_period_ns
        on_progress = self.on_progress
        first_lateness = len(lateness)
        last_log_time = window_start
        late = 0

        def report_progress(now: int) -> None:
            bag_s = (last_log_time - window_start) / 1e9
            wall_s = (now - timeline.wall_start_ns) / 1e9
            assert on_progress is not None
            on_progress(
                PlayProgress(
                    bag_time_s=bag_s,
                    wall_time_s=wall_s,
                    effective_rate=bag_s / wall_s if wall_s > 0 else 0.0,
                    messages=len(lateness) - first_lateness,
                    late=late,
                    loop=loop,
                )
            )

        for message in messages:
            log_time = message.log_time
            deadline = timeline.deadline(log_time)
            if clock is not None:
                while next_tick < deadline:
                    wait_until(next_tick)
                    clock.publish(clock_message(timeline.bag_time(next_tick)))
                    # After a stall, resume ticking from now instead of bursting the backlog.
                    next_tick = max(next_tick + tick_ns, time.monotonic_ns())
            if on_progress is not None:
                now = time.monotonic_ns()
                if now >= next_progress and (
                    deadline - now > PROGRESS_SLACK_NS
                    or now - next_progress > PROGRESS_FORCE_S * 1e9
                ):
                    report_progress(now)
                    next_progress = now + self.progress_period_ns
            now = wait_until(deadline)
            if clock is not None:
                clock.publish(clock_message(log_time))
            output = outputs[message.topic]
            output.publish(message.data)
            output.count += 1
            delay_ns = now - deadline
            lateness.append(delay_ns)
            if delay_ns > LATE_THRESHOLD_NS:
                late += 1
            last_log_time = log_time
        if on_progress is not None:
            report_progress(time.monotonic_ns())
        return last_log_time - window_start

    def wait_until_acknowledged(self) -> list[str]:
        """Wait until the subscribers of reliable topics have every message; return the others.

        A fast replay ends while messages are still in flight; destroying the publishers then
        would lose them. Waits at most ``ack_timeout`` seconds in all.
        """
        deadline = time.monotonic() + self.ack_timeout
        pending = []
        for output in self._outputs.values():
            publisher = output.publisher
            if publisher.qos_profile.reliability != ReliabilityPolicy.RELIABLE:
                continue
            remaining = max(deadline - time.monotonic(), 0.0)
            if not publisher.wait_for_all_acked(Duration(seconds=remaining)):
                pending.append(output.name)
        return pending

    def wait_until_matched(self) -> None:
        """Block until the subscriptions the graph knows on replayed topics have matched.

        A subscription in another process shows up in the graph only when its participant's
        discovery announcement arrives (Fast DDS announces every 3 s), so the graph is watched
        for ``discovery_time`` seconds after the player's node was created, and until it has
        been unchanged for ``GRAPH_SETTLE_S``; every compatible subscription seen by then must
        match. Topics in ``wait_for`` additionally need at least one subscription.

        Raises:
            SubscriberTimeoutError: not matched within ``wait_timeout`` seconds.
        """
        node = self.node
        outputs = list(self._outputs.values())
        if self._clock is not None:
            outputs.append(self._clock)
        required = sorted(set(self.wait_for))
        now = time.monotonic()
        deadline = now + self.wait_timeout
        settled_at = max(self._node_created + self.discovery_time, now + GRAPH_SETTLE_S)
        last_graph: dict[str, int] = {}
        while True:
            graph = {out.name: node.count_subscribers(out.name) for out in outputs}
            graph.update({topic: node.count_subscribers(topic) for topic in required})
            now = time.monotonic()
            if graph != last_graph:
                last_graph = graph
                settled_at = max(settled_at, now + GRAPH_SETTLE_S)
            pending = [
                f"{out.name} ({matched} of {expected} subscriptions matched)"
                for out in outputs
                for matched, expected in [
                    (out.publisher.get_subscription_count(), _compatible_subscriptions(node, out))
                ]
                if matched < expected
            ]
            pending += [f"a subscriber on {topic}" for topic in required if not graph[topic]]
            if not pending and now >= settled_at:
                break
            if now >= deadline:
                raise SubscriberTimeoutError(
                    f"timed out after {self.wait_timeout:g} s waiting for {', '.join(pending)}; "
                    "use --no-wait-for-subscribers to start anyway"
                )
            time.sleep(0.02)
        time.sleep(MATCH_GRACE_S)


def play(bag: str | Path, **options: Any) -> PlayReport:
    """Replay ``bag`` once with ``Player(bag, **options)`` and return the report."""
    with Player(bag, **options) as player:
        return player.play()


def parse_remaps(pairs: Iterable[str]) -> dict[str, str]:
    """Parse ``OLD:=NEW`` topic remappings (as in ``ros2 bag play --remap``)."""
    remap = {}
    for pair in pairs:
        old, sep, new = pair.partition(":=")
        if not sep or not old or not new:
            raise PlayerError(f"remapping {pair!r} is not of the form OLD:=NEW")
        remap[old] = new
    return remap


def _compatible_subscriptions(node: Node, output: _Output) -> int:
    """Subscriptions on ``output``'s topic in the graph whose QoS can match the publisher's."""
    count = 0
    for endpoint in node.get_subscriptions_info_by_topic(output.name):
        compatibility, _ = qos_check_compatible(output.publisher.qos_profile, endpoint.qos_profile)
        if compatibility != QoSCompatibility.ERROR:
            count += 1
    return count
