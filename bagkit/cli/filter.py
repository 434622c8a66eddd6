"""``bagkit filter``: a new bag with some topics and/or a time range (like ``ros2 bag convert``)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import typer

from bagkit.bag import BagReader
from bagkit.cli.common import (
    ReportFormat,
    bag_location,
    err_console,
    handle_errors,
    split_list,
)
from bagkit.cli.selection_options import End, Start, StateTopics
from bagkit.cli.surgery_options import (
    CheckCrc,
    Compression,
    Force,
    Format,
    LatchedTopics,
    MaxBagDuration,
    MaxBagSize,
    NoLatched,
    Output,
    SelectionCommand,
    latched_options,
    output_options,
    print_cuts,
    print_report,
)
from bagkit.selection.conditions import TopicCondition, parse_condition, parse_topic_condition
from bagkit.selection.times import parse_duration
from bagkit.selection.topics import absolute_topic_name
from bagkit.storage.transfer import written_to
from bagkit.surgery.cut import cut_windows
from bagkit.surgery.errors import NothingToCutError, SurgeryError
from bagkit.surgery.rewrite import OutputOptions, filter_bag
from bagkit.surgery.select import Selection

HELP = """Write the messages of BAG that pass the selection to a new bag OUT, in log-time
order, with their definitions and QoS. Topics are selected like ros2 bag: --topics and
--regex include (all topics when neither is given), --exclude-topics and --exclude-regex
remove. Chunks whose messages all pass are copied as stored (not decoded or recompressed).
Times: seconds since the epoch (1700000000.5), nanoseconds (1700000000500000000ns) or
ISO 8601 (2026-11-23T12:00:00Z).

With --start, the latched state comes first: the last message before the start of each
selected topic recorded transient-local (/tf_static, maps), logged at the start
(--latched-topics adds volatile topics, --no-latched leaves it out). --where CONDITION keeps
only the messages satisfying it of the topics that have its fields (others are kept whole).
--around 'TOPIC: CONDITION' writes one bag per episode where the condition holds,
OUT/<bag>_<n>/, from --before before its first match to --after after its last, each with
its latched state.

Example: bagkit filter drive -o imu_only --topics /imu/data /gps/fix --start 1763850000
Example: bagkit filter flight -o cuts --around '/alerts: status[*].level >= 2' --before 10 --after 5
"""
WHERE_HELP = (
    "Keep only the messages satisfying CONDITION (e.g. 'linear_acceleration.z < 0') of the "
    "selected topics that have its fields; the others are kept whole."
)
AROUND_HELP = (
    "'TOPIC: CONDITION': write one bag per episode where it holds, OUT/<bag>_<n>/, "
    "with --before/--after around it."
)
BEFORE_HELP = "With --around: keep this long before an episode's first match (90, 1m30s, 250ms)."
AFTER_HELP = "With --around: keep this long after an episode's last match."
GAP_HELP = "With --around: matches closer than this merge into one episode (default 0)."

TOPICS_HELP = "Topics to keep (several after one flag, repeated, or comma-separated)."
REGEX_HELP = "Keep topics matching this regular expression (re.search)."
EXCLUDE_TOPICS_HELP = "Topics to drop (several after one flag, repeated, or comma-separated)."
EXCLUDE_REGEX_HELP = "Drop topics matching this regular expression."


COMMAND_CLASS = SelectionCommand


@handle_errors
def filter_command(
    bag: Path = typer.Argument(
        ..., help="The bag to read (directory, .mcap file or URL).", parser=bag_location
    ),
    *,
    output: Output,
    topics: list[str] | None = typer.Option(None, "--topics", help=TOPICS_HELP),
    regex: str = typer.Option("", "--regex", "-e", help=REGEX_HELP),
    exclude_topics: list[str] | None = typer.Option(
        None, "--exclude-topics", help=EXCLUDE_TOPICS_HELP
    ),
    exclude_regex: str = typer.Option("", "--exclude-regex", help=EXCLUDE_REGEX_HELP),
    start: Start = None,
    end: End = None,
    latched_topics: LatchedTopics = None,
    no_latched: NoLatched = False,
    where: str | None = typer.Option(None, "--where", help=WHERE_HELP, metavar="CONDITION"),
    around: str | None = typer.Option(None, "--around", help=AROUND_HELP, metavar="TRIGGER"),
    before: str = typer.Option("0", "--before", help=BEFORE_HELP, metavar="DURATION"),
    after: str = typer.Option("0", "--after", help=AFTER_HELP, metavar="DURATION"),
    gap: str = typer.Option("0", "--gap", help=GAP_HELP, metavar="DURATION"),
    state_topics: StateTopics = None,
    compression: Compression = "zstd",
    max_bag_size: MaxBagSize = 0,
    max_bag_duration: MaxBagDuration = 0.0,
    force: Force = False,
    check_crc: CheckCrc = True,
    output_format: Format = ReportFormat.TABLE,
) -> None:
    """Write the selected messages of a bag to a new bag."""
    selection = Selection.create(
        split_list(topics), regex, split_list(exclude_topics), exclude_regex, start, end
    )
    selection = replace(selection, latched=latched_options(latched_topics, no_latched))
    options = output_options(
        compression, max_bag_size, max_bag_duration, force=force, check_crc=check_crc
    )
    states = [absolute_topic_name(t) for t in split_list(state_topics)]
    if where is not None:
        from bagkit.data.where import where_filters  # numpy, rosbags: only when asked

        with BagReader(bag) as reader:
            content = where_filters(
                reader, parse_condition(where), selection.topic_passes, state_topics=states
            )
        selection = replace(selection, content=content)
    if around is None:
        with err_console.status(f"filtering {bag}"), written_to(output, replace=force) as local:
            report = filter_bag(bag, local, selection, options)
        report.output = output
        print_report(report, output_format)
        return
    if start is not None or end is not None:
        raise SurgeryError("--around sets the windows: it takes no --start or --end")
    margins = (parse_duration(before, "--before"), parse_duration(after, "--after"))
    trigger = parse_topic_condition(around)
    _cut_around(
        bag,
        output,
        trigger,
        margins,
        parse_duration(gap, "--gap"),
        selection,
        options,
        output_format,
        state_topics=states,
    )


def _cut_around(  # noqa: PLR0917 (the command's options, passed on)
    bag: Path,
    output: Path,
    trigger: TopicCondition,
    margins: tuple[int, int],
    gap_ns: int,
    selection: Selection,
    options: OutputOptions,
    output_format: ReportFormat,
    *,
    state_topics: list[str],
) -> None:
    """``--around``: the episodes of ``trigger``, then one bag per window around each."""
    from bagkit.data.episodes import episode_windows, find_episodes

    # Episodes whose windows would overlap are one: matches less than before + after apart
    # merge, so that each message is in one output bag.
    merge_ns = max(gap_ns, margins[0] + margins[1] + 1)
    with err_console.status(f"finding episodes in {bag}"), BagReader(bag) as reader:
        found = find_episodes(reader, trigger, merge_ns, state_topics=state_topics)
    if not found.episodes:
        raise NothingToCutError(f"{bag}: {trigger.text!r} holds for no message")
    windows = episode_windows(found.episodes, *margins)
    with err_console.status(f"cutting {len(windows)} windows of {bag}"):
        reports = cut_windows(bag, output, windows, selection, options)
    print_cuts(found, reports, output_format)
