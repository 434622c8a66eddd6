"""``bagkit filter``: a new bag with some topics and/or a time range (like ``ros2 bag convert``)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import typer

from bagkit.cli.common import ReportFormat, handle_errors, option_flags, status
from bagkit.cli.option_parsing import BAG_HELP, bag_location, split_list
from bagkit.cli.selection_options import Distro, End, Start, StateTopics, build_query
from bagkit.cli.surgery_options import (
    AROUND_FLAGS,
    CheckCrc,
    Compression,
    ExcludeRegex,
    ExcludeTopics,
    Force,
    Format,
    KeepRegex,
    KeepTopics,
    KeepWhere,
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
    topic_of_where,
)
from bagkit.selection.times import parse_duration
from bagkit.selection.topics import absolute_topic_name
from bagkit.storage.transfer import written_to
from bagkit.surgery.around import Around, cut_around
from bagkit.surgery.rewrite import filter_bag
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

Examples:

  bagkit filter drive -o imu_only --topics /imu/data /gps/fix \\
    --start 1763850000

  bagkit filter flight -o cuts --around '/alerts: status[*].level >= 2' \\
    --before 10 --after 5
"""
AROUND_HELP = (
    "'TOPIC: CONDITION': write one bag per episode where it holds, OUT/<bag>_<n>/, "
    "with --before/--after around it."
)
BEFORE_HELP = "With --around: keep this long before an episode's first match (90, 1m30s, 250ms)."
AFTER_HELP = "With --around: keep this long after an episode's last match."
GAP_HELP = "With --around: matches closer than this merge into one episode (default 0)."


COMMAND_CLASS = SelectionCommand


@handle_errors
def filter_command(
    bag: Path = typer.Argument(..., help=BAG_HELP, parser=bag_location),
    *,
    output: Output,
    topics: KeepTopics = None,
    regex: KeepRegex = "",
    exclude_topics: ExcludeTopics = None,
    exclude_regex: ExcludeRegex = "",
    start: Start = None,
    end: End = None,
    latched_topics: LatchedTopics = None,
    no_latched: NoLatched = False,
    where: KeepWhere = None,
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
    distro: Distro = None,
) -> None:
    """Write the selected messages of a bag to a new bag."""
    where_topic, where = topic_of_where(where)
    query = build_query(topics, start=start, end=end, where=where)
    selection = Selection.of(
        query, regex=regex, exclude_topics=split_list(exclude_topics), exclude_regex=exclude_regex
    )
    selection = replace(
        selection,
        where_topic=where_topic,
        latched=latched_options(latched_topics, no_latched),
        state_topics=frozenset(absolute_topic_name(t) for t in split_list(state_topics)),
    )
    options = output_options(
        compression, max_bag_size, max_bag_duration, force=force, check_crc=check_crc
    )
    if around is None:
        with status(f"filtering {bag}"), written_to(output, replace=force) as local:
            report = filter_bag(bag, local, selection, options)
        report.output = output
        print_report(report, output_format)
        return
    with option_flags(AROUND_FLAGS):
        trigger = Around.create(
            around,
            parse_duration(before, "--before"),
            parse_duration(after, "--after"),
            parse_duration(gap, "--gap"),
            selection.state_topics,
        )
        with (
            status(f"cutting around the episodes in {bag}"),
            written_to(output, replace=force) as local,
        ):
            found, reports = cut_around(bag, local, trigger, selection, options)
    for report in reports:  # named where they are: under an output URL, not the local copy
        report.output = output / report.output.relative_to(local).as_posix()
    print_cuts(found, reports, output_format)
