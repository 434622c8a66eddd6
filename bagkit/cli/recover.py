"""``bagkit recover`` (alias ``reindex``): rewrite a crashed or truncated bag as a complete one."""

from __future__ import annotations

from pathlib import Path

import typer

from bagkit.cli.common import ReportFormat, fail, handle_errors, status
from bagkit.cli.option_parsing import LOCAL_BAG_HELP
from bagkit.cli.surgery_options import (
    CheckCrc,
    Force,
    Format,
    Output,
    output_options,
    print_report,
)
from bagkit.surgery.rewrite import recover_bag

HELP = """Rewrite a crashed (killed), truncated or index-less bag as a complete one: chunks,
message indexes, summary with statistics, chunk indexes, metadata.yaml (version 9) and the
rosbag2 metadata record, so that ros2 bag, rosbags, the mcap tools and Foxglove open it.
Intact chunks are copied as they are stored (not recompressed); what could not be read is
printed.

Exit status: 0 when everything was read, 3 when messages were recovered but something was lost
(printed as 'lost: ...'), 1 when no message could be recovered of a damaged bag (an intact bag
without messages is recovered as one: 0), 2 for bad input.

Examples:

  bagkit recover crashed_drive -o drive_recovered

  bagkit recover crashed_drive/crashed_drive_0.mcap -o drive.mcap
"""


@handle_errors
def recover(
    bag: Path = typer.Argument(..., help=LOCAL_BAG_HELP),
    *,
    output: Output,
    force: Force = False,
    check_crc: CheckCrc = True,
    output_format: Format = ReportFormat.TABLE,
) -> None:
    """Rewrite a crashed or truncated bag as a complete one."""
    options = output_options(force=force, check_crc=check_crc)
    with status(f"recovering {bag}"):
        report = recover_bag(bag, output, options)
    print_report(report, output_format)
    if report.recover_exit_code == 1:
        raise fail(f"no message of {bag} could be recovered", report.recover_exit_code)
    raise typer.Exit(report.recover_exit_code)
