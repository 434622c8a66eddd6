"""What a recording is asked to do: :class:`RecordOptions`, the options of ``bagkit record``.

Frozen and free of rclpy: the CLI parses its command line into one, a Python user writes one,
and :class:`bagkit.ros.record.recorder.Recorder` runs it. Every default is the CLI's.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path

from bagkit.bag.errors import BagError
from bagkit.bag.file_rotation import FileRotation, FreeSpace
from bagkit.bag.sizes import split_size_problem
from bagkit.bag.writer import DEFAULT_CHUNK_SIZE
from bagkit.recording.errors import RecorderOptionsError
from bagkit.selection.conditions import TopicCondition, parse_topic_condition
from bagkit.selection.errors import SelectionError
from bagkit.selection.services import RecordSelection
from bagkit.selection.topics import TopicSelection

# Bounds the memory held between taking and writing: absorbs writer hiccups (a slow disk
# write, a chunk to compress); beyond that the middleware holds the messages (see handoff).
DEFAULT_QUEUE_BYTES = 64 << 20
DISCOVERY_PERIOD_S = 0.1


def default_output_name(now: datetime | None = None) -> str:
    """``rosbag2_YYYY_MM_DD-HH_MM_SS`` in local time, as ``ros2 bag record`` names its bags."""
    return (now or datetime.now()).strftime("rosbag2_%Y_%m_%d-%H_%M_%S")


@dataclass(frozen=True)
class RecordOptions:
    """The options of a recording (``bagkit record``'s, docs/record.md).

    Example::

        options = RecordOptions(Path("run1"), topics=("/imu/data",), duration_s=60)
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
        compression: MCAP chunk compression: ``zstd``, ``lz4`` or ``none``.
        max_bag_size: split into a new file at this many bytes (0: never).
        max_bag_duration_s: split when a file spans this many seconds (0: never).
        duration_s: ``run()`` stops this many seconds after the topics are subscribed (None:
            only when told to stop).
        max_messages: ``run()`` stops once this many messages are written (None: no limit).
        qos_overrides: a rosbag2 QoS overrides file (``topic: {reliability: ..., ...}``):
            subscribe with these profiles instead of the adapted ones.
        use_sim_time: ``log_time`` is the latest ``/clock`` time when the message was taken;
            messages taken before the first ``/clock`` are not written (counted in
            ``TopicRecord.before_clock``).
        node_name: the recorder node's name.
        queue_bytes: bound of the queue between taking and writing (``--max-cache-size``).
        discovery_period_s: how often the graph is polled for new topics and publishers.
        tune_process: tune the process as ``bagkit record`` does (:mod:`bagkit.native`:
            Fast DDS shared-memory queue, malloc thresholds); False leaves the host process
            alone.
        snapshot_mode: keep the newest messages in memory and write a bag of them under
            ``output`` at each trigger only (``--snapshot-mode``).
        snapshot_max_bytes: the snapshot buffer's bound in bytes (``--max-cache-size`` in
            snapshot mode; 0: none).
        snapshot_max_duration_s: the snapshot buffer's bound in seconds of log time
            (``--max-cache-duration``; 0: none).
        triggers: ``'TOPIC: CONDITION'`` texts: a message on TOPIC that satisfies the field
            condition triggers a snapshot (``--trigger``).
        pre_s: a snapshot starts this long before its trigger (None: all that is buffered).
        post_s: a snapshot goes on this long after its (last) trigger.
        repeat_transient_local: topic -> how many of its last messages are written at the
            start of every snapshot and split file (``--repeat-transient-local TOPIC[=N]``).
        repeat_all_transient_local: repeat the last message of every transient-local topic
            (``--repeat-all-transient-local``); None: on in snapshot mode, off otherwise.
        max_bag_files: circular recording: keep the newest N files of a split bag (0: all).
        min_free_space: a free-space floor (``2GiB``, ``5%``): below it the oldest file of a
            circular bag is deleted, else the recording stops with an error (None: no guard).
        start_paused: start paused (``--start-paused``): messages are counted as ``paused``
            until ``Recorder.resume()``, the ``~/resume`` service or the space key.

    Raises:
        RecorderOptionsError: nothing selected, a negative limit.
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
    compression: str = "zstd"
    max_bag_size: int = 0
    max_bag_duration_s: float = 0
    duration_s: float | None = None
    max_messages: int | None = None
    qos_overrides: Path | None = None
    use_sim_time: bool = False
    node_name: str = "bagkit_recorder"
    queue_bytes: int = DEFAULT_QUEUE_BYTES
    discovery_period_s: float = DISCOVERY_PERIOD_S
    tune_process: bool = True
    snapshot_mode: bool = False
    snapshot_max_bytes: int = 0
    snapshot_max_duration_s: float = 0
    triggers: tuple[str, ...] = ()
    pre_s: float | None = None
    post_s: float = 0
    repeat_transient_local: Mapping[str, int] = field(default_factory=dict)
    repeat_all_transient_local: bool | None = None
    start_paused: bool = False
    max_bag_files: int = 0
    min_free_space: str | None = None

    def __post_init__(self) -> None:
        if self.selection.empty:
            raise RecorderOptionsError(
                "nothing to record: name topics, services or actions, or use --all, "
                "--all-services, --all-actions, --regex or --topic-types"
            )
        if self.max_bag_size < 0 or self.max_bag_duration_s < 0:
            raise RecorderOptionsError("--max-bag-size and --max-bag-duration must be >= 0")
        too_small = split_size_problem(self.max_bag_size, DEFAULT_CHUNK_SIZE)
        if too_small is not None:
            raise RecorderOptionsError(f"--max-bag-size: {too_small} (one chunk)")
        if self.duration_s is not None and self.duration_s < 0:
            raise RecorderOptionsError(f"duration must not be negative, got {self.duration_s}")
        if self.max_messages is not None and self.max_messages < 1:
            raise RecorderOptionsError(f"max_messages must be positive, got {self.max_messages}")
        if self.queue_bytes < 1 or self.discovery_period_s <= 0:
            raise RecorderOptionsError("queue_bytes and discovery_period_s must be positive")
        check_snapshot_options(self)
        check_rotation_options(self)

    @property
    def rotation(self) -> FileRotation:
        """The circular-recording and free-space settings, parsed."""
        floor = None if self.min_free_space is None else FreeSpace.parse(self.min_free_space)
        return FileRotation(self.max_bag_files, floor)

    @property
    def repeats_all_transient_local(self) -> bool:
        """Whether every transient-local topic's last message starts each file and snapshot."""
        if self.repeat_all_transient_local is None:
            return self.snapshot_mode
        return self.repeat_all_transient_local

    @property
    def trigger_conditions(self) -> list[TopicCondition]:
        """The parsed ``triggers``."""
        return [parse_topic_condition(text) for text in self.triggers]

    @property
    def selection(self) -> RecordSelection:
        """The topic, service and action options, a :class:`RecordSelection`."""
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


