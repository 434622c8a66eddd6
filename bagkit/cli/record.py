"""``bagkit record``: record topics into a rosbag2-compatible MCAP bag, counting every loss."""

from __future__ import annotations

import contextlib
import re
import signal
import sys
import threading
from collections.abc import Callable
from types import FrameType
from typing import TYPE_CHECKING

import typer

from bagkit.cli.common import (
    EXIT_INTERRUPTED,
    ReportFormat,
    err_console,
    fail,
    handle_errors,
    option_flags,
    print_json,
    warn,
)
from bagkit.cli.option_parsing import MultiValueCommand, split_list
from bagkit.cli.record_options import (
    RECORD_FLAGS,
    Actions,
    AllActions,
    AllServices,
    AllTopics,
    AllTopicsAndServices,
    CompressionFormat,
    CompressionFormatOption,
    CompressionMode,
    CompressionModeOption,
    CustomData,
    Duration,
    ExcludeActions,
    ExcludeRegex,
    ExcludeServices,
    ExcludeTopics,
    ExcludeTopicTypes,
    Format,
    Health,
    IncludeHidden,
    IncludeUnpublished,
    LogLevel,
    LogLevelOption,
    MaxBagDuration,
    MaxBagFiles,
    MaxBagSize,
    MaxCacheDuration,
    MaxCacheSize,
    MinFreeSpace,
    NodeName,
    Output,
    PollingInterval,
    Post,
    Pre,
    QosOverrides,
    Regex,
    RepeatAllTransientLocal,
    RepeatTransientLocal,
    Services,
    SnapshotMode,
    StartPaused,
    StopOnHealth,
    Storage,
    Topics,
    TopicsPositional,
    TopicTypes,
    TriggerOnHealth,
    TriggerOption,
    UseSimTime,
)
from bagkit.cli.record_table import print_record_table, progress_line
from bagkit.extras import ROS, require
from bagkit.playback.keyboard import key_presses
from bagkit.recording.latched import parse_repeat
from bagkit.recording.options import (
    DEFAULT_QUEUE_BYTES,
    MIN_CACHE_BYTES,
    FileOptions,
    RecordOptions,
    SnapshotOptions,
    SnapshotTrigger,
)
from bagkit.recording.report import RecordProgress, RecordReport
from bagkit.selection.times import parse_duration

if TYPE_CHECKING:
    from pathlib import Path

    from rich.status import Status

    from bagkit.health.live import LiveHealth
    from bagkit.recording.health_watch import HealthEvent

    # The recorder imports rclpy: only `bagkit record` itself pays for that import.
    from bagkit.ros.record.recorder import Recorder

HELP = (
    "Record TOPICS (or --topics, --all, --regex, --topic-types) into an MCAP bag that ros2 bag, "
    "Foxglove and rosbags read. Options are ros2 bag record's (docs/cli.md).\n\n"
    "Topics are discovered at start and while recording (--polling-interval); each is "
    "subscribed with QoS adapted to its publishers (reliable / transient-local only if every "
    "publisher is). Stops on Ctrl-C, SIGTERM or --duration (counted from when the topics are "
    "subscribed), finishes the bag and prints per topic: messages, lost, rate and bytes. Lost "
    "counts gaps in the publishers' sequence numbers (loss inside the middleware), write-queue "
    "overflows and write failures. -d/--max-bag-duration splits the bag, as in ros2 bag.\n\n"
    "Black box: --snapshot-mode keeps the newest messages in memory and writes a bag per "
    "trigger (--trigger 'TOPIC: CONDITION', ~/snapshot, the s key); --max-bag-files, "
    "--min-free-space, --start-paused and the space key as in docs/record.md.\n\n"
    "Health: --health SPEC checks bagkit check's contract on what is recorded and prints a "
    "line when a check breaks or clears; --trigger-on-health makes a broken check a snapshot "
    "trigger, --stop-on-health DURATION a guardrail.\n\n"
    "Exit status: 0 after --duration, 130 after Ctrl-C, 143 after SIGTERM (the bag is complete "
    "in all three), 1 when recording failed (disk full: the bag keeps what was written), "
    "2 for bad options or an existing output.\n\n"
    "Example:\n\n  bagkit record --topics /imu/data /gps/fix -o run1 --duration 60"
)


def chunk_compression(mode: CompressionMode | None, fmt: CompressionFormat | None) -> str:
    """ros2 bag's compression options -> bagkit's chunk compression (zstd, lz4 or none).

    rosbag2's ``file`` mode compresses whole files (``.mcap.zstd``, which MCAP readers
    cannot open) and ``message`` each message; bagkit compresses MCAP chunks in both, which
    every MCAP reader decompresses. Without either option bagkit keeps its zstd default.
    """
    if mode is CompressionMode.NONE:
        if fmt is not None:
            raise fail("--compression-format needs a --compression-mode other than none")
        return "none"
    return (fmt or CompressionFormat.ZSTD).value


