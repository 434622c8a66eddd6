"""Live replay of a bag over ROS 2: original timing scaled by a rate, /clock, no lost first message.

``Player`` is a context manager: constructing it only checks the options; entering opens the bag
and creates one publisher per replayed topic (:mod:`bagkit.ros.publishers`); ``play()`` waits
for the subscribers the graph knows about, then runs the passes (:mod:`bagkit.ros.publish_loop`)
and returns a :class:`~bagkit.ros.playback_report.PlayReport`.
"""

from __future__ import annotations

import itertools
import math
import time
from collections.abc import Callable, Mapping, Sequence
from contextlib import ExitStack
from pathlib import Path
from typing import Any

import rclpy
from rclpy.context import Context
from rclpy.node import Node
from rclpy.qos import QoSProfile
from rclpy.signals import SignalHandlerOptions

from bagkit.bag import BagReader, TopicInfo
from bagkit.ros.errors import PlayerError
from bagkit.ros.lateness import LatenessSamples
from bagkit.ros.play_controls import PlayControls
from bagkit.ros.play_options import PlayWindow, SubscriberWaits, check_play_options
from bagkit.ros.playback_report import PlayProgress, PlayReport, TopicPlayback
from bagkit.ros.player_services import serve_controls
from bagkit.ros.player_topics import PublishableTopics, publishable_topics, replay_selection
from bagkit.ros.publish_loop import PassPublisher
from bagkit.ros.publishers import (
    TopicOutput,
    create_clock_output,
    create_output,
    other_publishers,
    wait_until_acknowledged,
    wait_until_matched,
)
from bagkit.ros.qos import load_qos_overrides, replay_publisher_qos
from bagkit.ros.timing import DEFAULT_DISCOVERY_TIME_S
from bagkit.times import seconds_to_ns