def check_snapshot_options(options: RecordOptions) -> None:
    """Raise RecorderOptionsError for snapshot settings that do not go together or parse."""
    if options.snapshot_mode:
        if options.snapshot_max_bytes < 0 or options.snapshot_max_duration_s < 0:
            raise RecorderOptionsError("--max-cache-size and --max-cache-duration must be >= 0")
        if not (options.snapshot_max_bytes or options.snapshot_max_duration_s):
            raise RecorderOptionsError(
                "--snapshot-mode needs a bound: --max-cache-size or --max-cache-duration"
            )
    elif options.triggers or options.snapshot_max_duration_s or options.post_s:
        raise RecorderOptionsError(
            "--trigger, --max-cache-duration and --post need --snapshot-mode"
        )
    if (options.pre_s is not None and options.pre_s < 0) or options.post_s < 0:
        raise RecorderOptionsError("--pre and --post must be >= 0")
    if any(depth < 1 for depth in options.repeat_transient_local.values()):
        raise RecorderOptionsError("--repeat-transient-local: N must be positive")
    for text in options.triggers:
        try:
            topic = parse_topic_condition(text).topic
        except SelectionError as exc:
            raise RecorderOptionsError(f"--trigger {exc}") from None
        if not options.selection.matches(topic) and topic not in options.topics:
            raise RecorderOptionsError(
                f"--trigger {text!r}: {topic} is not among the recorded topics"
            )


def check_rotation_options(options: RecordOptions) -> None:
    """Raise RecorderOptionsError for --max-bag-files / --min-free-space that cannot work."""
    if options.max_bag_files < 0:
        raise RecorderOptionsError("--max-bag-files must be >= 0")
    if options.max_bag_files and not (options.max_bag_size or options.max_bag_duration_s):
        raise RecorderOptionsError("--max-bag-files needs splitting: -b or -d")
    if options.snapshot_mode and (options.max_bag_files or options.min_free_space):
        raise RecorderOptionsError(
            "--max-bag-files and --min-free-space do not apply to --snapshot-mode"
        )
    try:
        _ = options.rotation
    except BagError as exc:
        raise RecorderOptionsError(str(exc)) from None