def parse_custom_data(values: list[str]) -> dict[str, str]:
    """``KEY=VALUE`` pairs (``--custom-data``) -> dict; a pair without ``=`` is bad input.

    Comma lists split only before a ``KEY=``: ``a=1,b=2`` is two pairs, ``a=1,2`` one.
    """
    data = {}
    pairs = [pair for value in values for pair in re.split(r",(?=[^,=]+=)", value)]
    for pair in pairs:
        key, sep, value = pair.partition("=")
        if not sep or not key:
            raise fail(f"--custom-data {pair!r} is not KEY=VALUE")
        data[key] = value
    return data


class RecordCommand(MultiValueCommand):
    """``ros2 bag record``'s options that take several values (its ``nargs='+'``)."""

    multi_value = frozenset(
        {"--topics", "--topic-types", "--exclude-topics", "--exclude-topic-types", "--custom-data"}
        | {"--services", "--exclude-services", "--actions", "--exclude-actions"}
    )
    bag_positional = False  # the positional arguments are topics


COMMAND_CLASS = RecordCommand
# The keys, when stdin is a terminal: pause/resume, a snapshot (--snapshot-mode).
PAUSE_KEY = b" "
SNAPSHOT_KEY = b"s"


@handle_errors
def record(  # noqa: PLR0917 (typer maps parameters to options; ros2 bag has them all)
    topics_positional: TopicsPositional = None,
    topics: Topics = None,
    topic_types: TopicTypes = None,
    all_topics: AllTopics = False,
    all_topics_and_services: AllTopicsAndServices = False,
    services: Services = None,
    all_services: AllServices = False,
    exclude_services: ExcludeServices = None,
    actions: Actions = None,
    all_actions: AllActions = False,
    exclude_actions: ExcludeActions = None,
    regex: Regex = None,
    exclude_regex: ExcludeRegex = None,
    exclude_topics: ExcludeTopics = None,
    exclude_topic_types: ExcludeTopicTypes = None,
    include_hidden: IncludeHidden = False,
    include_unpublished: IncludeUnpublished = False,
    output: Output = None,
    storage: Storage = "mcap",
    max_bag_size: MaxBagSize = 0,
    max_bag_duration: MaxBagDuration = 0,
    duration: Duration = None,
    compression_mode: CompressionModeOption = None,
    compression_format: CompressionFormatOption = None,
    qos_overrides: QosOverrides = None,
    use_sim_time: UseSimTime = False,
    node_name: NodeName = "bagkit_recorder",
    custom_data: CustomData = None,
    max_cache_size: MaxCacheSize = None,
    polling_interval: PollingInterval = 100,
    log_level: LogLevelOption = LogLevel.INFO,
    output_format: Format = ReportFormat.TABLE,
    snapshot_mode: SnapshotMode = False,
    max_cache_duration: MaxCacheDuration = None,
    trigger: TriggerOption = None,
    pre: Pre = None,
    post: Post = None,
    repeat_transient_local: RepeatTransientLocal = None,
    repeat_all_transient_local: RepeatAllTransientLocal = None,
    start_paused: StartPaused = False,
    max_bag_files: MaxBagFiles = 0,
    min_free_space: MinFreeSpace = None,
    health: Health = None,
    trigger_on_health: TriggerOnHealth = False,
    stop_on_health: StopOnHealth = None,
) -> None:
    require(ROS, "bagkit record")
    from bagkit.ros.record.recorder import Recorder

    if storage != "mcap":
        raise fail(f"--storage {storage}: bagkit records MCAP only (it reads sqlite3 bags)")
    quiet = log_level in (LogLevel.ERROR, LogLevel.FATAL)
    if max_cache_size is not None and max_cache_size < MIN_CACHE_BYTES:
        raise fail(f"--max-cache-size {max_cache_size}: at least 1 MiB ({MIN_CACHE_BYTES} bytes)")
    if not snapshot_mode:
        snapshot_only = {
            "--trigger": trigger,
            "--max-cache-duration": max_cache_duration,
            "--pre": pre,
            "--post": post,
        }
        if given := [flag for flag, value in snapshot_only.items() if value is not None]:
            raise fail(f"{', '.join(given)}: need --snapshot-mode")
    with option_flags(RECORD_FLAGS):
        snapshot = (
            SnapshotOptions(
                max_bytes=max_cache_size or 0,
                max_duration_ns=max_cache_duration or 0,
                triggers=tuple(SnapshotTrigger.parse(text) for text in trigger or ()),
                pre_ns=pre,
                post_ns=post or 0,
            )
            if snapshot_mode
            else None
        )
        options = RecordOptions(
            output=output,
            topics=tuple(split_list(topics_positional) + split_list(topics)),
            all_topics=all_topics or all_topics_and_services,
            services=tuple(split_list(services)),
            all_services=all_services or all_topics_and_services,
            exclude_services=tuple(split_list(exclude_services)),
            actions=tuple(split_list(actions)),
            all_actions=all_actions or all_topics_and_services,
            exclude_actions=tuple(split_list(exclude_actions)),
            regex=regex,
            exclude_regex=exclude_regex,
            include_hidden=include_hidden,
            topic_types=tuple(split_list(topic_types)),
            exclude_topics=tuple(split_list(exclude_topics)),
            exclude_topic_types=tuple(split_list(exclude_topic_types)),
            include_unpublished=include_unpublished,
            custom_data=parse_custom_data(custom_data or []),
            files=FileOptions(
                compression=chunk_compression(compression_mode, compression_format),
                max_bag_size=max_bag_size,
                max_bag_duration_ns=max_bag_duration,
                max_bag_files=max_bag_files,
                min_free_space=min_free_space,
            ),
            duration_ns=duration,
            qos_overrides=qos_overrides,
            use_sim_time=use_sim_time,
            node_name=node_name,
            queue_bytes=DEFAULT_QUEUE_BYTES
            if snapshot_mode or max_cache_size is None
            else max_cache_size,
            discovery_period_ns=polling_interval * 1_000_000,
            snapshot=snapshot,
            repeat_transient_local=parse_repeat(repeat_transient_local or []),
            repeat_all_transient_local=repeat_all_transient_local,
            start_paused=start_paused,
        )
    with option_flags(RECORD_FLAGS):
        watch = _health_watch(health, trigger_on_health, stop_on_health, quiet=quiet)
        recorder = Recorder(
            options, on_warning=(lambda _message: None) if quiet else warn, health=watch
        )
    report, received = _record_until_stopped(recorder)
    _print_outcome(report, received, output_format, quiet=quiet)


