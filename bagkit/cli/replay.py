"""``bagkit replay``: publish a bag's messages over ROS 2 with their recorded timing."""

from __future__ import annotations

import re
import sys
from typing import TYPE_CHECKING, Any

import typer

from bagkit.bag.latched import LatchedOptions
from bagkit.cli.common import (
    CONTEXT_SETTINGS,
    ReportFormat,
    fail,
    handle_errors,
    option_flags,
    warn,
)
from bagkit.cli.option_parsing import MultiValueCommand, split_list
from bagkit.cli.replay_options import (
    PLAY_FLAGS,
    Bags,
    Clock,
    Delay,
    DisableKeyboardControls,
    DiscoveryTime,
    DriftRules,
    Duration,
    Exclude,
    ExcludeTopics,
    Format,
    Inputs,
    LatchedTopics,
    Loop,
    MessageOrderOption,
    NoLatched,
    OnDriftOption,
    PublishServiceRequests,
    QosOverrides,
    Rate,
    ReadAheadQueueSize,
    Regex,
    Remap,
    SeekStep,
    ServiceRequestsSourceOption,
    ServiceTimeout,
    StartOffset,
    StartPaused,
    Storage,
    Topics,
    UntilNsec,
    UntilSec,
    WaitFor,
    WaitForAllAcked,
    WaitForSubscribers,
    WaitTimeout,
)
from bagkit.cli.replay_report import finish, warn_live_publishers, warn_skipped
from bagkit.errors import BagkitError
from bagkit.extras import ROS, require
from bagkit.playback.options import (
    OnDrift,
    PlayOptions,
    ServiceRequestReplay,
    ServiceRequestSource,
    SubscriberWaits,
)
from bagkit.playback.progress import ProgressLine
from bagkit.playback.source import MessageOrder
from bagkit.playback.timing import DEFAULT_CLOCK_HZ, DEFAULT_DISCOVERY_TIME_NS
from bagkit.selection.times import NS_PER_S, parse_duration, seconds_to_ns

if TYPE_CHECKING:
    # The player imports rclpy: only `bagkit replay` itself pays for that import.
    from bagkit.playback.report import PlayReport
    from bagkit.ros.replay.player import Player

_NUMBER = re.compile(r"[0-9]*\.?[0-9]+([eE][-+]?[0-9]+)?")
# Options that take several values, as `ros2 bag play`'s nargs='+' ones: `--topics a b c`.
_MULTI_VALUE = frozenset({"--topics", "--exclude-topics", "--remap", "-m", "--latched-topics"})


class ReplayCommand(MultiValueCommand):
    """Parses ``ros2 bag play``'s option forms that typer lacks.

    A bare ``--clock`` (followed by nothing, an option or the bag path) becomes ``--clock=40``;
    ``--topics a b c`` takes several values (:class:`~bagkit.cli.option_parsing.MultiValueCommand`).
    """

    multi_value = _MULTI_VALUE

    def parse_args(self, ctx: Any, args: list[str]) -> list[str]:
        return super().parse_args(ctx, _bare_clock(args))


def _bare_clock(args: list[str]) -> list[str]:
    """``--clock`` not followed by a number -> ``--clock=40`` (rosbag2's default rate)."""
    out: list[str] = []
    for index, arg in enumerate(args):
        after = args[index + 1] if index + 1 < len(args) else ""
        bare = arg == "--clock" and not _NUMBER.fullmatch(after)
        out.append(f"--clock={DEFAULT_CLOCK_HZ:g}" if bare else arg)
    return out


HELP = """Replay BAG over ROS 2 with its recorded timing, scaled by --rate (alias: play).

Publishes each message's stored bytes at start + (log time - start) / rate, after waiting
until the subscribers known to the graph have matched. Several bags (BAG BAG..., -i BAG)
play as one timeline. On --start-offset, a seek and each loop, the last message of each
transient-local topic is published first. In a terminal, space pauses and resumes, the
right arrow publishes the next message while paused, up/down change the rate by 0.1, the
left arrow and '.' seek a step back and forward; the player node offers rosbag2's services
(~/pause, ~/resume, ~/toggle_paused, ~/play_next, ~/is_paused, ~/get_rate, ~/play, ~/stop)
and the parameters `rate`, `seek` and `burst`.

Progress goes to stderr (on a terminal); per-topic counts and the timing error go to stdout.

Example:

  bagkit play drive/ --clock -r 2 --topics /imu/data /gps/fix
"""

app = typer.Typer()
HELP_OPTIONS = CONTEXT_SETTINGS


