"""``bagkit export``: topics of bags to Parquet or CSV files, streamed with bounded memory."""

from __future__ import annotations

from collections.abc import Callable
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any

import typer

from bagkit.cli.common import console, handle_errors, none_decoded, warn
from bagkit.cli.fleet_options import BAGS_HELP, Scheduler, Workers, end_with_unread
from bagkit.cli.option_parsing import bag_location
from bagkit.cli.progress import DelayedProgress
from bagkit.cli.selection_options import Distro, End, Start, Where, build_query
from bagkit.data.formats import ExportFormat
from bagkit.words import counted

if TYPE_CHECKING:
    from bagkit.data.export import ExportReport

HELP = """Write topics of BAG to Parquet (zstd) or CSV files, one per topic, for pandas, polars,
DuckDB, Spark or a spreadsheet.

Columns: log_time and publish_time (int64 ns), then every leaf field under its dotted path
(header.stamp.sec, orientation_covariance[0]); variable-length sequences are list columns in
Parquet and JSON text in CSV. OUT is a directory (/imu/data -> OUT/imu/data.parquet), or a
.parquet/.csv file when one topic is exported; --dataset writes a folder of part files per
topic. Undecodable topics are skipped with a warning; a damaged bag exports what is intact and
the loss is reported. --where keeps the messages satisfying a condition (with several topics,
those whose type lacks its fields are left out).

Several bags (several BAGs, a directory of bags, a glob, a listing file) run on a local Dask
cluster (or --scheduler), each into OUT/<its path relative to the bags' common folder>; a bag
that cannot be exported is reported, and after the others the exit status is 2. See
docs/fleet.md.

Examples:

  bagkit export flight1 -o flight1_parquet

  bagkit export flight1 -t /imu/data -o imu.csv --start 10 --end 70

  bagkit export flight1 -o out --topics /gps/fix --topics /imu/data \\
    --fields 'header.stamp.*'

  bagkit export flight1 -t /imu/data -o low.parquet \\
    --where 'linear_acceleration.z < 0'

  bagkit export 'flights/2026-11-*' -o flights_parquet -t /imu/data \\
    --workers 4
"""


@handle_errors
def export(  # noqa: PLR0917 (typer maps parameters to options)
    inputs: list[Path] = typer.Argument(
        ..., help=BAGS_HELP + ".", metavar="BAG", show_default=False, parser=bag_location
    ),
    out: Path = typer.Option(
        ...,
        "--output",
        "-o",
        help="Output directory, or a .parquet/.csv file for one topic; a URL uploads it.",
        parser=bag_location,
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
    start: Start = None,
    end: End = None,
    where: Where = None,
    dataset: bool = typer.Option(
        False, "--dataset", help="Parquet: a folder of part files per topic (OUT/imu/data/)."
    ),
    workers: Workers = None,
    scheduler: Scheduler = None,
    distro: Distro = None,
) -> None:
    from bagkit.data.errors import nothing_read
    from bagkit.data.export import none_decoded_topics, nothing_read_topics
    from bagkit.fleet.inputs import BAG_FILE_SUFFIXES, expand_bags, is_bag_directory
    from bagkit.storage.transfer import shown_path, written_to

    query = build_query(topics, fields, start, end, where)
    if file_format is None:
        file_format = ExportFormat.CSV if out.suffix == ".csv" else ExportFormat.PARQUET
    options = {
        "file_format": file_format,
        "query": query,
        "dataset": dataset,
    }
    named = inputs[0] if len(inputs) == 1 else None
    with written_to(out, replace=True) as local:
        shown = partial(shown_path, local=local, output=out)
        one_bag = named is not None and (
            named.name.endswith(BAG_FILE_SUFFIXES) or is_bag_directory(named)
        )
        if named is not None and one_bag:
            reports = [_export_one(named, local, options)]
            _print_report(reports[0], shown, where=where)
            failed = 0
        else:
            bags = expand_bags(inputs)
            reports, failed = _export_many(
                bags, local, options, shown, where=where, workers=workers, scheduler=scheduler
            )
    undecoded = none_decoded_topics(reports)
    if undecoded:  # the topic's files hold no row: not an export of it (the rest is written)
        raise none_decoded(undecoded)
    unread, lost = nothing_read_topics(reports)
    if unread:  # empty files because chunks were lost, not because the topic is empty
        raise nothing_read(unread, lost)
    end_with_unread(failed, len(reports) + failed, undone="exported")


def _export_one(bag: Path, out: Path, options: dict[str, Any]) -> ExportReport:
    from bagkit.data.export import export as write

    progress = DelayedProgress("exporting")
    try:
        return write(bag, out, progress=progress, **options)
    finally:
        progress.close()


def _export_many(
    bags: list[Path],
    out: Path,
    options: dict[str, Any],
    shown: Callable[[Path], str],
    *,
    where: str | None,
    workers: int | None,
    scheduler: str | None,
) -> tuple[list[ExportReport], int]:
    """Export on a cluster and print each bag's report; return the reports and how many bags
    failed."""
    from bagkit.cli.fleet_options import fleet_run
    from bagkit.errors import not_read
    from bagkit.fleet.cluster import EXPORT_RATE
    from bagkit.fleet.export import export_fleet

    with fleet_run(
        bags, workers=workers, scheduler=scheduler, label="exporting", rate=EXPORT_RATE
    ) as (client, done):
        results = export_fleet(bags, out, client=client, done=done, **options)
    reports: list[ExportReport] = []
    for result in results:
        if result.report is None:
            warn(not_read(result.bag, str(result.error), "not exported"))
            continue
        console.print(f"{result.bag} -> {shown(result.out)}", highlight=False, soft_wrap=True)
        _print_report(result.report, shown, indent="  ", where=where)
        reports.append(result.report)
    return reports, len(results) - len(reports)


def _print_report(
    report: ExportReport,
    shown: Callable[[Path], str],
    indent: str = "",
    where: str | None = None,
) -> None:
    """The report of one bag's export; ``shown`` names a written path (under -o's URL)."""
    for topic, reason in report.skipped.items():
        warn(f"topic {topic} skipped: {reason}")
    for problem in report.problems:
        warn(f"lost: {problem}")
    decoded = any(n > report.undecodable[t] for t, n in report.messages.items())
    if where is not None and decoded and not any(report.rows.values()):
        warn(f"no message satisfies {where!r}")
    for topic, files in report.files.items():
        written = files[0].parent if len(files) > 1 else files[0]
        console.print(
            f"{indent}{topic}: {counted(report.rows[topic], 'row')} -> {shown(written)}",
            highlight=False,
            soft_wrap=True,
        )
