"""What a recording is asked to do: :class:`RecordOptions`, the options of ``bagkit record``.

Frozen and free of rclpy: the CLI parses its command line into one, a Python user writes one,
and :class:`bagkit.ros.record.recorder.Recorder` runs it. Every default is the CLI's.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path

from bagkit.recording.errors import RecorderOptionsError
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
        tune_process: tune the process as ``bagkit record`` does (:mod:`bagkit.ros.tuning`:
            Fast DDS shared-memory queue, malloc thresholds); False leaves the host process
            alone.

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

    def __post_init__(self) -> None:
        if self.selection.empty:
            raise RecorderOptionsError(
                "nothing to record: name topics or services, or use --all, --all-services, --regex "
                "or --topic-types"
            )
        if self.max_bag_size < 0 or self.max_bag_duration_s < 0:
            raise RecorderOptionsError("--max-bag-size and --max-bag-duration must be >= 0")
        if self.duration_s is not None and self.duration_s < 0:
            raise RecorderOptionsError(f"duration must not be negative, got {self.duration_s}")
        if self.max_messages is not None and self.max_messages < 1:
            raise RecorderOptionsError(f"max_messages must be positive, got {self.max_messages}")
        if self.queue_bytes < 1 or self.discovery_period_s <= 0:
            raise RecorderOptionsError("queue_bytes and discovery_period_s must be positive")

    @property
    def selection(self) -> RecordSelection:
        """The topic and service options, a :class:`~bagkit.selection.services.RecordSelection`."""
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
        )