def _health_watch(
    spec: Path | None, trigger: bool, stop_after: str | None, *, quiet: bool
) -> LiveHealth | None:
    """The live health check of ``--health`` (None without it); its lines go to stderr."""
    if spec is None:
        if trigger or stop_after is not None:
            raise fail("--trigger-on-health and --stop-on-health need --health SPEC")
        return None
    from bagkit.health.live import LiveHealth
    from bagkit.health.spec import HealthSpec

    def tell(event: HealthEvent) -> None:
        err_console.print(event.line(), style="red" if event.broken else None, highlight=False)

    stop_after_ns = None if stop_after is None else parse_duration(stop_after, "--stop-on-health")
    return LiveHealth(
        HealthSpec.load(spec),
        trigger=trigger,
        stop_after_ns=stop_after_ns,
        on_event=None if quiet else tell,
    )


def _print_outcome(
    report: RecordReport, received: list[int], output_format: ReportFormat, *, quiet: bool
) -> None:
    """Print the report; exit 1 on a failure, 128 + the signal that stopped the recording."""
    if output_format is ReportFormat.JSON:
        print_json(report.to_dict())
    else:
        print_record_table(report)
    if not quiet:
        for topic, reason in report.skipped.items():
            warn(f"not recorded: {topic}: {reason}")
        if not report.messages and received == [] and report.error is None:
            warn("no message was recorded")
    if report.error is not None:
        raise fail(report.error, report.error_exit_code)
    if report.never_appeared is not None:
        raise fail(report.never_appeared, 2)
    if received:
        raise typer.Exit(EXIT_INTERRUPTED if received[0] == signal.SIGINT else 128 + received[0])


def _record_until_stopped(recorder: Recorder) -> tuple[RecordReport, list[int]]:
    """Record until a signal, ``--duration`` or a failure; return the report and the signals."""
    stop = threading.Event()
    received: list[int] = []

    def on_signal(signum: int, _frame: FrameType | None) -> None:
        if received:
            # A second signal: give up finishing (what is on disk stays salvageable).
            raise KeyboardInterrupt
        received.append(signum)
        stop.set()
        err_console.print("stopping: finishing the bag (Ctrl-C again to abort)")

    previous = {sig: signal.signal(sig, on_signal) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        with _ProgressStatus(recorder) as status, key_presses(_keys(recorder)):
            report = recorder.run(stop, on_progress=status.update)
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    return report, received


def _keys(recorder: Recorder) -> dict[bytes, Callable[[], object]]:
    """What the keys do while recording (a terminal on stdin): space pauses and resumes (as
    ``ros2 bag record``), s takes a snapshot."""
    keys: dict[bytes, Callable[[], object]] = {PAUSE_KEY: recorder.toggle_paused}
    if recorder.options.snapshot_mode:
        keys[SNAPSHOT_KEY] = lambda: recorder.snapshot("key")
    return keys


class _ProgressStatus:
    """The live progress line on stderr, opened at the first progress (the recording started)."""

    def __init__(self, recorder: Recorder) -> None:
        self._recorder = recorder
        self._stack = contextlib.ExitStack()
        self._status: Status | None = None

    def __enter__(self) -> _ProgressStatus:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self._stack.close()

    def update(self, progress: RecordProgress) -> None:
        line = progress_line(progress, subscribed=self._recorder.subscribed.is_set())
        if self._status is None:
            path = self._recorder.path
            keys = ""
            if sys.stdin.isatty():  # the keys are read from the terminal only
                keys = ", space: pause" + (
                    ", s: snapshot" if self._recorder.options.snapshot_mode else ""
                )
            err_console.print(f"recording to {path} (Ctrl-C to stop{keys})", highlight=False)
            self._status = self._stack.enter_context(err_console.status(line))
        else:
            self._status.update(line)
