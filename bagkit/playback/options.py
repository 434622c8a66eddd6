"""What a replay is asked to do: :class:`PlayOptions` (``bagkit replay``'s), its window, its waits.

Frozen and free of rclpy: the CLI parses its command line into one, a Python user writes one,
and :class:`bagkit.ros.replay.player.Player` runs it. Every default is the CLI's.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

from bagkit.bag.latched import LatchedOptions
from bagkit.bag.reader import bag_path
from bagkit.compat import StrEnum
from bagkit.playback.errors import PlayerError
from bagkit.playback.source import MessageOrder
from bagkit.playback.timing import DEFAULT_DISCOVERY_TIME_S
from bagkit.selection.errors import SelectionError
from bagkit.selection.times import Anchor, TimeLike, TimePoint, parse_time, seconds_to_ns
from bagkit.selection.topics import TopicSelection


class OnDrift(StrEnum):
    """What a replay does with a topic whose stored definition differs from the installed one."""

    SKIP = "skip"
    """Publish nothing on it (its subscribers would get messages of another layout)."""
    RAW = "raw"
    """Publish its bytes as recorded."""
    MIGRATE = "migrate"
    """Publish each message migrated to the installed definition (:mod:`bagkit.migrate`)."""


@dataclass(frozen=True, slots=True)
class PlayWindow:
    """The part of the bag each pass replays (``--start-offset``, ``--duration``, until).

    Attributes:
        start: where each pass starts, in the one time grammar: from the bag's first message
            (``10``, ``1m30s``), before its last (``-5``), or absolute (epoch, ISO 8601).
        duration_ns: bag time replayed after the offset; None = to the end.
        until_ns: last log time replayed (ns since the epoch); with ``duration_ns`` the later
            of the two ends the window (as rosbag2).
    """

    start: TimePoint = field(default_factory=lambda: TimePoint(Anchor.START, 0))
    duration_ns: int | None = None
    until_ns: int | None = None

    @classmethod
    def create(
        cls, start: TimeLike = 0.0, duration: float | None = None, until_ns: int | None = None
    ) -> PlayWindow:
        """The window of the player's options (``start`` a time, ``duration`` in seconds).

        Raises:
            PlayerError: not a time, or a duration that is not positive.
        """
        try:
            point = parse_time(start, "start offset")
        except SelectionError as exc:
            raise PlayerError(str(exc)) from None
        if duration is not None and not duration > 0:
            raise PlayerError(f"duration must be positive, got {duration}")
        duration_ns = None if duration is None else seconds_to_ns(duration, duration, PlayerError)
        return cls(point, duration_ns, until_ns)

    @property
    def whole(self) -> bool:
        """Whether every message of the bag is in the window."""
        return (
            self.start == TimePoint(Anchor.START, 0)
            and self.duration_ns is None
            and self.until_ns is None
        )

    def bounds(self, start_ns: int, end_ns: int, bag: Path) -> tuple[int, int | None]:
        """Log-time bounds (start, exclusive end or None) in a bag of messages start..end.

        Raises:
            PlayerError: the offset is past the bag's last message (nothing would be replayed).
        """
        window_start = max(start_ns, self.start.resolve(start_ns, end_ns))
        if window_start > end_ns:
            raise PlayerError(
                f"the start offset {(window_start - start_ns) / 1e9:g} s is past the end of "
                f"{bag} ({(end_ns - start_ns) / 1e9:.3f} s of messages)"
            )
        ends = []
        if self.duration_ns is not None:
            ends.append(window_start + self.duration_ns)
        if self.until_ns is not None:
            ends.append(self.until_ns + 1)
        return window_start, max(ends) if ends else None


@dataclass(frozen=True, slots=True)
class SubscriberWaits:
    """How the player waits for its subscribers, before the first message and after the last.

    Attributes:
        before_start: wait until every subscription the graph shows on a replayed topic has
            matched.
        topics: topics that must have a subscriber before playback starts.
        timeout_s: how long to wait for them before giving up.
        discovery_s: after the node's creation, how long the graph is watched for
            subscriptions that already exist.
        ack_timeout_s: at the end, how long subscribers of reliable topics get to acknowledge
            every message.
    """

    before_start: bool = True
    topics: tuple[str, ...] = ()
    timeout_s: float = 10.0
    discovery_s: float = DEFAULT_DISCOVERY_TIME_S
    ack_timeout_s: float = 10.0


@dataclass(frozen=True)
class PlayOptions:
    """The options of a replay (``bagkit replay``'s, docs/replay.md).

    Example::

        report = Player(PlayOptions(Path("drive"), rate=2.0, clock_hz=100.0)).run()

    Attributes:
        bag: bag directory or single ``.mcap`` file.
        rate: playback speed factor (2.0 = twice as fast as recorded).
        topics: replay only these topics (union with ``regex``); None = all.
        regex: replay topics whose name matches this regular expression (``re.search``).
        exclude_regex: do not replay topics whose name matches this regular expression.
        exclude_topics: do not replay these topics.
        start_offset_s: where to start, a time of the one grammar
            (:mod:`bagkit.selection.times`): seconds from the bag's start (``10``, ``1m30s``),
            before its end (``-5``), or absolute (epoch seconds, ISO 8601, ``NNNns``).
        duration_s: replay only this many seconds of bag time (after ``start_offset_s``).
        until_ns: replay only messages logged at or before this time (ns since the epoch);
            with ``duration_s``, the later of the two ends the replay (as rosbag2).
        loops: passes over the bag; 0 = until interrupted.
        delay_s: seconds to sleep before each pass.
        clock_hz: publish ``/clock`` at this rate (and before each message); None = off.
        start_paused: start paused (``player.controls.resume()`` or a service resumes).
        services: offer rosbag2's control services and a ``rate`` parameter on the node
            (:mod:`bagkit.ros.replay.services`).
        remap: topic renames, recorded name -> published name.
        wait_for_subscribers: before the first message, wait until every subscription that
            the graph shows on a replayed topic has matched.
        wait_for: topics that must have at least one subscriber before playback starts
            (for consumers that are still starting up).
        wait_timeout_s: seconds to wait for subscribers before giving up.
        discovery_time_s: seconds after the node's creation during which the graph is watched
            for subscriptions that already exist.
        ack_timeout_s: at the end, seconds to wait for subscribers of reliable topics to
            acknowledge every message.
        qos_overrides: rosbag2 QoS overrides file (``topic: {reliability: ..., ...}``).
        publish_service_requests: instead of republishing service events, call each service
            with its recorded requests at their times and compare the live responses with the
            recorded ones (:mod:`bagkit.ros.replay.service_requests`).
        service_requests_source: which recorded events hold the requests to send:
            ``service_introspection`` (the server's) or ``client_introspection`` (the client's).
        service_timeout_s: after the last request, how long answers are waited for; requests
            still unanswered then (a service that is not there) count as unanswered.
        node_name: name of the player's node.
        progress_period_s: seconds between two calls of the player's ``on_progress``.
        tune_process: tune the process as ``bagkit replay`` does (:mod:`bagkit.native`:
            Fast DDS shared-memory buffers, malloc thresholds, precise timers on the publishing
            thread); False leaves the host process alone.
        more_bags: further bags replayed with ``bag`` as one timeline (``bagkit play A B``).
        message_order: merge and schedule by log time (received) or send time (sent).
        latched: on a late start (``start_offset_s``, a seek, each loop), first publish the
            last message before it of each latched topic (``--no-latched``: False).
        latched_topics: topics recorded volatile whose state is carried over too.
        seek_step_s: bag time one seek key moves back or forward.
        on_drift: a topic whose stored definition differs from the installed type's
            (:mod:`bagkit.decode.drift`): skipped, published as recorded, or migrated.
        drift_rules: the rules file of ``on_drift`` migrate (as ``bagkit migrate --rules``).

    Raises:
        PlayerError: an option out of its range, or a regular expression that does not compile.
    """

    bag: Path
    rate: float = 1.0
    topics: tuple[str, ...] | None = None
    regex: str | None = None
    exclude_regex: str | None = None
    exclude_topics: tuple[str, ...] = ()
    start_offset_s: TimeLike = 0.0
    duration_s: float | None = None
    until_ns: int | None = None
    loops: int = 1
    delay_s: float = 0.0
    clock_hz: float | None = None
    start_paused: bool = False
    services: bool = True
    remap: Mapping[str, str] = field(default_factory=dict)
    wait_for_subscribers: bool = True
    wait_for: tuple[str, ...] = ()
    wait_timeout_s: float = 10.0
    discovery_time_s: float = DEFAULT_DISCOVERY_TIME_S
    ack_timeout_s: float = 10.0
    qos_overrides: Path | None = None
    publish_service_requests: bool = False
    service_requests_source: str = "service_introspection"
    service_timeout_s: float = 5.0
    node_name: str = "bagkit_player"
    progress_period_s: float = 0.5
    tune_process: bool = True
    more_bags: tuple[Path, ...] = ()
    message_order: MessageOrder = MessageOrder.RECEIVED
    latched: bool = True
    latched_topics: tuple[str, ...] = ()
    seek_step_s: float = 5.0
    on_drift: OnDrift = OnDrift.SKIP
    drift_rules: Path | None = None

    def __post_init__(self) -> None:
        if not self.rate > 0:
            raise PlayerError(f"rate must be positive, got {self.rate}")
        if self.delay_s < 0:
            raise PlayerError(f"delay must not be negative, got {self.delay_s}")
        if self.clock_hz is not None and not self.clock_hz > 0:
            raise PlayerError(f"clock rate must be positive, got {self.clock_hz}")
        if self.loops < 0:
            raise PlayerError(f"loops must be 0 (forever) or positive, got {self.loops}")
        seconds_to_ns(self.progress_period_s, self.progress_period_s, PlayerError)
        if not self.seek_step_s > 0:
            raise PlayerError(f"seek step must be positive, got {self.seek_step_s}")
        if self.latched_topics and not self.latched:
            raise PlayerError("--latched-topics and --no-latched exclude each other")
        if self.service_requests_source not in ("service_introspection", "client_introspection"):
            raise PlayerError(
                f"service requests source {self.service_requests_source!r}: use "
                "service_introspection or client_introspection"
            )
        if self.service_timeout_s < 0:
            raise PlayerError(f"service timeout must not be negative, got {self.service_timeout_s}")
        _ = self.window, self.selection  # their own checks

    @property
    def window(self) -> PlayWindow:
        """The part of the bag each pass replays."""
        return PlayWindow.create(self.start_offset_s, self.duration_s, self.until_ns)

    @property
    def bags(self) -> tuple[Path, ...]:
        """Every bag of the replay, ``bag`` first."""
        return (bag_path(self.bag), *self.more_bags)

    @property
    def latched_options(self) -> LatchedOptions:
        """Which topics carry their state over to a late start."""
        return LatchedOptions(enabled=self.latched, extra_topics=self.latched_topics)

    @property
    def seek_step_ns(self) -> int:
        """:attr:`seek_step_s` in nanoseconds."""
        return seconds_to_ns(self.seek_step_s, self.seek_step_s, PlayerError)

    @property
    def waits(self) -> SubscriberWaits:
        """How the player waits for its subscribers."""
        return SubscriberWaits(
            self.wait_for_subscribers,
            self.wait_for,
            self.wait_timeout_s,
            self.discovery_time_s,
            self.ack_timeout_s,
        )

    @property
    def selection(self) -> TopicSelection:
        """The topic options as a selection: all topics unless ``topics``/``regex``.

        A bag's topics were chosen when it was recorded: hidden ones replay like the others.
        """
        return TopicSelection.create(
            self.topics or (),
            all_topics=self.topics is None and self.regex is None,
            regex=self.regex,
            exclude=self.exclude_regex,
            include_hidden=True,
            exclude_topics=self.exclude_topics,
            error=PlayerError,
        )
