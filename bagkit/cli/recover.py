"""``bagkit recover`` (alias ``reindex``): rewrite a crashed or truncated bag as a complete one."""

from __future__ import annotations

import enum
from pathlib import Path

import typer

from bagkit.cli.common import console, err_console, handle_errors, print_json, warn
from bagkit.surgery.rewrite import OutputOptions, RewriteReport, recover_bag

HELP = """Rewrite a crashed (killed), truncated or index-less bag as a complete one: chunks,
message indexes, summary with statistics, chunk indexes, metadata.yaml (version 9) and the
rosbag2 metadata record, so that ros2 bag, rosbags, the mcap tools and Foxglove open it.
Intact chunks are copied as they are stored (not recompressed); what could not be read is
printed.

Example: bagkit recover crashed_drive -o drive_recovered
"""

OUTPUT_HELP = "The bag directory to write (must not exist unless --force)."
FORCE_HELP = "Replace OUT if it exists."
CRC_HELP = "Check each chunk's CRC (a damaged chunk's messages are reported lost)."


class ReportFormat(enum.StrEnum):
    """How the surgery commands print their report."""

    TEXT = "text"
    JSON = "json"


FORMAT_OPTION = typer.Option(
    ReportFormat.TEXT, "--format", help="text (for people) or json (for scripts)."
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
    for problem in report.problems:
        warn(f"lost: {problem}")


@handle_errors
def recover(
    bag: Path = typer.Argument(..., help="The bag (directory or .mcap file) to recover."),
    output: Path = typer.Option(..., "--output", "-o", help=OUTPUT_HELP),
    force: bool = typer.Option(False, "--force", help=FORCE_HELP),
    check_crc: bool = typer.Option(True, "--crc/--no-crc", help=CRC_HELP),
    output_format: ReportFormat = FORMAT_OPTION,
) -> None:
    """Rewrite a crashed or truncated bag as a complete one."""
    with err_console.status(f"recovering {bag}"):
        report = recover_bag(bag, output, OutputOptions(force=force, check_crc=check_crc))
    print_report(report, output_format)
