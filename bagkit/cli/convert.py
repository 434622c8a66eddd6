"""``bagkit convert``: bags of any storage into a rosbag2 MCAP or SQLite3 bag (like ``ros2
bag convert``, ``rosbags-convert`` and ``mcap convert``)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import typer

from bagkit.cli.common import ReportFormat, handle_errors
from bagkit.cli.option_parsing import bag_location, split_list
from bagkit.cli.progress import DelayedProgress
from bagkit.cli.selection_options import Distro, End, Start, build_query
from bagkit.cli.surgery_options import (
    CheckCrc,
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
    SelectionCommand,
    latched_options,
    output_options,
    print_report,
    topic_of_where,
)
from bagkit.storage.transfer import written_to
from bagkit.surgery.convert import convert_bags, read_output_options
from bagkit.surgery.errors import SurgeryError
from bagkit.surgery.rewrite import OutputOptions, RewriteReport
from bagkit.surgery.select import Selection

HELP = """Convert BAGs (rosbag2 directories, .mcap, .db3 or ROS 1 .bag files, several merged
in log-time order) into a new rosbag2 bag OUT: MCAP (default) or SQLite3 (--storage sqlite3),
with every topic's definition, QoS and type hash and each bag's custom_data. ROS 1 types
become their ROS 2 form (as rosbags-convert maps them), payloads CDR. --compression sets
OUT's: MCAP chunks zstd (default), lz4 or none; sqlite3 none (default) or zstd per message.
Topics, times, --where and the latched state are selected as in bagkit filter. MCAP chunks
already in OUT's compression are copied as stored. An OUT ending in .mcap is one MCAP file,
not a directory.

--output-options FILE reads ros2 bag convert's options file instead of -o (output_bags: a
list of uri, storage_id, topics, regex, exclude_topics, compression_format, ...; one bag each).

Examples:

  bagkit convert old_drive.bag -o drive

  bagkit convert field_db3_bag -o field.mcap

  bagkit convert field_db3_bag -o field_mcap --compression zstd

  bagkit convert drive -o drive_db3 --storage sqlite3 --topics /imu/data
"""
STORAGE_HELP = "OUT's storage: mcap (default) or sqlite3."
COMPRESSION_HELP = (
    "OUT's compression: zstd, lz4 (mcap only) or none (default: zstd for mcap, none for sqlite3)."
)
OPTIONS_HELP = "ros2 bag convert's YAML options file (output_bags: [...]) instead of -o."


COMMAND_CLASS = SelectionCommand


@handle_errors
def convert(
    bags: list[Path] = typer.Argument(
        ..., help="The bags to convert (merged when several).", parser=bag_location
    ),
    *,
    output: Path | None = typer.Option(
        None,
        "--output",
        "-o",
        help="The bag directory to write, or one MCAP file if it ends in .mcap (must not "
        "exist unless --force); a URL uploads it.",
        parser=bag_location,
    ),
    output_options_file: Path | None = typer.Option(
        None, "--output-options", help=OPTIONS_HELP, metavar="FILE"
    ),
    storage: str = typer.Option("mcap", "--storage", "-s", help=STORAGE_HELP),
    compression: str | None = typer.Option(None, "--compression", help=COMPRESSION_HELP),
    topics: KeepTopics = None,
    regex: KeepRegex = "",
    exclude_topics: ExcludeTopics = None,
    exclude_regex: ExcludeRegex = "",
    start: Start = None,
    end: End = None,
    where: KeepWhere = None,
    latched_topics: LatchedTopics = None,
    no_latched: NoLatched = False,
    max_bag_size: MaxBagSize = 0,
    max_bag_duration: MaxBagDuration = 0.0,
    force: Force = False,
    check_crc: CheckCrc = True,
    output_format: Format = ReportFormat.TABLE,
    distro: Distro = None,
) -> None:
    """Convert bags to a rosbag2 MCAP or SQLite3 bag."""
    where_topic, where = topic_of_where(where)
    query = build_query(topics, start=start, end=end, where=where)
    latched = latched_options(latched_topics, no_latched)
    if output_options_file is not None:
        if output is not None:
            raise SurgeryError("give -o or --output-options, not both")
        for spec in read_output_options(output_options_file, force=force):
            selection = replace(
                spec.selection, latched=latched, where=query.where, where_topic=where_topic
            )
            _convert(bags, spec.uri, selection, spec.options, output_format)
        return
    if output is None:
        raise SurgeryError("no output: give -o OUT (or --output-options FILE)")
    selection = Selection.of(
        query, regex=regex, exclude_topics=split_list(exclude_topics), exclude_regex=exclude_regex
    )
    options = replace(
        output_options(
            compression or ("none" if storage == "sqlite3" else "zstd"),
            max_bag_size,
            max_bag_duration,
            force=force,
            check_crc=check_crc,
        ),
        storage=storage,
    )
    selection = replace(selection, latched=latched, where_topic=where_topic)
    _convert(bags, output, selection, options, output_format)


def _convert(
    bags: list[Path],
    output: Path,
    selection: Selection,
    options: OutputOptions,
    output_format: ReportFormat,
) -> None:
    progress = DelayedProgress(f"converting to {output}")
    try:
        with written_to(output, replace=options.force) as local:
            report: RewriteReport = convert_bags(bags, local, selection, options, progress)
        report.output = output
    finally:
        progress.close()
    print_report(report, output_format)
