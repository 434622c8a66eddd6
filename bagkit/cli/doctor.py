"""``bagkit doctor``: check a bag, one line per problem (exit 0 healthy, 1 problems)."""

from __future__ import annotations

from pathlib import Path

import typer

from bagkit.cli.common import ReportFormat, console, err_console, handle_errors, print_json, status
from bagkit.cli.option_parsing import LOCAL_BAG_HELP
from bagkit.cli.selection_options import Distro
from bagkit.cli.surgery_options import Format
from bagkit.surgery.doctor import DoctorReport, diagnose
from bagkit.words import counted

HELP = """Check a bag like mcap doctor, for whole rosbag2 bags: chunk CRCs, message and chunk
indexes against the records, the summary against the content, metadata.yaml against the files
(file list, counts, times, topics), every schema decodable; with --deep every message too.
Prints one line per problem; exit code 0 healthy, 1 problems found, 2 unreadable. Lines
starting with "note:" describe valid data worth knowing (they do not count as problems).
With --against-installed, each topic's stored message definition is compared instead with the
one installed today (the ROS packages this Python or AMENT_PREFIX_PATH sees): every field added,
removed, retyped or moved is named; exit 1 when a topic drifted.

Examples:

  bagkit doctor drive --deep

  bagkit doctor fixtures/takeoff/golden --against-installed
"""


@handle_errors
def doctor(
    bag: Path = typer.Argument(..., help=LOCAL_BAG_HELP),
    deep: bool = typer.Option(False, "--deep", help="Also decode every message."),
    against_installed: bool = typer.Option(
        False,
        "--against-installed",
        help="Compare each topic's stored definition with the installed one instead.",
    ),
    output_format: Format = ReportFormat.TABLE,
    distro: Distro = None,
) -> None:
    """Check a bag; one line per problem."""
    if against_installed:
        _drift(bag, output_format)
    with status(f"checking {bag}"):
        report = diagnose(bag, deep=deep)
    if output_format == ReportFormat.JSON:
        print_json(report.to_dict())
    else:
        for finding in report.findings:
            console.print(finding.line, highlight=False, soft_wrap=True, markup=False)
        if report.healthy:
            console.print(
                f"{bag}: healthy ({counted(report.message_count, 'message')} in "
                f"{counted(len(report.files), 'file')}{_decoded(report) if deep else ''})",
                highlight=False,
                soft_wrap=True,
                markup=False,
            )
    raise typer.Exit(0 if report.healthy else 1)


def _decoded(report: DoctorReport) -> str:
    """What of the messages was decoded (``--deep``)."""
    if report.undecoded:
        return f", {counted(len(report.undecoded), 'topic')} not decoded: no definition"
    return ", all decoded"


def _drift(bag: Path, output_format: ReportFormat) -> None:
    """Print each topic's drift from the installed definitions; exit 1 when one drifted."""
    from bagkit.decode.drift import DriftStatus, bag_drift

    drifts = bag_drift(bag)
    if output_format == ReportFormat.JSON:
        print_json({"bag": str(bag), "topics": [drift.to_dict() for drift in drifts]})
    else:
        for drift in drifts:
            console.print(
                f"{drift.topic} ({drift.type}): {drift.status.value}",
                highlight=False,
                soft_wrap=True,
                markup=False,
            )
            for change in drift.changes:
                console.print(f"  {change}", highlight=False, soft_wrap=True, markup=False)
    drifted = [d.topic for d in drifts if d.status == DriftStatus.DRIFTED]
    if drifted:
        err_console.print(
            f"{bag}: {len(drifted)} of {counted(len(drifts), 'topic')} drifted from the installed "
            f"definitions: {', '.join(drifted)}",
            highlight=False,
            soft_wrap=True,
            markup=False,
        )
    raise typer.Exit(1 if drifted else 0)
