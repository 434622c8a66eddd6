"""``bagkit export``: topics of a bag to Parquet or CSV files, streamed with bounded memory."""

from __future__ import annotations

from pathlib import Path

import typer

from bagkit.cli.common import console, handle_errors, split_list, warn
from bagkit.cli.progress import DelayedProgress
from bagkit.data.formats import ExportFormat

HELP = """Write topics of BAG to Parquet (zstd) or CSV files, one per topic, for pandas, polars,
DuckDB, Spark or a spreadsheet.

Columns: log_time and publish_time (int64 ns), then every leaf field under its dotted path
(header.stamp.sec, orientation_covariance[0]); variable-length sequences are list columns in
Parquet and JSON text in CSV. OUT is a directory (/imu/data -> OUT/imu/data.parquet), or a
.parquet/.csv file when one topic is exported; --dataset writes a folder of part files per
topic. Undecodable topics are skipped with a warning; a damaged bag exports what is intact and
the loss is reported.

Examples:

  bagkit export flight1 -o flight1_parquet

  bagkit export flight1 -t /imu/data -o imu.csv --start 10 --end 70

  bagkit export flight1 -o out --topics /gps/fix --topics /imu/data --fields 'header.stamp.*'
"""

# Below this many seconds an export finishes without a progress bar flashing by.


@handle_errors
def export(  # noqa: PLR0917 (typer maps parameters to options)
    bag: Path = typer.Argument(
        ..., help="Bag directory or single .mcap/.db3 file.", metavar="BAG", show_default=False
    ),
    out: Path = typer.Option(
        ..., "--output", "-o", help="Output directory, or a .parquet/.csv file for one topic."
    ),
    file_format: ExportFormat | None = typer.Option(
        None, "--format", help="parquet or csv (default: from OUT's suffix, else parquet)."
    ),
    topics: list[str] | None = typer.Option(
        None, "--topics", "-t", help="Only these topics (repeat for several; default: all)."
    ),
    fields: list[str] | None = typer.Option(
        None, "--fields", "-f", help="Only fields matching these paths or globs (as stats)."
    ),
    start: str | None = typer.Option(
        None,
        "--start",
        help="From SEC seconds after the bag start (or absolute: epoch seconds, ISO 8601).",
        metavar="SEC",
    ),
    end: str | None = typer.Option(None, "--end", help="Until SEC (exclusive).", metavar="SEC"),
    dataset: bool = typer.Option(
        False, "--dataset", help="Parquet: a folder of part files per topic (OUT/imu/data/)."
    ),
) -> None:
    from bagkit.data.export import export as write

    if file_format is None:
        file_format = ExportFormat.CSV if out.suffix == ".csv" else ExportFormat.PARQUET
    progress = DelayedProgress("exporting")
    try:
        report = write(
            bag,
            out,
            file_format=file_format,
            topics=split_list(topics) or None,
            fields=split_list(fields) or None,
            start=start,
            end=end,
            dataset=dataset,
            progress=progress,
        )
    finally:
        progress.close()
    for topic, reason in report.skipped.items():
        warn(f"topic {topic} skipped: {reason}")
    for problem in report.problems:
        warn(f"lost: {problem}")
    for topic, files in report.files.items():
        where = files[0].parent if len(files) > 1 else files[0]
        console.print(
            f"{topic}: {report.rows[topic]:,} rows -> {where}", highlight=False, soft_wrap=True
        )
