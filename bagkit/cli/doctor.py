"""``bagkit doctor``: check a bag, one line per problem (exit 0 healthy, 1 problems)."""

from __future__ import annotations

from pathlib import Path

import typer

from bagkit.cli.common import ReportFormat, console, err_console, handle_errors, print_json
from bagkit.cli.surgery_options import Format
from bagkit.surgery.doctor import diagnose

HELP = """Check a bag like mcap doctor, for whole rosbag2 bags: chunk CRCs, message and chunk
indexes against the records, the summary against the content, metadata.yaml against the files
(file list, counts, times, topics), every schema decodable; with --deep every message too.
Prints one line per problem; exit code 0 healthy, 1 problems found, 2 unreadable. Lines
starting with "note:" describe valid data worth knowing (they do not count as problems).

Example: bagkit doctor drive --deep
"""


@handle_errors
def doctor(
    bag: Path = typer.Argument(..., help="Bag directory, its metadata.yaml, or a .mcap file."),
    deep: bool = typer.Option(False, "--deep", help="Also decode every message."),
    output_format: Format = ReportFormat.TABLE,
) -> None:
    """Check a bag; one line per problem."""
    with err_console.status(f"checking {bag}"):
        report = diagnose(bag, deep=deep)
    if output_format == ReportFormat.JSON:
        print_json(report.to_dict())
    else:
        for finding in report.findings:
            console.print(finding.line, highlight=False, soft_wrap=True, markup=False)
        if report.healthy:
            console.print(
                f"{bag}: healthy ({report.message_count:,} messages in "
                f"{len(report.files)} files{', all decoded' if deep else ''})",
                highlight=False,
                soft_wrap=True,
                markup=False,
            )
    raise typer.Exit(0 if report.healthy else 1)
