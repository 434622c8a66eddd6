"""What the bag-surgery commands share: the output bag's options and the report they print.

``filter``, ``merge`` and ``recover`` write a new bag (``-o``, ``--force``, ``--crc``; filter and
merge also choose its compression and splitting, as ``ros2 bag convert`` does); ``doctor`` and
the three print a report as a table for people or JSON for scripts.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from bagkit.cli.common import ReportFormat, console, print_json, warn
from bagkit.surgery.rewrite import OutputOptions, RewriteReport

Output = Annotated[
    Path,
    typer.Option(
        "--output", "-o", help="The bag directory to write (must not exist unless --force)."
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
        help="Split OUT into files of at most this many bytes (0: never), like ros2 bag.",
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


def print_report(report: RewriteReport, output_format: ReportFormat) -> None:
    """What a rewrite wrote (stdout) and lost (stderr warnings)."""
    if output_format == ReportFormat.JSON:
        print_json(report.to_dict())
    else:
        console.print(
            f"wrote {report.output}: {report.message_count:,} messages "
            f"({len(report.topic_counts)} topics, {len(report.files)} files, "
            f"{report.chunks_copied} chunks copied as stored)",
            highlight=False,
            soft_wrap=True,
        )
    for warning in report.warnings:
        warn(warning)
    for problem in report.problems:
        warn(f"lost: {problem}")
