"""What a replay is asked to do: :class:`PlayOptions` (``bagkit replay``'s), its window, its waits.

Frozen and free of rclpy: the CLI parses its command line into one, a Python user writes one,
and :class:`bagkit.ros.replay.player.Player` runs it. Every default is the CLI's.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path

from bagkit.bag.latched import LatchedOptions
from bagkit.bag.storage_files import bag_path
from bagkit.compat import StrEnum
from bagkit.playback.errors import PlayerError
from bagkit.playback.source import MessageOrder
from bagkit.playback.timing import DEFAULT_DISCOVERY_TIME_NS
from bagkit.selection.errors import SelectionError, UnknownTopicError
from bagkit.selection.query import BagOutline, Query, resolve_names
from bagkit.selection.times import (
    NS_PER_S,
    Anchor,
    TimeLike,
    TimePoint,
    parse_time,
)
from bagkit.selection.topics import TopicSelection
from bagkit.selection.windows import TimeRange, Window, outside_warning


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
        cls, start: TimeLike = 0, duration_ns: int | None = None, until_ns: int | None = None
    ) -> PlayWindow:
        """The window of the player's options (``start`` a time of the one grammar).

        Raises:
            PlayerError: not a time (field ``start_offset``), or a duration that is not
                positive (``duration_ns``).
        """
        try:
            point = parse_time(start, "start offset")
        except SelectionError as exc:
            raise PlayerError(exc.problem, "start_offset") from None
        if duration_ns is not None and not duration_ns > 0:
            raise PlayerError(f"must be positive, got {duration_ns}", "duration_ns")
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
            PlayerError: the window holds none of the bag's messages (an offset past its last
                message, an until before its first): the one message of a window outside a
                bag.
        """
        window_start = max(start_ns, self.start.resolve(start_ns, end_ns))
        ends = []
        if self.duration_ns is not None:
            ends.append(window_start + self.duration_ns)
        if self.until_ns is not None:
            ends.append(self.until_ns + 1)
        window_end = max(ends) if ends else None
        outside = outside_warning(str(bag), Window(window_start, window_end), start_ns, end_ns)
        if outside is not None:
            raise PlayerError(outside)
        return window_start, window_end


@dataclass(frozen=True, slots=True)
class SubscriberWaits:
    """How the player waits for its subscribers, before the first message and after the last.

    Attributes:
        before_start: wait until every subscription the graph shows on a replayed topic has
            matched.
        topics: topics that must have a subscriber before playback starts.
        timeout_ns: how long to wait for them before giving up.
        discovery_ns: after the node's creation, how long the graph is watched for
            subscriptions that already exist.
        ack_timeout_ns: at the end, how long subscribers of reliable topics get to acknowledge
            every message.
    """

    before_start: bool = True
    topics: tuple[str, ...] = ()
    timeout_ns: int = 10 * NS_PER_S
    discovery_ns: int = DEFAULT_DISCOVERY_TIME_NS
    ack_timeout_ns: int = 10 * NS_PER_S

    def __post_init__(self) -> None:
        for name in ("timeout_ns", "discovery_ns", "ack_timeout_ns"):
            if getattr(self, name) < 0:
                raise PlayerError("must be >= 0", f"waits.{name}")

    @property
    def any_before_start(self) -> bool:
        """Whether the player waits before its first message (for the graph, or for topics)."""
        return self.before_start or bool(self.topics)


class ServiceRequestSource(StrEnum):
    """Which recorded service events hold the requests a replay sends."""

    SERVICE = "service_introspection"
    """The server's events."""
    CLIENT = "client_introspection"
    """The client's events."""


@dataclass(frozen=True, slots=True)
class ServiceRequestReplay:
    """Recorded service requests sent to the live services instead of their events republished
    (``--publish-service-requests``), the live responses compared with the recorded ones
    (:mod:`bagkit.ros.replay.service_requests`).

    Attributes:
        source: which recorded events hold the requests.
        timeout_ns: after the last request, how long answers are waited for; requests still
            unanswered then (a service that is not there) count as unanswered.
    """

    source: ServiceRequestSource = ServiceRequestSource.SERVICE
    timeout_ns: int = 5 * NS_PER_S

    def __post_init__(self) -> None:
        if self.timeout_ns < 0:
            raise PlayerError("must be >= 0", "service_requests.timeout_ns")


