"""``bagkit merge``: several bags into one, in log-time order (like ``mcap merge``)."""

from __future__ import annotations

from pathlib import Path

import typer

from bagkit.cli.common import ReportFormat, err_console, handle_errors
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
from bagkit.surgery.rewrite import merge_bags

HELP = """Merge BAGs into one new bag OUT in log-time order (equal times: in the order the
bags are given), with every topic's definition and QoS. A topic must have the same type in
every bag. Chunks that do not overlap other inputs in time are copied as stored.

Example: bagkit merge drive_part1 drive_part2 -o drive
"""


@handle_errors
def merge(
    bags: list[Path] = typer.Argument(..., help="The bags to merge (directories or .mcap files)."),
    *,
    output: Output,
    compression: Compression = "zstd",
    max_bag_size: MaxBagSize = 0,
    max_bag_duration: MaxBagDuration = 0.0,
    force: Force = False,
    check_crc: CheckCrc = True,
    output_format: Format = ReportFormat.TABLE,
) -> None:
    """Merge bags into one, in log-time order."""
    options = output_options(
        compression, max_bag_size, max_bag_duration, force=force, check_crc=check_crc
    )
    with err_console.status(f"merging {len(bags)} bags"):
        report = merge_bags(bags, output, options=options)
    print_report(report, output_format)