@app.command(
    "replay", cls=ReplayCommand, no_args_is_help=True, help=HELP, context_settings=HELP_OPTIONS
)
@handle_errors(take_sigint=True)
def replay(  # noqa: PLR0917 (typer maps parameters to options)
    bags: Bags = None,
    rate: Rate = 1.0,
    topics: Topics = None,
    regex: Regex = None,
    exclude: Exclude = None,
    exclude_topics: ExcludeTopics = None,
    start_offset: StartOffset = "0",
    duration: Duration = None,
    until_sec: UntilSec = None,
    until_nsec: UntilNsec = None,
    loop: Loop = False,
    delay: Delay = 0.0,
    clock: Clock = None,
    start_paused: StartPaused = False,
    disable_keyboard_controls: DisableKeyboardControls = False,
    remap: Remap = None,
    wait_for_subscribers: WaitForSubscribers = True,
    wait_for: WaitFor = None,
    wait_timeout: WaitTimeout = 10.0,
    discovery_time: DiscoveryTime = DEFAULT_DISCOVERY_TIME_NS / NS_PER_S,
    wait_for_all_acked: WaitForAllAcked = 10_000,
    qos_overrides: QosOverrides = None,
    read_ahead_queue_size: ReadAheadQueueSize = 1000,
    storage: Storage = None,
    publish_service_requests: PublishServiceRequests = False,
    service_requests_source: ServiceRequestsSourceOption = ServiceRequestSource.SERVICE,
    service_timeout: ServiceTimeout = 5.0,
    output_format: Format = ReportFormat.TABLE,
    inputs: Inputs = None,
    message_order: MessageOrderOption = MessageOrder.RECEIVED,
    latched_topics: LatchedTopics = None,
    no_latched: NoLatched = False,
    seek_step: SeekStep = 5 * NS_PER_S,
    on_drift: OnDriftOption = OnDrift.SKIP,
    drift_rules: DriftRules = None,
) -> None:
    require(ROS, "bagkit replay")
    from bagkit.ros.replay.player import Player
    from bagkit.ros.replay.topics import parse_remaps

    all_bags = [*(bags or ()), *(inputs or ())]
    if not all_bags:
        raise fail("give a bag to replay: bagkit replay BAG [BAG...] or -i BAG")
    bag = all_bags[0]
    _check_ros2_options(until_sec, until_nsec, storage, read_ahead_queue_size, wait_for_all_acked)
    progress = ProgressLine(sys.stderr, warn)
    with option_flags(PLAY_FLAGS):
        options = PlayOptions(
            bag,
            rate=rate,
            topics=tuple(split_list(topics)) or None,
            regex=regex,
            exclude_regex=exclude,
            exclude_topics=tuple(split_list(exclude_topics)),
            start_offset=start_offset,
            duration_ns=None
            if duration is None
            else parse_duration(duration, "--playback-duration"),
            until_ns=_until_ns(until_sec, until_nsec),
            loops=0 if loop else 1,
            delay_ns=_seconds_ns(delay, "--delay"),
            clock_hz=clock,
            start_paused=start_paused,
            remap=parse_remaps(rule for value in remap or () for rule in value.split(",") if rule),
            waits=SubscriberWaits(
                before_start=wait_for_subscribers,
                topics=tuple(wait_for or ()),
                timeout_ns=_seconds_ns(wait_timeout, "--wait-timeout"),
                discovery_ns=_seconds_ns(discovery_time, "--discovery-time"),
                ack_timeout_ns=wait_for_all_acked * 1_000_000
                if wait_for_all_acked
                else _FOREVER_NS,
            ),
            qos_overrides=qos_overrides,
            progress_period_ns=PROGRESS_PERIOD_NS,
            more_bags=tuple(all_bags[1:]),
            message_order=message_order,
            latched=LatchedOptions(
                enabled=not no_latched, extra_topics=tuple(split_list(latched_topics))
            ),
            seek_step_ns=seek_step,
            on_drift=on_drift,
            drift_rules=drift_rules,
            service_requests=ServiceRequestReplay(
                service_requests_source, _seconds_ns(service_timeout, "--service-timeout")
            )
            if publish_service_requests
            else None,
        )
    player = Player(
        options,
        on_progress=progress.update if progress.interactive else None,
        on_live_publishers=warn_live_publishers,
        on_warning=progress.warn,
        # Plain: rich (note()) would be imported just before the first message.
        on_waited=lambda waited: print(waited.line(), file=sys.stderr, flush=True),
    )
    with option_flags(PLAY_FLAGS):
        report = _run(player, keyboard=not disable_keyboard_controls)
    progress.finish()
    finish(report, " + ".join(map(str, all_bags)), output_format)


def _check_ros2_options(
    until_sec: float | None,
    until_nsec: int | None,
    storage: str | None,
    read_ahead_queue_size: int,
    wait_for_all_acked: int,
) -> None:
    """The checks of ros2 bag play's options that typer's types do not express."""
    if until_sec is not None and until_nsec is not None:
        raise fail("--playback-until-sec and --playback-until-nsec exclude each other")
    if storage not in {None, "mcap", "sqlite3"}:
        raise fail(f"--storage {storage}: bagkit reads mcap and sqlite3 bags")
    if read_ahead_queue_size < 1 or wait_for_all_acked < 0:
        raise fail("--read-ahead-queue-size must be positive, --wait-for-all-acked not negative")


def _until_ns(until_sec: float | None, until_nsec: int | None) -> int | None:
    """--playback-until-sec or --playback-until-nsec as ns since the epoch."""
    if until_sec is None:
        return until_nsec
    return seconds_to_ns(until_sec, until_sec, BagkitError)


def _seconds_ns(seconds: float, flag: str) -> int:
    """A wait flag's seconds as the options' ns (a negative one is the options' error)."""
    return seconds_to_ns(seconds, seconds, BagkitError, flag)


def _run(player: Player, *, keyboard: bool) -> PlayReport:
    """Open the player (which tunes the process), hand it the terminal's keys, replay."""
    from bagkit.playback.keyboard import terminal_controls

    step_ns = player.options.seek_step_ns
    with player:
        warn_skipped(player)
        with terminal_controls(
            player.controls,
            keyboard=keyboard,
            seek_step=lambda direction: player.seek_by(direction * step_ns),
        ):
            return player.play()


# --wait-for-all-acked 0: wait "forever" (a year).
_FOREVER_NS = 365 * 24 * 3600 * NS_PER_S
# The progress line is redrawn four times a second.
PROGRESS_PERIOD_NS = NS_PER_S // 4


# `ros2 bag play`'s name for the same command.
app.command(
    "play", cls=ReplayCommand, no_args_is_help=True, help=HELP, context_settings=HELP_OPTIONS
)(replay)