@dataclass(frozen=True)
class PlayOptions:
    """The options of a replay (``bagkit replay``'s, docs/replay.md).

    Example::

        report = Player(PlayOptions(Path("drive"), rate=2.0, clock_hz=100.0)).run()

    Attributes:
        bag: bag directory or single ``.mcap`` file.
        rate: playback speed factor (2.0 = twice as fast as recorded).
        topics: replay only these topics (union with ``regex``); None = all. A recorded
            service's or action's name stands for its topics; a name the bags lack is an
            error naming the closest (:meth:`selection_in`).
        regex: replay topics whose name matches this regular expression (``re.search``).
        exclude_regex: do not replay topics whose name matches this regular expression.
        exclude_topics: do not replay these topics.
        start_offset: where to start, a time of the one grammar
            (:mod:`bagkit.selection.times`): seconds from the bag's start (``10``, ``1m30s``),
            before its end (``-5``), or absolute (epoch seconds, ISO 8601, ``NNNns``).
        duration_ns: replay only this much bag time (after ``start_offset``).
        until_ns: replay only messages logged at or before this time (ns since the epoch);
            with ``duration_ns``, the later of the two ends the replay (as rosbag2).
        loops: passes over the bag; 0 = until interrupted.
        delay_ns: how long to sleep before each pass.
        clock_hz: publish ``/clock`` at this rate (and before each message); None = off.
        start_paused: start paused (``player.controls.resume()`` or a service resumes).
        services: offer rosbag2's control services and a ``rate`` parameter on the node
            (:mod:`bagkit.ros.replay.services`).
        remap: topic renames, recorded name -> published name.
        waits: how the player waits for its subscribers, before the first message (every
            subscription the graph shows, named topics) and after the last (acknowledgements).
        qos_overrides: rosbag2 QoS overrides file (``topic: {reliability: ..., ...}``).
        service_requests: call each service with its recorded requests at their times instead
            of republishing its events (None: republish the events).
        node_name: name of the player's node.
        progress_period_ns: wall time between two calls of the player's ``on_progress``.
        tune_process: tune the process as ``bagkit replay`` does (:mod:`bagkit.ros.tuning`:
            Fast DDS shared-memory buffers, malloc thresholds, precise timers on the publishing
            thread); False leaves the host process alone.
        more_bags: further bags replayed with ``bag`` as one timeline (``bagkit play A B``).
        message_order: merge and schedule by log time (received) or send time (sent).
        latched: on a late start (``start_offset``, a seek, each loop), first publish the
            last message before it of each latched topic (and of ``extra_topics``);
            ``LatchedOptions(enabled=False)``: none (``--no-latched``).
        seek_step_ns: bag time one seek key moves back or forward.
        on_drift: a topic whose stored definition differs from the installed type's
            (:mod:`bagkit.decode.drift`): skipped, published as recorded, or migrated.
        drift_rules: the rules file of ``on_drift`` migrate (as ``bagkit migrate --rules``).

    Errors name the field (``waits.timeout_ns: must be >= 0``); the CLI names its flag.

    Raises:
        PlayerError: an option out of its range, or a regular expression that does not compile.
    """

    bag: Path
    rate: float = 1.0
    topics: tuple[str, ...] | None = None
    regex: str | None = None
    exclude_regex: str | None = None
    exclude_topics: tuple[str, ...] = ()
    start_offset: TimeLike = 0
    duration_ns: int | None = None
    until_ns: int | None = None
    loops: int = 1
    delay_ns: int = 0
    clock_hz: float | None = None
    start_paused: bool = False
    services: bool = True
    remap: Mapping[str, str] = field(default_factory=dict)
    waits: SubscriberWaits = field(default_factory=SubscriberWaits)
    qos_overrides: Path | None = None
    service_requests: ServiceRequestReplay | None = None
    node_name: str = "bagkit_player"
    progress_period_ns: int = NS_PER_S // 2
    tune_process: bool = True
    more_bags: tuple[Path, ...] = ()
    message_order: MessageOrder = MessageOrder.RECEIVED
    latched: LatchedOptions = field(default_factory=LatchedOptions)
    seek_step_ns: int = 5 * NS_PER_S
    on_drift: OnDrift = OnDrift.SKIP
    drift_rules: Path | None = None

    def __post_init__(self) -> None:
        if not 0 < self.rate < float("inf"):
            raise PlayerError(f"must be positive, got {self.rate}", "rate")
        if self.delay_ns < 0:
            raise PlayerError("must not be negative", "delay_ns")
        if self.clock_hz is not None and not 0 < self.clock_hz < float("inf"):
            raise PlayerError(f"must be positive, got {self.clock_hz}", "clock_hz")
        if self.loops < 0:
            raise PlayerError(f"must be 0 (forever) or positive, got {self.loops}", "loops")
        if self.progress_period_ns <= 0:
            raise PlayerError(
                f"must be positive, got {self.progress_period_ns}", "progress_period_ns"
            )
        if self.seek_step_ns <= 0:
            raise PlayerError(f"must be positive, got {self.seek_step_ns}", "seek_step_ns")
        if self.latched.extra_topics and not self.latched.enabled:
            raise PlayerError("extra topics without latched state", "latched")
        _ = self.window, self.selection  # their own checks

    @cached_property
    def window(self) -> PlayWindow:
        """The part of the bag each pass replays."""
        return PlayWindow.create(self.start_offset, self.duration_ns, self.until_ns)

    @property
    def bags(self) -> tuple[Path, ...]:
        """Every bag of the replay, ``bag`` first."""
        return (bag_path(self.bag), *self.more_bags)

    @cached_property
    def query(self) -> Query:
        """The topics asked for (a service or an action by its name) and where each pass
        starts, as every command's query; resolved against the bags by :meth:`selection_in`."""
        return Query(self.topics or (), span=TimeRange(self.window.start))

    def selection_in(self, bags: BagOutline, label: str) -> TopicSelection:
        """:attr:`selection` against the replay's bags: the named topics as they store them (a
        service's event topic, an action's topics), and so the excluded ones where they can.

        Raises:
            UnknownTopicError: a named topic is in none of the bags (the message names the
                closest ones, as every command's).
        """
        types = {name: info.type for name, info in bags.topics.items()}
        named = self.query.resolve(bags, label=label).topics
        excluded: list[str] = []
        for name in self.exclude_topics:  # an exclusion the bags lack excludes nothing
            try:
                excluded += resolve_names([name], types)
            except UnknownTopicError:
                excluded.append(name)
        return replace(self.selection, topics=frozenset(named), exclude_topics=frozenset(excluded))

    @cached_property
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
