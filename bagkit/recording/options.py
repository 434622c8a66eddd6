"""What a recording is asked to do: :class:`RecordOptions`, the options of ``bagkit record``.

Frozen and free of rclpy: the CLI parses its command line into one, a Python user writes one,
and :class:`bagkit.ros.record.recorder.Recorder` runs it. Every default is the CLI's.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from datetime import datetime
from functools import cached_property
from pathlib import Path

from bagkit.bag.file_rotation import FileRotation, FreeSpace
from bagkit.bag.sizes import split_size_problem
from bagkit.bag.writer import DEFAULT_CHUNK_SIZE
from bagkit.recording.errors import RecorderOptionsError
from bagkit.selection.conditions import TopicCondition, parse_topic_condition
from bagkit.selection.errors import SelectionError
from bagkit.selection.record_selection import RecordSelection
from bagkit.selection.times import NS_PER_S
from bagkit.selection.topics import TopicSelection

# Bounds the memory held between taking and writing: absorbs writer hiccups (a slow disk
# write, a chunk to compress); beyond that the middleware holds the messages (see handoff).
DEFAULT_QUEUE_BYTES = 64 << 20
# The least --max-cache-size: below it the queue or buffer holds less than one large message
# (an image) and drops it.
MIN_CACHE_BYTES = 1 << 20
DISCOVERY_PERIOD_NS = NS_PER_S // 10


@dataclass(frozen=True, slots=True)
class FileOptions:
    """The bag's files: compression, splitting, circular recording, the free-space guard.

    Attributes:
        compression: MCAP chunk compression: ``zstd``, ``lz4`` or ``none``.
        max_bag_size: split into a new file at this many bytes (0: never; at least one chunk).
        max_bag_duration_ns: split when a file spans this much log time (0: never).
        max_bag_files: circular recording: keep the newest N files of a split bag (0: all).
        min_free_space: a free-space floor (:meth:`FreeSpace.parse`: ``2GiB``, ``5%``): below
            it the oldest file of a circular bag is deleted, else the recording stops with an
            error (None: no guard).
    """

    compression: str = "zstd"
    max_bag_size: int = 0
    max_bag_duration_ns: int = 0
    max_bag_files: int = 0
    min_free_space: FreeSpace | None = None

    def __post_init__(self) -> None:
        if self.max_bag_size < 0:
            raise RecorderOptionsError("must be >= 0", "files.max_bag_size")
        too_small = split_size_problem(self.max_bag_size, DEFAULT_CHUNK_SIZE)
        if too_small is not None:
            raise RecorderOptionsError(f"{too_small} (one chunk)", "files.max_bag_size")
        if self.max_bag_duration_ns < 0:
            raise RecorderOptionsError("must be >= 0", "files.max_bag_duration_ns")
        if self.max_bag_files < 0:
            raise RecorderOptionsError("must be >= 0", "files.max_bag_files")
        if self.max_bag_files and not self.splits:
            raise RecorderOptionsError(
                "needs the bag split (by size or by duration)", "files.max_bag_files"
            )

    @property
    def splits(self) -> bool:
        """Whether the bag is split into several files."""
        return bool(self.max_bag_size or self.max_bag_duration_ns)

    @property
    def rotation(self) -> FileRotation:
        """The circular-recording and free-space settings, as the bag writer takes them."""
        return FileRotation(self.max_bag_files, self.min_free_space)


@dataclass(frozen=True, slots=True)
class SnapshotTrigger:
    """A snapshot trigger: a message on ``condition.topic`` that satisfies ``condition``.

    Attributes:
        text: as given (``'/alerts: status[*].level >= 2'``), for the report.
        condition: the parsed condition.
    """

    text: str
    condition: TopicCondition

    @classmethod
    def parse(cls, text: str) -> SnapshotTrigger:
        """``'TOPIC: CONDITION'`` parsed.

        Raises:
            RecorderOptionsError: not a topic and a condition (field ``snapshot.triggers``).
        """
        try:
            return cls(text, parse_topic_condition(text))
        except SelectionError as exc:
            raise RecorderOptionsError(str(exc), "snapshot.triggers") from None


@dataclass(frozen=True, slots=True)
class SnapshotOptions:
    """Snapshot mode (the black box): the newest messages kept in memory, a bag per trigger.

    Attributes:
        max_bytes: the buffer's bound in bytes (0: none).
        max_duration_ns: the buffer's bound in log time (0: none); one of the two is needed.
        triggers: conditions on the data that trigger a snapshot.
        pre_ns: a snapshot starts this long before its trigger (None: all that is buffered).
        post_ns: a snapshot goes on this long after its (last) trigger.
    """

    max_bytes: int = 0
    max_duration_ns: int = 0
    triggers: tuple[SnapshotTrigger, ...] = ()
    pre_ns: int | None = None
    post_ns: int = 0

    def __post_init__(self) -> None:
        for name in ("max_bytes", "max_duration_ns", "pre_ns", "post_ns"):
            value = getattr(self, name)
            if value is not None and value < 0:
                raise RecorderOptionsError("must be >= 0", f"snapshot.{name}")
        if not (self.max_bytes or self.max_duration_ns):
            raise RecorderOptionsError(
                "one is needed: the snapshot buffer's bound",
                "snapshot.max_bytes, snapshot.max_duration_ns",
            )


def default_output_name(now: datetime | None = None) -> str:
    """``rosbag2_YYYY_MM_DD-HH_MM_SS`` in local time, as ``ros2 bag record`` names its bags."""
    return (now or datetime.now()).strftime("rosbag2_%Y_%m_%d-%H_%M_%S")


@dataclass(frozen=True)
class RecordOptions:
    """The options of a recording (``bagkit record``'s, docs/record.md).

    Example::

        options = RecordOptions(Path("run1"), topics=("/imu/data",), duration_ns=60 * NS_PER_S)
        report = Recorder(options).run()

    Attributes:
        output: the bag directory to create (it must not exist); None: ``rosbag2_<date-time>``
            in the working directory, named when the recorder is created.
        topics: topic names to record (hidden or not; relative names are made absolute).
        all_topics: record every topic (hidden ones only with ``include_hidden``).
        regex: also record topics whose name contains a match of this regular expression.
        exclude_regex: leave out topics matching this, named ones included.
        include_hidden: let ``all_topics``/``regex`` select hidden topics (``/_x``).
        topic_types: also record topics of these types (``pkg/msg/Name``).
        exclude_topics: leave out these topics, named ones included.
        exclude_topic_types: leave out topics of these types.
        include_unpublished: also subscribe to selected topics that have no publisher.
        services: services whose introspection events to record (``/name/_service_event``).
        all_services: record every service's events (``ros2 bag record --all-services``; ``-a``
            is ``all_topics`` and ``all_services``).
        exclude_services: leave out these services, named ones included.
        actions: actions whose feedback and status topics to record (``/name/_action/...``; the
            goal, result and cancel services' events too where introspection publishes them).
        all_actions: record every action (``ros2 bag record --all-actions``, Kilted; ``-a``
            sets it too).
        exclude_actions: leave out these actions, named ones included.
        custom_data: key -> value pairs for metadata.yaml's ``custom_data``.
        files: compression, splitting, circular recording, the free-space guard.
        duration_ns: ``run()`` stops this long after the topics are subscribed (None: only
            when told to stop).
        max_messages: ``run()`` stops once this many messages are written (None: no limit).
        qos_overrides: a rosbag2 QoS overrides file (``topic: {reliability: ..., ...}``):
            subscribe with these profiles instead of the adapted ones.
        use_sim_time: ``log_time`` is the latest ``/clock`` time when the message was taken;
            messages taken before the first ``/clock`` are not written (counted in
            ``TopicRecord.before_clock``).
        node_name: the recorder node's name.
        queue_bytes: bound of the queue between taking and writing.
        discovery_period_ns: how often the graph is polled for new topics and publishers.
        tune_process: tune the process as ``bagkit record`` does (:mod:`bagkit.ros.tuning`:
            Fast DDS shared-memory queue, malloc thresholds); False leaves the host process
            alone.
        snapshot: snapshot mode: keep the newest messages in memory and write a bag of them
            under ``output`` at each trigger only (None: record everything to one bag).
        repeat_transient_local: topic -> how many of its last messages are written at the
            start of every snapshot and split file.
        repeat_all_transient_local: repeat the last message of every transient-local topic;
            None: on in snapshot mode, off otherwise.
        start_paused: start paused: messages are counted as ``paused`` until
            ``Recorder.resume()``, the ``~/resume`` service or the space key.

    Errors name the field (``files.max_bag_size: must be >= 0``); the CLI names its flag.

    Raises:
        RecorderOptionsError: nothing selected, a value out of its range, a trigger on a topic
            that is not recorded.
        SelectionError: a regular expression does not compile.
    """

    output: Path | None = None
    topics: tuple[str, ...] = ()
    all_topics: bool = False
    regex: str | None = None
    exclude_regex: str | None = None
    include_hidden: bool = False
    topic_types: tuple[str, ...] = ()
    exclude_topics: tuple[str, ...] = ()
    exclude_topic_types: tuple[str, ...] = ()
    include_unpublished: bool = False
    services: tuple[str, ...] = ()
    all_services: bool = False
    exclude_services: tuple[str, ...] = ()
    actions: tuple[str, ...] = ()
    all_actions: bool = False
    exclude_actions: tuple[str, ...] = ()
    custom_data: Mapping[str, str] = field(default_factory=dict)
    files: FileOptions = field(default_factory=FileOptions)
    duration_ns: int | None = None
    max_messages: int | None = None
    qos_overrides: Path | None = None
    use_sim_time: bool = False
    node_name: str = "bagkit_recorder"
    queue_bytes: int = DEFAULT_QUEUE_BYTES
    discovery_period_ns: int = DISCOVERY_PERIOD_NS
    tune_process: bool = True
    snapshot: SnapshotOptions | None = None
    repeat_transient_local: Mapping[str, int] = field(default_factory=dict)
    repeat_all_transient_local: bool | None = None
    start_paused: bool = False

    def __post_init__(self) -> None:
        if self.selection.empty:
            raise RecorderOptionsError(
                "nothing to record: no topic, service or action is selected", "selection"
            )
        if self.duration_ns is not None and self.duration_ns < 0:
            raise RecorderOptionsError("must not be negative", "duration_ns")
        if self.max_messages is not None and self.max_messages < 1:
            raise RecorderOptionsError("must be positive", "max_messages")
        if self.queue_bytes < 1:
            raise RecorderOptionsError("must be positive", "queue_bytes")
        if self.discovery_period_ns <= 0:
            raise RecorderOptionsError("must be positive", "discovery_period_ns")
        if any(depth < 1 for depth in self.repeat_transient_local.values()):
            raise RecorderOptionsError("N must be positive", "repeat_transient_local")
        if self.snapshot is not None:
            for name in ("max_bag_files", "min_free_space"):
                if getattr(self.files, name):
                    raise RecorderOptionsError("does not apply to snapshot mode", f"files.{name}")
            for trigger in self.snapshot.triggers:
                topic = trigger.condition.topic
                if not self.selection.matches(topic) and topic not in self.topics:
                    raise RecorderOptionsError(
                        f"{trigger.text!r}: {topic} is not among the recorded topics",
                        "snapshot.triggers",
                    )

    @property
    def snapshot_mode(self) -> bool:
        """Whether snapshots are written (:attr:`snapshot`) rather than one bag."""
        return self.snapshot is not None

    @property
    def repeats_all_transient_local(self) -> bool:
        """Whether every transient-local topic's last message starts each file and snapshot."""
        if self.repeat_all_transient_local is None:
            return self.snapshot_mode
        return self.repeat_all_transient_local

    @cached_property
    def selection(self) -> RecordSelection:
        """The topic, service and action options, a :class:`RecordSelection` (built once)."""
        topics = TopicSelection.create(
            self.topics,
            all_topics=self.all_topics,
            regex=self.regex,
            exclude=self.exclude_regex,
            include_hidden=self.include_hidden,
            topic_types=self.topic_types,
            exclude_topics=self.exclude_topics,
            exclude_topic_types=self.exclude_topic_types,
        )
        return RecordSelection.of(
            topics,
            self.services,
            all_services=self.all_services,
            exclude_services=self.exclude_services,
            actions=self.actions,
            all_actions=self.all_actions,
            exclude_actions=self.exclude_actions,
        )
