"""The options of ``bagkit record``, named as ``ros2 bag record``'s (docs/cli.md).

Declared here, one alias each, with the value types of the options that take a choice, so that
the command itself reads as what it does.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from bagkit.bag.file_rotation import FreeSpace
from bagkit.cli.common import ReportFormat
from bagkit.cli.option_parsing import byte_size, duration_ns, free_space
from bagkit.compat import StrEnum


class CompressionMode(StrEnum):
    """``ros2 bag record --compression-mode``: bagkit compresses MCAP chunks in either mode."""

    NONE = "none"
    FILE = "file"
    MESSAGE = "message"


class CompressionFormat(StrEnum):
    """``--compression-format``: the MCAP chunk compression."""

    ZSTD = "zstd"
    LZ4 = "lz4"


class LogLevel(StrEnum):
    """``--log-level``: warnings are printed at ``warn`` and below, progress at ``info``."""

    DEBUG = "debug"
    INFO = "info"
    WARN = "warn"
    ERROR = "error"
    FATAL = "fatal"


TopicsPositional = Annotated[
    list[str] | None,
    typer.Argument(
        help="Topics to record (as --topics).", show_default=False, metavar="[TOPIC]..."
    ),
]
Topics = Annotated[
    list[str] | None,
    typer.Option(
        "--topics", help="Topics to record (always, hidden ones too).", metavar="TOPIC..."
    ),
]
TopicTypes = Annotated[
    list[str] | None,
    typer.Option("--topic-types", help="Record topics of these types.", metavar="TYPE..."),
]
AllTopicsAndServices = Annotated[
    bool,
    typer.Option("--all", "-a", help="Record every topic (not hidden ones), service and action."),
]
AllTopics = Annotated[
    bool, typer.Option("--all-topics", help="Record every topic (not hidden ones).")
]
AllServices = Annotated[
    bool,
    typer.Option("--all-services", help="Record every service's introspection events."),
]
Services = Annotated[
    list[str] | None,
    typer.Option(
        "--services",
        help="Record these services' introspection events (NAME/_service_event).",
        metavar="SERVICE...",
    ),
]
ExcludeServices = Annotated[
    list[str] | None,
    typer.Option("--exclude-services", help="Leave out these services.", metavar="SERVICE..."),
]
AllActions = Annotated[
    bool,
    typer.Option("--all-actions", help="Record every action's feedback and status topics."),
]
Actions = Annotated[
    list[str] | None,
    typer.Option(
        "--actions",
        help="Record these actions' feedback and status (NAME/_action/feedback, .../status).",
        metavar="ACTION...",
    ),
]
ExcludeActions = Annotated[
    list[str] | None,
    typer.Option("--exclude-actions", help="Leave out these actions.", metavar="ACTION..."),
]
Regex = Annotated[
    str | None,
    typer.Option("--regex", "-e", help="Record topics whose name contains a match of RE."),
]
ExcludeRegex = Annotated[
    str | None,
    typer.Option("--exclude-regex", "-x", help="Leave out topics matching RE, named ones too."),
]
ExcludeTopics = Annotated[
    list[str] | None,
    typer.Option("--exclude-topics", help="Leave out these topics.", metavar="TOPIC..."),
]
ExcludeTopicTypes = Annotated[
    list[str] | None,
    typer.Option(
        "--exclude-topic-types", help="Leave out topics of these types.", metavar="TYPE..."
    ),
]
IncludeHidden = Annotated[
    bool,
    typer.Option("--include-hidden-topics", help="Let --all/--regex select hidden topics (/_x)."),
]
IncludeUnpublished = Annotated[
    bool,
    typer.Option("--include-unpublished-topics", help="Also record topics without a publisher."),
]
Output = Annotated[
    Path | None,
    typer.Option(
        "--output",
        "-o",
        help="Bag directory to create (default: rosbag2_YYYY_MM_DD-HH_MM_SS); never overwritten.",
        show_default=False,
    ),
]
Storage = Annotated[str, typer.Option("--storage", "-s", help="Storage: mcap only.")]
MaxBagSize = Annotated[
    int,
    typer.Option(
        "--max-bag-size",
        "-b",
        help="Split into a new file at this size (2GiB, 500MB, 1.5G, bytes; 0: never; at "
        "least one chunk, 1 MiB).",
        parser=byte_size,
        metavar="SIZE",
    ),
]
MaxBagDuration = Annotated[
    int,
    typer.Option(
        "--max-bag-duration",
        "-d",
        help="Split into a new file every this long (seconds, or 1m30s; 0: never); keeps "
        "recording.",
        parser=duration_ns,
        metavar="DURATION",
    ),
]
Duration = Annotated[
    int | None,
    typer.Option(
        "--duration",
        help="Stop after this long (seconds, or 1m30s), counted from when the topics are "
        "subscribed.",
        parser=duration_ns,
        metavar="DURATION",
    ),
]
CompressionModeOption = Annotated[
    CompressionMode | None,
    typer.Option("--compression-mode", help="none: no compression; file or message: chunks."),
]
CompressionFormatOption = Annotated[
    CompressionFormat | None,
    typer.Option("--compression-format", help="Chunk compression (default zstd)."),
]
QosOverrides = Annotated[
    Path | None,
    typer.Option(
        "--qos-profile-overrides-path",
        help="YAML {topic: {reliability: ..., durability: ..., ...}} (ros2 bag's format): "
        "subscribe with these profiles instead of the adapted ones.",
    ),
]
UseSimTime = Annotated[
    bool,
    typer.Option("--use-sim-time", help="Stamp with /clock time; nothing is written before it."),
]
NodeName = Annotated[str, typer.Option("--node-name", help="The recorder's node.")]
CustomData = Annotated[
    list[str] | None,
    typer.Option(
        "--custom-data", help="KEY=VALUE pairs for metadata.yaml.", metavar="KEY=VALUE..."
    ),
]
MaxCacheSize = Annotated[
    int | None,
    typer.Option(
        "--max-cache-size",
        help="Bytes held between taking and writing messages (64MiB, 1.5G; default 64 MiB, "
        "at least 1 MiB); with --snapshot-mode, the snapshot buffer's bound.",
        parser=byte_size,
        metavar="SIZE",
        show_default=False,
    ),
]
PollingInterval = Annotated[
    int,
    typer.Option("--polling-interval", help="Milliseconds between looks for new topics.", min=1),
]
LogLevelOption = Annotated[LogLevel, typer.Option("--log-level", help="error: no warnings.")]
Format = Annotated[ReportFormat, typer.Option("--format", help="Final report as a table or JSON.")]
SnapshotMode = Annotated[
    bool,
    typer.Option(
        "--snapshot-mode",
        help="Keep the newest messages in memory (--max-cache-size, --max-cache-duration) and "
        "write a bag of them under the output at each trigger: --trigger, the ~/snapshot "
        "service, the s key.",
    ),
]
MaxCacheDuration = Annotated[
    int | None,
    typer.Option(
        "--max-cache-duration",
        help="With --snapshot-mode: keep this many seconds of messages (or 1m30s).",
        parser=duration_ns,
        metavar="DURATION",
    ),
]
TriggerOption = Annotated[
    list[str] | None,
    typer.Option(
        "--trigger",
        help="'TOPIC: CONDITION': a message satisfying the field condition triggers a "
        "snapshot, e.g. '/alerts: status[*].level >= 2'. Repeatable.",
        metavar="'TOPIC: CONDITION'",
    ),
]
Pre = Annotated[
    int | None,
    typer.Option(
        "--pre",
        help="A snapshot starts this long before its trigger (default: all that is buffered).",
        parser=duration_ns,
        metavar="DURATION",
    ),
]
Post = Annotated[
    int | None,
    typer.Option(
        "--post",
        help="A snapshot goes on this long after its trigger; a trigger meanwhile extends it.",
        parser=duration_ns,
        metavar="DURATION",
    ),
]
Health = Annotated[
    Path | None,
    typer.Option(
        "--health",
        help="A health contract (bagkit check's spec, docs/health.md) checked on what is "
        "recorded: a line when a check breaks or clears; counts in the report and metadata.",
        metavar="SPEC",
    ),
]
TriggerOnHealth = Annotated[
    bool,
    typer.Option(
        "--trigger-on-health",
        help="With --snapshot-mode and --health: a check that breaks triggers a snapshot.",
    ),
]
StopOnHealth = Annotated[
    str | None,
    typer.Option(
        "--stop-on-health",
        help="With --health: stop (exit 1) once a check has been broken this long (0: at once).",
        metavar="DURATION",
    ),
]
RepeatTransientLocal = Annotated[
    list[str] | None,
    typer.Option(
        "--repeat-transient-local",
        help="Write the last N (default 1) messages of TOPIC at the start of every snapshot and "
        "split file.",
        metavar="TOPIC[=N]",
    ),
]
RepeatAllTransientLocal = Annotated[
    bool | None,
    typer.Option(
        "--repeat-all-transient-local/--no-repeat-all-transient-local",
        help="Repeat the last message of every transient-local topic at the start of every "
        "snapshot and split file (default: on with --snapshot-mode).",
        show_default=False,
    ),
]
StartPaused = Annotated[
    bool,
    typer.Option(
        "--start-paused",
        help="Start paused: messages are counted, not written, until the space key or the "
        "~/resume service.",
    ),
]
MaxBagFiles = Annotated[
    int,
    typer.Option(
        "--max-bag-files",
        help="With -b or -d: keep the newest N files, deleting the oldest (0: all).",
        min=0,
    ),
]
MinFreeSpace = Annotated[
    FreeSpace | None,
    typer.Option(
        "--min-free-space",
        help="Keep this much disk free (2GiB, 500MB, 5%): delete the oldest file with "
        "--max-bag-files, else stop with an error before the disk fills.",
        parser=free_space,
        metavar="SIZE",
    ),
]

# The fields of RecordOptions as the flags that set them: an options error names the flag.
RECORD_FLAGS = {
    "selection": "{} (name TOPICs, or use --all, --regex, --topic-types, --services ...)",
    "topics": "--topics",
    "files.max_bag_size": "--max-bag-size",
    "files.max_bag_duration_ns": "--max-bag-duration",
    "files.max_bag_files": "--max-bag-files",
    "files.min_free_space": "--min-free-space",
    "duration_ns": "--duration",
    "queue_bytes": "--max-cache-size",
    "discovery_period_ns": "--polling-interval",
    "node_name": "--node-name",
    "snapshot.max_bytes": "--max-cache-size",
    "snapshot.max_duration_ns": "--max-cache-duration",
    "snapshot.triggers": "--trigger",
    "snapshot.pre_ns": "--pre",
    "snapshot.post_ns": "--post",
    "repeat_transient_local": "--repeat-transient-local",
    "health.trigger": "--trigger-on-health {} (add --snapshot-mode)",
    "stop_after_ns": "--stop-on-health",
}
