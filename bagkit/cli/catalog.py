"""``bagkit catalog``: a Parquet catalogue of many bags, one row per bag and topic; ``query``."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

import typer

from bagkit.cli.common import OutputFormat, err_console, handle_errors, print_json, warn
from bagkit.cli.fleet_options import BAGS_HELP, Scheduler, Workers, end_with_unread, fleet_run
from bagkit.cli.option_parsing import bag_location
from bagkit.cli.selection_options import build_query
from bagkit.cli.tables import Column, Table, print_table
from bagkit.errors import BagkitError
from bagkit.words import counted

if TYPE_CHECKING:
    import pandas as pd

    from bagkit.fleet.catalog import CatalogPlan


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
        parser=bag_location,
        help=BAGS_HELP + ".",
        metavar="ROOT",
        show_default=False,
    ),
    output: Path = typer.Option(
        ...,
        "--output",
        "-o",
        help="The catalogue (.parquet); a URL is fetched, updated, uploaded.",
        parser=bag_location,
    ),
    events: list[str] | None = typer.Option(
        None,
        "--events",
        help="NAME='TOPIC: CONDITION': store the episodes where it holds in each bag "
        "(repeat for several), for query --event NAME.",
        metavar="NAME=TRIGGER",
    ),
    workers: Workers = None,
    scheduler: Scheduler = None,
) -> None:
    """Build or update a catalogue: bags unchanged since the last update are not reopened.

    With --events, the episodes of each named condition go to OUTPUT's .events.parquet
    beside it (a bag is searched again when it changed or the condition did). A bag that
    cannot be read gets a row saying why, a warning, and exit status 2.

    Example:

      bagkit catalog /data/flights -o flights.parquet
    --events gps_lost='/gps/fix: status.status < 0'
    """
    from bagkit.fleet.events import parse_events
    from bagkit.storage.transfer import written_to

    named = parse_events(events or [])
    with written_to(output, update=True) as local:
        _build(roots, local, named, workers, scheduler, shown=output)


def _build(
    roots: list[Path],
    output: Path,
    named: dict[str, str],
    workers: int | None,
    scheduler: str | None,
    *,
    shown: Path,
) -> None:
    """Update the catalogue ``output`` (a local copy of ``shown`` when that is a URL)."""
    from bagkit.errors import not_read
    from bagkit.fleet.catalog import complete_update, plan_update, unreadable, write_catalog
    from bagkit.fleet.cluster import CATALOG_RATE

    plan = plan_update(roots, output)
    changed = bool(plan.to_open or plan.removed) or not output.exists()
    if plan.to_open:
        with fleet_run(
            plan.to_open,
            workers=workers,
            scheduler=scheduler,
            label="cataloguing",
            rate=CATALOG_RATE,
        ) as (
            client,
            done,
        ):
            frame = complete_update(plan, client, done)
    else:
        frame = complete_update(plan, None)
    if changed:
        write_catalog(frame, output)
    unread = unreadable(frame)  # described in the catalogue all the same (their problems)
    for path, why in unread.items():
        warn(not_read(path, why))
    err_console.print(
        f"{shown}: {counted(len(plan.bags), 'bag')}, {counted(len(frame), 'row')}; "
        f"{len(plan.to_open)} read, "
        f"{len(plan.bags) - len(plan.to_open)} unchanged, {plan.removed} removed",
        highlight=False,
    )
    if named:
        _update_events(plan, named, output, workers, scheduler)
    end_with_unread(len(unread), len(plan.bags))


def _update_events(
    plan: CatalogPlan,
    named: dict[str, str],
    output: Path,
    workers: int | None,
    scheduler: str | None,
) -> None:
    from bagkit.fleet.cluster import FIND_RATE
    from bagkit.fleet.events import events_path, update_events

    with fleet_run(
        plan.bags, workers=workers, scheduler=scheduler, label="searching", rate=FIND_RATE
    ) as (
        client,
        _,
    ):
        frame = update_events(plan, named, output, client)
    found = frame[frame["count"] > 0]
    for name in named:
        bags = found[found["event"] == name]["path"].nunique()
        episodes = int((found["event"] == name).sum())
        err_console.print(
            f"{events_path(output)}: {name}: {counted(episodes, 'episode')} in "
            f"{counted(bags, 'bag')}",
            highlight=False,
        )


@app.command("query", no_args_is_help=True)
@handle_errors
def query(  # noqa: PLR0917 (typer maps parameters to options)
    catalog: Path = typer.Argument(
        ...,
        help="A catalogue written by bagkit catalog (a path or a URL).",
        parser=bag_location,
    ),
    topic: str | None = typer.Option(
        None, "--topic", "-t", help="Bags with messages on this topic (a glob: '/gps/*')."
    ),
    start: str | None = typer.Option(
        None,
        "--start",
        help="Bags with messages at or after this time (ISO 8601, UTC if no zone; epoch seconds).",
    ),
    end: str | None = typer.Option(
        None, "--end", help="Bags with messages at or before this time."
    ),
    event: str | None = typer.Option(
        None,
        "--event",
        help="Episodes of this event (catalog --events NAME=...) within the time range.",
        metavar="NAME",
    ),
    output: OutputFormat = typer.Option(OutputFormat.TABLE, "--format", help="table, json or csv."),
) -> None:
    """Rows of the catalogue with messages on a topic within a time range; with --event, the
    episodes of a named event (which bags had it, when).

    Examples:

      bagkit catalog query flights.parquet -t /gps/fix \\
        --start 2026-11-01 --end 2026-11-08

      bagkit catalog query flights.parquet --event gps_lost --start 2026-11-18
    """
    from bagkit.fleet.catalog import query as select
    from bagkit.fleet.catalog import read_catalog, unknown_topics
    from bagkit.fleet.events import events_path, query_events, read_events
    from bagkit.storage.transfer import read_from

    selection = build_query(topic, start=start, end=end)
    # A catalogue at a URL is fetched (with its events file) into a temporary folder.
    with read_from(catalog, events_path(Path(catalog.name)).name) as local:
        if not local.exists():
            raise BagkitError(f"{catalog}: no such catalogue")
        if event is not None:
            rows = query_events(read_events(events_path(local)), event, selection)
            columns = ["path", "event", "topic", "start", "end", "count"]
        else:
            frame = read_catalog(local)
            rows = select(frame, selection)
            for unknown in unknown_topics(frame, selection) if rows.empty else ():
                warn(unknown)
            columns = ["path", "topic", "type", "count", "start", "end", "duration"]
    if output is OutputFormat.JSON:
        records = rows[columns].astype({"start": "string", "end": "string"})
        print_json(records.astype(object).where(records.notna(), None).to_dict("records"))
    elif output is OutputFormat.CSV:
        rows[columns].to_csv(sys.stdout, index=False)
    else:
        _print_table(rows[columns])


def _print_table(rows: pd.DataFrame) -> None:
    table = Table([Column(c, numeric=c in ("count", "duration")) for c in rows.columns])
    for record in rows.itertuples(index=False):
        table.add_row(*(_cell(value) for value in record))
    print_table(table)
    err_console.print(counted(len(rows), "row"), highlight=False)


def _cell(value: object) -> str:
    if hasattr(value, "isoformat"):
        return value.isoformat(timespec="milliseconds").replace("+00:00", "Z")
    if isinstance(value, float):
        return f"{value:.3f}"
    return str(value)
