"""``bagkit merge``: several bags into one, in log-time order (like ``mcap merge``)."""

from __future__ import annotations

from pathlib import Path

import typer

from bagkit.cli.common import err_console, handle_errors
from bagkit.cli.filter import COMPRESSION_HELP, DURATION_HELP, SIZE_HELP
from bagkit.cli.recover import (
    CRC_HELP,
    FORCE_HELP,
    FORMAT_OPTION,
    OUTPUT_HELP,
    ReportFormat,
    print_report,
)
from bagkit.surgery.rewrite import OutputOptions, merge_bags

HELP = """Merge BAGs into one new bag OUT in log-time order (equal times: in the order the
bags are given), with every topic's definition and QoS. A topic must have the same type in
every bag. Chunks that do not overlap other inputs in time are copied as stored.

Example: bagkit merge drive_part1 drive_part2 -o drive
"""


@handle_errors
def merge(  # noqa: PLR0917 (typer maps parameters to options)
    bags: list[Path] = typer.Argument(..., help="The bags to merge (directories or .mcap files)."),
    output: Path = typer.Option(..., "--output", "-o", help=OUTPUT_HELP),
    compression: str = typer.Option("zstd", "--compression", help=COMPRESSION_HELP),
    max_bag_size: int = typer.Option(0, "--max-bag-size", "-b", help=SIZE_HELP),
    max_bag_duration: float = typer.Option(0, "--max-bag-duration", "-d", help=DURATION_HELP),
    force: bool = typer.Option(False, "--force", help=FORCE_HELP),
    check_crc: bool = typer.Option(True, "--crc/--no-crc", help=CRC_HELP),
    output_format: ReportFormat = FORMAT_OPTION,
) -> None:
    """Merge bags into one, in log-time order."""
    options = OutputOptions(
        compression=compression,
        max_bag_size=max_bag_size,
        max_bag_duration_s=max_bag_duration,
        force=force,
        check_crc=check_crc,
    )
    with err_console.status(f"merging {len(bags)} bags"):
        report = merge_bags(bags, output, options=options)
    print_report(report, output_format)
