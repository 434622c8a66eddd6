"""The options of ``bagkit stats summary``, declared once each so the command reads as what it
does (the many-bag ones are :mod:`bagkit.cli.fleet_options`')."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from bagkit.cli.common import OutputFormat
from bagkit.cli.fleet_options import BAGS_HELP
from bagkit.cli.option_parsing import bag_location

Inputs = Annotated[
    list[Path],
    typer.Argument(
        help=BAGS_HELP + "; several bags are pooled.",
        metavar="BAG",
        show_default=False,
        parser=bag_location,
    ),
]
Topics = Annotated[
    list[str] | None,
    typer.Option("--topics", "-t", help="Only these topics (repeat, or a comma list)."),
]
Fields = Annotated[
    list[str] | None,
    typer.Option(
        "--fields",
        "-f",
        help="Only fields matching these globs, e.g. 'linear_acceleration.*' "
        "(* and ? are wildcards, brackets are literal: 'orientation_covariance[0]').",
    ),
]
Format = Annotated[
    OutputFormat, typer.Option("--format", help="table for people, json or csv for scripts.")
]
Bulk = Annotated[
    bool,
    typer.Option(
        "--bulk/--no-bulk",
        help="Decode fixed-layout messages in bulk with numpy (--no-bulk: one by one, slower, "
        "to cross-check).",
    ),
]
