"""``bagkit catalog``: a Parquet catalogue of many bags, one row per bag and topic; ``query``."""

from __future__ import annotations

import sys
from datetime import timezone
from pathlib import Path
from typing import TYPE_CHECKING, Any

import typer
from rich.measure import Measurement
from rich.table import Table

from bagkit.cli.common import (
    OutputFormat,
    console,
    err_console,
    fail,
    handle_errors,
    print_json,
)
from bagkit.cli.fleet_options import BAGS_HELP, Scheduler, Workers, fleet_run
from bagkit.errors import BagkitError

if TYPE_CHECKING:
    import pandas as pd


class _BuildByDefault(typer.core.TyperGroup):
    """``bagkit catalog ROOT...`` is ``bagkit catalog build ROOT...``."""

    def parse_args(self, ctx: Any, args: list[str]) -> list[str]:
        if args and args[0] not in self.commands and args[0] not in ("-h", "--help"):
            args = ["build", *args]
        return super().parse_args(ctx, args)


app = typer.Typer(
    name="catalog",
    cls=_BuildByDefault,
    help="A Parquet catalogue of many bags (one row per bag and topic), updated in place; "
    "'bagkit catalog ROOT... -o catalog.parquet' builds or updates it, "
    "'bagkit catalog query' searches it. See docs/fleet.md.",
    no_args_is_help=True,
    context_settings={"help_option_names": ["-h", "--help"]},
)


@app.command("build", no_args_is_help=True)
@handle_errors
def build(
    roots: list[Path] = typer.Argument(
        ...,
        help=BAGS_HELP + ".",
        metavar="ROOT",
        show_default=False,
    ),
    output: Path = typer.Option(..., "--output", "-o", help="The catalogue (.parquet)."),
    workers: Workers = None,
    scheduler: Scheduler = None,
) -> None:
    """Build or update a catalogue: bags unchanged since the last update are not reopened.

    Example: bagkit catalog /data/flights -o flights.parquet
    """
    from bagkit.fleet.catalog import complete_update, plan_update, write_catalog

    plan = plan_update(roots, output)
    changed = bool(plan.to_open or plan.removed) or not output.exists()
    if plan.to_open:
        with fleet_run(plan.to_open, workers=workers, scheduler=scheduler, label="cataloguing") as (
            client,
            done,
        ):
            frame = complete_update(plan, client, done)
    else:
        frame = complete_update(plan, None)
    if changed:
        write_catalog(frame, output)
    err_console.print(
        f"{output}: {len(plan.bags)} bags, {len(frame)} rows; {len(plan.to_open)} read, "
        f"{len(plan.bags) - len(plan.to_open)} unchanged, {plan.removed} removed",
        highlight=False,
    )


def _timestamp(text: str | None) -> pd.Timestamp | None:
    import pandas as pd

    if text is None:
        return None
    try:
        stamp = pd.Timestamp(text)
    except ValueError:
        stamp = pd.NaT
    if pd.isna(stamp):  # also "nan" and "": pandas reads them as no time at all
        raise fail(f"not a date and time: {text!r} (e.g. 2026-11-23T14:00Z)")
    return stamp.tz_localize(timezone.utc) if stamp.tzinfo is None else stamp


@app.command("query", no_args_is_help=True)
@handle_errors
def query(
    catalog: Path = typer.Argument(..., help="A catalogue written by bagkit catalog."),
    topic: str | None = typer.Option(
        None, "--topic", "-t", help="Bags with messages on this topic (a glob: '/gps/*')."
    ),
    start: str | None = typer.Option(
        None, "--start", help="Bags with messages at or after this time (ISO 8601, UTC if no zone)."
    ),
    end: str | None = typer.Option(
        None, "--end", help="Bags with messages at or before this time."
    ),
    output: OutputFormat = typer.Option(OutputFormat.TABLE, "--format", help="table, json or csv."),
) -> None:
    """Rows of the catalogue with messages on a topic within a time range.

    Example: bagkit catalog query flights.parquet -t /gps/fix --start 2026-11-01 --end 2026-11-08
    """
    from bagkit.fleet.catalog import query as select
    from bagkit.fleet.catalog import read_catalog

    if not catalog.exists():
        raise BagkitError(f"{catalog}: no such catalogue")
    rows = select(read_catalog(catalog), topic=topic, start=_timestamp(start), end=_timestamp(end))
    columns = ["path", "topic", "type", "count", "start", "end", "duration"]
    if output is OutputFormat.JSON:
        records = rows[columns].astype({"start": "string", "end": "string"})
        print_json(records.astype(object).where(records.notna(), None).to_dict("records"))
    elif output is OutputFormat.CSV:
        rows[columns].to_csv(sys.stdout, index=False)
    else:
        _print_table(rows[columns])


def _print_table(rows: pd.DataFrame) -> None:
    table = Table(show_edge=False, box=None, header_style="dim")
    for column in rows.columns:
        table.add_column(column, no_wrap=True, justify="right" if column == "count" else "left")
    for record in rows.itertuples(index=False):
        table.add_row(*(_cell(value) for value in record))
    # Paths and times are never cut: the table is printed as wide as it needs.
    natural = Measurement.get(console, console.options.update(width=10_000), table).maximum
    width = console.width
    console.width = max(width, natural)
    try:
        console.print(table)
    finally:
        console.width = width
    err_console.print(f"{len(rows)} rows", highlight=False)


def _cell(value: object) -> str:
    if hasattr(value, "isoformat"):
        return value.isoformat(timespec="milliseconds").replace("+00:00", "Z")
    if isinstance(value, float):
        return f"{value:.3f}"
    return str(value)
