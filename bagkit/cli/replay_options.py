"""The options of ``bagkit replay``/``play``, named as ``ros2 bag play``'s (docs/cli.md).

Declared here, one alias each, so that the command itself reads as what it does.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from bagkit.cli.common import ReportFormat
from bagkit.cli.option_parsing import bag_location, duration_ns
from bagkit.playback.options import OnDrift, ServiceRequestSource
from bagkit.playback.source import MessageOrder
from bagkit.playback.timing import DEFAULT_CLOCK_HZ

Bags = Annotated[
    list[Path] | None,
    typer.Argument(
        help="Bag directories, .mcap files or URLs; several are replayed as one timeline.",
        show_default=False,
        metavar="BAG...",
        parser=bag_location,
    ),
]
Rate = Annotated[
    float, typer.Option("--rate", "-r", help="Playback speed factor (2 = twice as fast).")
]
Topics = Annotated[
    list[str] | None,
    typer.Option(
        "--topics",
        help="Replay only these topics: several after one --topics, repeated, or comma lists.",
    ),
]
Regex = Annotated[
    str | None,
    typer.Option("--regex", "-e", help="Replay topics whose name matches this regex (re.search)."),
]
Exclude = Annotated[
    str | None,
    typer.Option(
        "--exclude-regex",
        "-x",
        "--exclude",
        help="Do not replay topics whose name matches this regex.",
    ),
]
ExcludeTopics = Annotated[
    list[str] | None,
    typer.Option("--exclude-topics", help="Do not replay these topics (as --topics)."),
]
StartOffset = Annotated[
    str,
    typer.Option(
        "--start-offset",
        help="Start at TIME: seconds from the bag's first message (10, 1m30s), before its "
        "last (-5), or absolute (epoch seconds, ISO 8601, NNNns), as --start elsewhere.",
        metavar="TIME",
    ),
]
Duration = Annotated[
    str | None,
    typer.Option(
        "--playback-duration",
        "--duration",
        help="Replay only this much bag time (seconds, or 1m30s, 250ms).",
        metavar="DURATION",
    ),
]
UntilSec = Annotated[
    float | None,
    typer.Option(
        "--playback-until-sec",
        help="Replay messages logged up to this time (seconds since the epoch).",
    ),
]
UntilNsec = Annotated[
    int | None,
    typer.Option(
        "--playback-until-nsec",
        help="Replay messages logged up to this time (nanoseconds since the epoch).",
    ),
]
Loop = Annotated[bool, typer.Option("--loop", "-l", help="Replay again and again until Ctrl-C.")]
Delay = Annotated[
    float, typer.Option("--delay", "-d", help="Sleep this many seconds before each pass.")
]
Clock = Annotated[
    float | None,
    typer.Option(
        "--clock",
        metavar="[HZ]",
        help=f"Publish rosgraph_msgs/Clock on /clock at HZ ({DEFAULT_CLOCK_HZ:g} when given "
        "without a value) and before each message; a /clock topic in the bag is then not "
        "replayed.",
        show_default=False,
    ),
]
StartPaused = Annotated[
    bool,
    typer.Option("--start-paused", "-p", help="Start paused (space, or the ~/resume service)."),
]
DisableKeyboardControls = Annotated[
    bool, typer.Option("--disable-keyboard-controls", help="Do not read keys from the terminal.")
]
Remap = Annotated[
    list[str] | None,
    typer.Option("--remap", "-m", help="Publish topic OLD as NEW (OLD:=NEW); several or repeated."),
]
WaitForSubscribers = Annotated[
    bool,
    typer.Option(
        "--wait-for-subscribers/--no-wait-for-subscribers",
        help="Before the first message, wait until every subscription the ROS graph shows on a "
        "replayed topic (and /clock) has matched.",
    ),
]
WaitFor = Annotated[
    list[str] | None,
    typer.Option(
        "--wait-for",
        help="Also wait until this topic (published name) has a subscriber; repeatable.",
    ),
]
WaitTimeout = Annotated[
    float, typer.Option("--wait-timeout", help="Seconds to wait for subscribers before giving up.")
]
DiscoveryTime = Annotated[
    float,
    typer.Option(
        "--discovery-time",
        help="Seconds to watch the ROS graph for subscribers that already exist (Fast DDS "
        "announces participants every 3 s); 0 with --wait-for when the consumers are known.",
    ),
]
WaitForAllAcked = Annotated[
    int,
    typer.Option(
        "--wait-for-all-acked",
        metavar="TIMEOUT",
        help="At the end, wait up to TIMEOUT ms for reliable subscribers to acknowledge "
        "every message (0 = as long as it takes).",
    ),
]
QosOverrides = Annotated[
    Path | None,
    typer.Option(
        "--qos-profile-overrides-path",
        "--qos-overrides",
        help="rosbag2 QoS overrides file (YAML: topic -> reliability, durability, history, depth).",
    ),
]
ReadAheadQueueSize = Annotated[
    int,
    typer.Option(
        "--read-ahead-queue-size",
        help="Accepted for ros2 bag; bagkit reads chunk by chunk as the replay reaches them.",
    ),
]
Storage = Annotated[
    str | None,
    typer.Option(
        "--storage",
        "-s",
        help="Accepted for ros2 bag (mcap or sqlite3); bagkit detects the storage itself.",
    ),
]
Format = Annotated[
    ReportFormat, typer.Option("--format", help="Final report as a table or as JSON.")
]
Inputs = Annotated[
    list[Path] | None,
    typer.Option(
        "--input",
        "-i",
        help="A bag to replay (rosbag2 Kilted's form); repeated for several, with BAG... too.",
        show_default=False,
        parser=bag_location,
    ),
]
OnDriftOption = Annotated[
    OnDrift,
    typer.Option(
        "--on-drift",
        help="A topic whose stored definition differs from the installed type's: skip it, "
        "publish it raw (as recorded), or migrate each message to the installed definition.",
    ),
]
DriftRules = Annotated[
    Path | None,
    typer.Option(
        "--drift-rules",
        help="With --on-drift migrate: a rules file, as bagkit migrate --rules takes.",
        metavar="FILE",
    ),
]
MessageOrderOption = Annotated[
    MessageOrder,
    typer.Option(
        "--message-order",
        help="Merge and time the bags' messages by log time (received) or send time (sent).",
    ),
]
LatchedTopics = Annotated[
    list[str] | None,
    typer.Option(
        "--latched-topics",
        help="Also carry over the last message of these (volatile) topics on a late start.",
    ),
]
NoLatched = Annotated[
    bool,
    typer.Option(
        "--no-latched",
        help="On --start-offset, a seek or a loop, do not first publish the last message of "
        "each transient-local topic.",
    ),
]
SeekStep = Annotated[
    int,
    typer.Option(
        "--seek-step",
        help="Bag time that the seek keys (left arrow, ',' '.') move (seconds, or 250ms).",
        parser=duration_ns,
        metavar="DURATION",
    ),
]
PublishServiceRequests = Annotated[
    bool,
    typer.Option(
        "--publish-service-requests",
        help="Call the recorded services with their recorded requests (instead of republishing "
        "the events) and compare the live responses with the recorded ones; exit 1 when one "
        "differs or is not answered.",
    ),
]


ServiceRequestsSourceOption = Annotated[
    ServiceRequestSource,
    typer.Option(
        "--service-requests-source",
        help="Requests from the server's events (service_introspection) or the client's.",
    ),
]
ServiceTimeout = Annotated[
    float,
    typer.Option(
        "--service-timeout",
        help="Seconds answers are waited for after the last request; then unanswered.",
        min=0.0,
    ),
]

# The fields of PlayOptions as the flags that set them: an options error names the flag.
PLAY_FLAGS = {
    "rate": "--rate",
    "start_offset": "{}",  # the problem names it: bad start offset ...
    "duration_ns": "--playback-duration",
    "delay_ns": "--delay",
    "clock_hz": "--clock",
    "seek_step_ns": "--seek-step",
    "latched": "--latched-topics and --no-latched exclude each other ({})",
    "waits.before_start": "{}; use --no-wait-for-subscribers to start anyway",
    "waits.timeout_ns": "--wait-timeout",
    "waits.discovery_ns": "--discovery-time",
    "waits.ack_timeout_ns": "--wait-for-all-acked",
    "service_requests.timeout_ns": "--service-timeout",
}