class Player:
    """Replays a bag through ROS 2 publishers with the recorded timing.

    Args:
        bag: bag directory or single ``.mcap`` file.
        rate: playback speed factor (2.0 = twice as fast as recorded).
        topics: replay only these topics (union with ``regex``); None = all.
        regex: replay topics whose name matches this regular expression (``re.search``).
        exclude: do not replay topics whose name matches this regular expression.
        start_offset: skip this many seconds from the start of the bag.
        duration: replay only this many seconds of bag time (after ``start_offset``).
        playback_until_ns: replay only messages logged at or before this time (ns since the
            epoch); with ``duration``, the later of the two ends the replay (as rosbag2).
        exclude_topics: do not replay these topics.
        loops: passes over the bag; 0 = until interrupted.
        delay: seconds to sleep before each pass.
        clock_hz: publish ``/clock`` at this rate (and before each message); None = off.
        start_paused: start paused (``player.controls.resume()`` or a service resumes).
        services: offer rosbag2's control services and a ``rate`` parameter on the node
            (:mod:`bagkit.ros.player_services`).
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
        on_live_publishers: called once before the first message with the replayed topics
            that other nodes publish too (published name -> those nodes).

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
        playback_until_ns: int | None = None,
        exclude_topics: Sequence[str] = (),
        loops: int = 1,
        delay: float = 0.0,
        clock_hz: float | None = None,
        start_paused: bool = False,
        services: bool = False,
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
        on_live_publishers: Callable[[dict[str, list[str]]], None] | None = None,
    ) -> None:
        """Set up a replay; nothing is opened until the player is entered."""
        check_play_options(rate, delay, clock_hz, loops)
        self.bag_path = Path(bag)
        self.rate = rate
        self.controls = PlayControls(rate, paused=start_paused)
        self.services = services
        self.selection = replay_selection(topics, regex, exclude, exclude_topics)
        self.window = PlayWindow.create(start_offset, duration, playback_until_ns)
        self.loops = loops
        self.delay = delay
        self.clock_hz = clock_hz
        self.remap = dict(remap or {})
        self.waits = SubscriberWaits(
            wait_for_subscribers, tuple(wait_for), wait_timeout, discovery_time, ack_timeout
        )
        self.qos_overrides_path = Path(qos_overrides) if qos_overrides is not None else None
        self.on_progress = on_progress
        self.on_live_publishers = on_live_publishers
        self.progress_period_ns = seconds_to_ns(progress_period, progress_period, PlayerError)
        self._context = context
        self._node_name = node_name
        self._stack = ExitStack()
        self._reader: BagReader | None = None
        self._node: Node | None = None
        self._outputs: dict[str, TopicOutput] = {}
        self._clock: TopicOutput | None = None
        self._node_created = 0.0
        self.live_publishers: dict[str, list[str]] = {}
        """Published topic -> other nodes publishing it, found when the replay starts."""
        self.publishable = PublishableTopics()
        """The bag's topics that are replayed, and the selected ones that cannot be."""

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
        self.window.bounds(reader.start_ns, reader.end_ns, self.bag_path)  # raises past the end
        selected = self._select_topics(reader.topics)
        mean_size = reader.uncompressed_size // max(reader.message_count, 1) or 1024
        bag_duration_s = (reader.end_ns - reader.start_ns) / 1e9
        node = self._create_node()
        for info, message_class in selected:
            name = self.remap.get(info.name, info.name)
            count = reader.topic_counts.get(info.name, 0)
            qos = overrides.get(name) or overrides.get(info.name)
            if qos is None:
                qos = replay_publisher_qos(
                    info,
                    count=count,
                    mean_size=mean_size,
                    messages_per_s=self._replay_rate_hz(count, bag_duration_s),
                )
            self._outputs[info.name] = create_output(node, info, message_class, name, qos)
        if self.clock_hz is not None:
            self._clock = create_clock_output(node)
        if self.services:
            self._stack.enter_context(serve_controls(node, self.controls))

    def _create_node(self) -> Node:
        context = self._context
        if context is None:
            context = Context()
            # No signal handlers: Ctrl-C must reach play() as KeyboardInterrupt so that it can
            # stop between two messages and still report.
            # args=[]: not sys.argv, whose --remap is bagkit's (applied to the publishers'
            # names), not a ROS remap rule for rcl to parse and warn about.
            rclpy.init(args=[], context=context, signal_handler_options=SignalHandlerOptions.NO)
            self._stack.callback(context.try_shutdown)
        node = Node(
            self._node_name,
            context=context,
            start_parameter_services=self.services,
            enable_rosout=False,
        )
        self._stack.callback(node.destroy_node)
        self._node = node
        self._node_created = time.monotonic()
        return node

    def _replay_rate_hz(self, count: int, bag_duration_s: float) -> float:
        """Messages per second of wall time of a topic with ``count`` messages, at ``rate``."""
        if bag_duration_s <= 0:
            return math.inf
        return count / bag_duration_s * self.rate

    def _select_topics(self, topics: Mapping[str, TopicInfo]) -> list[tuple[TopicInfo, Any]]:
        self.publishable = publishable_topics(
            topics,
            self.selection,
            clock_published=self.clock_hz is not None,
            bag_path=self.bag_path,
        )
        return self.publishable.selected

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
        lateness = LatenessSamples()
        bag_ns = 0
        passes = 0
        interrupted = False
        wall_start = time.monotonic_ns()
        try:
            if self.waits.before_start or self.waits.topics:
                self.wait_until_matched()
            self.live_publishers = other_publishers(self.node, list(self._outputs.values()))
            if self.live_publishers and self.on_live_publishers is not None:
                self.on_live_publishers(self.live_publishers)
            wall_start = time.monotonic_ns()
            while self.loops == 0 or passes < self.loops:
                if self.delay > 0:
                    time.sleep(self.delay)
                before = lateness.count
                bag_ns += self._play_pass(passes, lateness)
                passes += 1
                if lateness.count == before:
                    break  # an empty window: looping would only spin
            wall_ns = time.monotonic_ns() - wall_start
            unacknowledged = self.wait_until_acknowledged()
        except KeyboardInterrupt:
            interrupted = True
            wall_ns = time.monotonic_ns() - wall_start
            unacknowledged = []
        return PlayReport(
            topics=self._topic_playbacks(passes, complete=not interrupted),
            messages=lateness.count,
            loops=passes,
            bag_duration_s=bag_ns / 1e9,
            wall_duration_s=wall_ns / 1e9,
            rate=self.rate,
            lateness=lateness.summary(),
            skipped_types=dict(self.publishable.skipped_types),
            skipped_formats=dict(self.publishable.skipped_formats),
            missing_topics=list(self.publishable.missing),
            problems=list(dict.fromkeys(self._reader.problems)),
            unacknowledged=unacknowledged,
            interrupted=interrupted,
        )

    def _topic_playbacks(self, passes: int, *, complete: bool) -> list[TopicPlayback]:
        """Per-topic counts; unreadable messages where the whole bag was to be replayed."""
        assert self._reader is not None
        reader = self._reader
        whole_bag = complete and self.window.whole
        playbacks = []
        for topic, out in self._outputs.items():
            unreadable = 0
            if whole_bag and reader.problems:
                unreadable = max(0, reader.topic_counts.get(topic, 0) * passes - out.count)
            playbacks.append(TopicPlayback(topic, out.name, out.info.type, out.count, unreadable))
        return playbacks

    def _play_pass(self, loop: int, lateness: LatenessSamples) -> int:
        """Publish one pass over the window; return the bag time it covered (ns)."""
        assert self._reader is not None
        reader = self._reader
        window_start, window_end = self.window.bounds(reader.start_ns, reader.end_ns, self.bag_path)
        messages = iter(
            reader.messages(topics=list(self._outputs), start_ns=window_start, end_ns=window_end)
        )
        # The first chunk is read before the clock starts, so the first message is on time.
        # Later chunks are read inline, right after a publication: a read-ahead thread was
        # measured to do worse, its GIL hand-offs delaying the publishing loop.
        first = next(messages, None)
        if first is None:
            return 0
        publisher = PassPublisher(
            self._outputs,
            self._clock,
            clock_hz=self.clock_hz,
            lateness=lateness,
            on_progress=self.on_progress,
            progress_period_ns=self.progress_period_ns,
            loop=loop,
            controls=self.controls,
        )
        return publisher.run(itertools.chain([first], messages), window_start)

    def wait_until_acknowledged(self) -> list[str]:
        """Wait until the subscribers of reliable topics have every message; return the others.

        A fast replay ends while messages are in flight. Waits at most ``ack_timeout`` s in all.
        """
        return wait_until_acknowledged(list(self._outputs.values()), self.waits.ack_timeout_s)

    def wait_until_matched(self) -> None:
        """Block until the subscriptions the graph knows on replayed topics have matched.

        The graph is watched for ``discovery_time`` seconds after the player's node was created
        (Fast DDS announces participants every 3 s); topics in ``wait_for`` additionally need
        a subscription.

        Raises:
            SubscriberTimeoutError: not matched within ``wait_timeout`` seconds.
        """
        outputs = list(self._outputs.values())
        if self._clock is not None:
            outputs.append(self._clock)
        wait_until_matched(
            self.node,
            outputs,
            wait_for=list(self.waits.topics),
            settled_at=self._node_created + self.waits.discovery_s,
            timeout=self.waits.timeout_s,
        )


def play(bag: str | Path, **options: Any) -> PlayReport:
    """Replay ``bag`` once with ``Player(bag, **options)`` and return the report."""
    with Player(bag, **options) as player:
        return player.play()
