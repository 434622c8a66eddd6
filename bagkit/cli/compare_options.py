"""The options of ``bagkit compare``, declared once each so the command reads as what it does."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from bagkit.cli.common import ReportFormat
from bagkit.cli.option_parsing import bag_location

Golden = Annotated[
    Path, typer.Argument(help="The reference bag (directory, .mcap or URL).", parser=bag_location)
]
Candidate = Annotated[
    Path, typer.Argument(help="The bag to check against it.", parser=bag_location)
]
Topics = Annotated[
    list[str] | None,
    typer.Option(
        "--topics",
        "-t",
        help="Topics to compare (repeat or comma-separate); default: the topics both bags have.",
        show_default=False,
    ),
]
Atol = Annotated[float | None, typer.Option(help="Absolute tolerance of float fields [0].")]
Rtol = Annotated[float | None, typer.Option(help="Relative tolerance of float fields [0].")]
IgnoreFields = Annotated[
    list[str] | None,
    typer.Option(
        "--ignore-fields",
        "-i",
        help="Field glob to skip, e.g. 'pose.covariance*' or "
        "'/logger/summary:*' for one topic (repeatable).",
        show_default=False,
    ),
]
Spec = Annotated[
    Path | None,
    typer.Option(
        help="Fixture spec (spec.yaml) whose outputs and tolerances to use; the options "
        "given here override it."
    ),
]
Live = Annotated[bool, typer.Option("--live", help="With --spec: its live tolerances.")]
EventWindow = Annotated[
    str | None,
    typer.Option(
        help="Duration (0.5, 500ms) within which alert events of equal (name, level) match [0.5].",
        metavar="DURATION",
    ),
]
MatchWindow = Annotated[
    str | None,
    typer.Option(
        help="Duration within which header stamps match [0: exactly].", metavar="DURATION"
    ),
]
Skip = Annotated[
    str | None,
    typer.Option(
        help="Duration after the golden's first message before which nothing is compared.",
        metavar="DURATION",
    ),
]
PassRate = Annotated[
    float | None,
    typer.Option(
        min=0.0,
        max=1.0,
        help="Fraction of each topic's matched messages that must be within tolerance [1].",
    ),
]
IncludeTimes = Annotated[
    bool, typer.Option("--include-times", help="Also compare receive and publish times.")
]
Report = Annotated[Path | None, typer.Option(help="Write the JSON verdict to this file.")]
Format = Annotated[
    ReportFormat, typer.Option("--format", help="table, or json (the verdict on stdout).")
]
Show = Annotated[int, typer.Option(help="How many divergences to print and keep per topic.")]
