"""``bagkit merge``: several bags into one, in log-time order (like ``mcap merge``)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import typer

from bagkit.cli.common import ReportFormat, handle_errors, status
from bagkit.cli.option_parsing import bag_location
from bagkit.cli.selection_options import Distro, End, Start, build_query
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
    latched_options,
    output_options,
    print_report,
)
from bagkit.storage.transfer import written_to
from bagkit.surgery.rewrite import merge_bags
from bagkit.surgery.select import Selection
from bagkit.words import counted

HELP = """Merge BAGs into one new bag OUT stored in log-time order (equal times: in the
order the bags are given), with every topic's definition and QoS and each bag's custom_data.
A topic must have the same type in every bag. Chunks that do not overlap other inputs in time
and are stored in order are copied as stored. --start/--end keep a time range (read against
the first and last message of all BAGs); with --start the latched state comes first (the
last message before it of each transient-local topic, as filter does).

Example:

  bagkit merge drive_part1 drive_part2 -o drive
"""


@handle_errors
def merge(
    bags: list[Path] = typer.Argument(
        ..., help="The bags to merge (directories, .mcap files, URLs).", parser=bag_location
    ),
    *,
    output: Output,
    start: Start = None,
    end: End = None,
    latched_topics: LatchedTopics = None,
    no_latched: NoLatched = False,
    compression: Compression = "zstd",
    max_bag_size: MaxBagSize = 0,
    max_bag_duration: MaxBagDuration = 0.0,
    force: Force = False,
    check_crc: CheckCrc = True,
    output_format: Format = ReportFormat.TABLE,
    distro: Distro = None,
) -> None:
    """Merge bags into one, in log-time order."""
    options = output_options(
        compression, max_bag_size, max_bag_duration, force=force, check_crc=check_crc
    )
    selection = Selection.of(build_query(start=start, end=end))
    selection = replace(selection, latched=latched_options(latched_topics, no_latched))
    with (
        status(f"merging {counted(len(bags), 'bag')}"),
        written_to(output, replace=force) as local,
    ):
        report = merge_bags(bags, local, selection, options)
    report.output = output
    print_report(report, output_format)
