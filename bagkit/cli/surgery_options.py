"""What the bag-surgery commands share: the output bag's options and the report they print.

``filter``, ``merge`` and ``recover`` write a new bag (``-o``, ``--force``, ``--crc``; filter and
merge also choose its compression and splitting, as ``ros2 bag convert`` does); ``doctor`` and
the three print a report as a table for people or JSON for scripts.
"""

from __future__ import annotations

from dataclasses import asdict
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from bagkit.bag.latched import LatchedOptions
from bagkit.cli.common import ReportFormat, print_json, warn
from bagkit.cli.option_parsing import MultiValueCommand, bag_location, byte_size, split_list
from bagkit.cli.tables import print_line
from bagkit.selection.times import format_ns
from bagkit.surgery.rewrite import OutputOptions, RewriteReport
from bagkit.words import counted

if TYPE_CHECKING:
    from bagkit.data.episodes import Episodes

Output = Annotated[
    Path,
    typer.Option(
        "--output",
        "-o",
        help="The bag directory to write, or one MCAP file if it ends in .mcap (must not "
        "exist unless --force); a URL uploads it.",
        parser=bag_location,
    ),
]
Force = Annotated[bool, typer.Option("--force", help="Replace OUT if it exists.")]
CheckCrc = Annotated[
    bool,
    typer.Option(
        "--crc/--no-crc",
        help="Check each chunk's CRC (a damaged chunk's messages are reported lost).",
    ),
]
Compression = Annotated[
    str, typer.Option("--compression", help="Chunk compression of OUT: zstd, lz4 or none.")
]
MaxBagSize = Annotated[
    int,
    typer.Option(
        "--max-bag-size",
        "-b",
        help="Split OUT into files of at most this size (2GiB, 500MB, 1.5G, bytes; 0: never; "
        "at least 16 KiB), like ros2 bag.",
        parser=byte_size,
        metavar="SIZE",
    ),
]
MaxBagDuration = Annotated[
    float,
    typer.Option(
        "--max-bag-duration",
        "-d",
        help="Split OUT into files spanning at most this many seconds (0: never).",
    ),
]
KeepTopics = Annotated[
    list[str] | None,
    typer.Option(
        "--topics",
        help="Topics to keep (several after one flag, repeated, or comma-separated).",
        metavar="TOPICS",
    ),
]
KeepRegex = Annotated[
    str,
    typer.Option("--regex", "-e", help="Keep topics matching this regular expression (re.search)."),
]
ExcludeTopics = Annotated[
    list[str] | None,
    typer.Option(
        "--exclude-topics",
        help="Topics to drop (several after one flag, repeated, or comma-separated).",
        metavar="TOPICS",
    ),
]
ExcludeRegex = Annotated[
    str,
    typer.Option(
        "--exclude-regex", help="Drop topics matching this regular expression.", metavar="REGEX"
    ),
]
KeepWhere = Annotated[
    str | None,
    typer.Option(
        "--where",
        help="Keep only the messages satisfying CONDITION (e.g. 'linear_acceleration.z < 0') "
        "of the selected topics that have its fields, or of one topic ('/alerts: "
        "status[*].level >= 2'); the others are kept whole.",
        metavar="CONDITION",
    ),
]


def topic_of_where(where: str | None) -> tuple[str | None, str | None]:
    """``--where``'s topic, if it names one (``'TOPIC: CONDITION'``), and its condition.

    Raises:
        SelectionError: a topic and a condition that does not parse.
    """
    from bagkit.selection.conditions import topic_of

    named = None if where is None else topic_of(where)
    return (None, where) if named is None else (named.topic, named.condition.text)


# The fields an --around error names (surgery.around, regression.add) as the flags that set them.
AROUND_FLAGS = {
    "selection.span": "--start/--end with --around",
    "span": "--start/--end with --around",
    "before_ns": "--before",
    "after_ns": "--after",
    "gap_ns": "--gap",
}
LatchedTopics = Annotated[
    list[str] | None,
    typer.Option(
        "--latched-topics",
        help="With --start: also carry over the last message before it of these topics "
        "recorded volatile (transient-local ones always are; several, repeated or a,b).",
    ),
]
NoLatched = Annotated[
    bool,
    typer.Option(
        "--no-latched",
        help="With --start: do not write the latched state (the last message before the "
        "start of each transient-local topic) first.",
    ),
]
Format = Annotated[
    ReportFormat,
    typer.Option("--format", help="table (for people) or json (for scripts)."),
]


def output_options(
    compression: str = "zstd",
    max_bag_size: int = 0,
    max_bag_duration: float = 0.0,
    *,
    force: bool,
    check_crc: bool,
) -> OutputOptions:
    """The library's options for the bag a command writes."""
    return OutputOptions(
        compression=compression,
        max_bag_size=max_bag_size,
        max_bag_duration_s=max_bag_duration,
        force=force,
        check_crc=check_crc,
    )


def latched_options(latched_topics: list[str] | None, no_latched: bool) -> LatchedOptions:
    """The library's latched-state options from ``--latched-topics`` and ``--no-latched``."""
    return LatchedOptions(enabled=not no_latched, extra_topics=tuple(split_list(latched_topics)))


def print_report(report: RewriteReport, output_format: ReportFormat, prefix: str = "") -> None:
    """What a rewrite wrote (stdout, after ``prefix``) and lost (stderr warnings)."""
    if output_format == ReportFormat.JSON:
        print_json(report.to_dict())
    else:
        print_line(
            [
                f"{prefix}wrote {report.output}: {counted(report.message_count, 'message')} "
                f"({counted(len(report.topic_counts), 'topic')}, "
                f"{counted(len(report.files), 'file')}, "
                f"{counted(report.chunks_copied, 'chunk')} copied as stored"
                + (f", {report.latched_messages} latched" if report.latched_messages else "")
                + ")"
            ]
        )
    for warning in report.warnings:
        warn(warning)
    for problem in report.problems:
        warn(f"lost: {problem}")


def print_cuts(found: Episodes, reports: list[RewriteReport], output_format: ReportFormat) -> None:
    """What ``filter --around`` wrote: one bag per episode (JSON: one object each)."""
    if output_format == ReportFormat.JSON:
        print_json(
            [
                {"episode": asdict(episode), **report.to_dict()}
                for episode, report in zip(found.episodes, reports, strict=True)
            ]
        )
    else:
        for episode, report in zip(found.episodes, reports, strict=True):
            print_report(
                report,
                ReportFormat.TABLE,
                f"{found.topic} from {format_ns(episode.start_ns)} to "
                f"{format_ns(episode.end_ns)} ({counted(episode.count, 'match', 'matches')}): ",
            )
    for problem in found.problems:
        warn(problem)


class SelectionCommand(MultiValueCommand):
    """``--topics a b c`` and ``--exclude-topics a b c`` (``filter``, ``convert``), as
    ``ros2 bag convert``'s options."""

    multi_value = frozenset({"--topics", "--exclude-topics"})
