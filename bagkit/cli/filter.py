"""``bagkit filter``: a new bag with some topics and/or a time range (like ``ros2 bag convert``)."""

from __future__ import annotations

from pathlib import Path

import typer

from bagkit.cli.common import (
    MultiValueCommand,
    ReportFormat,
    err_console,
    handle_errors,
    split_list,
)
from bagkit.cli.selection_options import End, Start
from bagkit.cli.surgery_options import (
    CheckCrc,
    Compression,
    Force,
    Format,
    MaxBagDuration,
    MaxBagSize,
    Output,
    output_options,
    print_report,
)
from bagkit.surgery.rewrite import filter_bag
from bagkit.surgery.select import Selection

HELP = """Write the messages of BAG that pass the selection to a new bag OUT, in log-time
order, with their definitions and QoS. Topics are selected like ros2 bag: --topics and
--regex include (all topics when neither is given), --exclude-topics and --exclude-regex
remove. Chunks whose messages all pass are copied as stored (not decoded or recompressed).
Times: seconds since the epoch (1700000000.5), nanoseconds (1700000000500000000ns) or
ISO 8601 (2026-11-23T12:00:00Z).

Example: bagkit filter drive -o imu_only --topics /imu/data /gps/fix --start 1763850000
"""

TOPICS_HELP = "Topics to keep (several after one flag, repeated, or comma-separated)."
REGEX_HELP = "Keep topics matching this regular expression (re.search)."
EXCLUDE_TOPICS_HELP = "Topics to drop (several after one flag, repeated, or comma-separated)."
EXCLUDE_REGEX_HELP = "Drop topics matching this regular expression."


class FilterCommand(MultiValueCommand):
    """``--topics a b c`` and ``--exclude-topics a b c``, as ``ros2 bag convert``'s options."""

    multi_value = frozenset({"--topics", "--exclude-topics"})


COMMAND_CLASS = FilterCommand


@handle_errors
def filter_command(
    bag: Path = typer.Argument(..., help="The bag to read (directory or .mcap file)."),
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
    options = output_options(
        compression, max_bag_size, max_bag_duration, force=force, check_crc=check_crc
    )
    with err_console.status(f"filtering {bag}"):
        report = filter_bag(bag, output, selection, options)
    print_report(report, output_format)
