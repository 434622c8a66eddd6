"""``bagkit find``: the episodes where a condition on a topic's messages holds, over bags."""

# Annotations are objects here, not strings (no `from __future__ import annotations`): typer
# reads the command's parameters at every start and compiles each annotation written as a
# string, twice.

import datetime as dt
from pathlib import Path
from typing import TYPE_CHECKING

import typer

from bagkit.cli import common
from bagkit.cli.common import handle_errors, none_decoded, print_json, warn
from bagkit.cli.fleet_options import BAGS_HELP, Scheduler, Workers, end_with_unread, fleet_run
from bagkit.cli.option_parsing import bag_location, split_list
from bagkit.cli.selection_options import Distro, End, Start, StateTopics, build_query
from bagkit.compat import StrEnum
from bagkit.words import counted

if TYPE_CHECKING:
    from bagkit.fleet.find import FindResult

HELP = """List the episodes of BAGS where WHEN ('TOPIC: CONDITION') holds: runs of matching
messages, merged when the next match comes less than --gap after the last one.

Each episode has its bag, topic, first and last matching log time (ns) and how many messages
matched, and "from"/"to": seconds from the bag's start (ms, widened to hold the episode) that
--start/--end of filter and golden add and play's --start-offset take as printed. The
condition is the --where language (docs/cli.md): fixed-layout topics are matched in bulk with
numpy. Several bags run on a local Dask cluster (--workers, or --scheduler),
each bag on one worker, with the same result as in one process. A bag without the topic has no
episode; one that cannot be read is reported, and after the others' episodes, the exit
status is 2 (docs/fleet.md).

Examples:

  bagkit find flight1 --when '/alerts: status[*].level >= 2'

  bagkit find flights/ --when '/imu/data: linear_acceleration.z < 5' \\
    --gap 2 --format json

  bagkit find 'flights/2026-11-*' --when '/gps/fix: status.status < 0' \\
    -o gps.parquet --workers 4
"""


class FindFormat(StrEnum):
    """Output formats of ``find``."""

    TABLE = "table"
    JSON = "json"
    PARQUET = "parquet"


@handle_errors
def find(  # noqa: PLR0917 (typer maps parameters to options)
    inputs: list[Path] = typer.Argument(
        ..., help=BAGS_HELP + ".", metavar="BAGS...", show_default=False, parser=bag_location
    ),
    when: str = typer.Option(
        ...,
        "--when",
        help="'TOPIC: CONDITION', e.g. '/alerts: status[*].level >= 2'.",
        metavar="'TOPIC: CONDITION'",
    ),
    gap: str = typer.Option(
        "0",
        "--gap",
        help="Merge matches less than this apart into one episode (90, 1.5, 2s, 250ms).",
        metavar="SEC",
    ),
    output: FindFormat | None = typer.Option(
        None, "--format", help="table, json (one object per episode) or parquet (needs -o)."
    ),
    out: Path | None = typer.Option(
        None, "--output", "-o", help="The .parquet file to write (--format parquet)."
    ),
    start: Start = None,
    end: End = None,
    state_topics: StateTopics = None,
    workers: Workers = None,
    scheduler: Scheduler = None,
    distro: Distro = None,
) -> None:
    from bagkit.data.errors import DataError, nothing_read
    from bagkit.fleet import expand_bags
    from bagkit.fleet.cluster import FIND_RATE
    from bagkit.fleet.find import find_fleet
    from bagkit.selection.conditions import parse_topic_condition
    from bagkit.selection.times import parse_duration

    if output is None:
        output = FindFormat.PARQUET if out is not None else FindFormat.TABLE
    if (output is FindFormat.PARQUET) != (out is not None):
        raise DataError("--format parquet and -o/--output FILE go together")
    parse_topic_condition(when)  # a bad condition is one error before any bag is read
    query = build_query(start=start, end=end)
    gap_ns = parse_duration(gap, "--gap")
    bags = expand_bags(inputs)
    with fleet_run(
        bags, workers=workers, scheduler=scheduler, label="searching", rate=FIND_RATE
    ) as (
        client,
        done,
    ):
        result = find_fleet(
            bags,
            when=when,
            gap_ns=gap_ns,
            query=query,
            state_topics=tuple(split_list(state_topics)),
            client=client,
            done=done,
        )
    for problem in result.problems:
        warn(problem)
    if output is FindFormat.JSON:
        print_json([episode.to_dict() for episode in result.episodes])
    elif output is FindFormat.PARQUET:
        _write_parquet(result, out)
    else:
        _print_table(result)
    if result.none_decoded:  # "0 episodes" of a topic that could not be read is no answer
        raise none_decoded({result.topic: result.messages})
    if result.nothing_read:  # nor is "0 episodes" of a topic whose chunks were lost
        raise nothing_read([result.topic], result.lost)
    end_with_unread(result.unread, len(bags))


def _write_parquet(result: "FindResult", out: Path | None) -> None:
    import pyarrow.parquet as pq

    assert out is not None
    out.parent.mkdir(parents=True, exist_ok=True)
    pq.write_table(result.to_arrow(), out, compression="zstd")
    common.console.print(
        f"{counted(result.count, 'episode')} -> {out}", highlight=False, soft_wrap=True
    )


def _utc(ns: int) -> str:
    stamp = dt.datetime.fromtimestamp(ns // 1_000_000_000, tz=dt.timezone.utc)
    return stamp.strftime("%Y-%m-%dT%H:%M:%S") + f".{ns % 1_000_000_000 // 1_000_000:03d}Z"


def _print_table(result: "FindResult") -> None:
    from bagkit.cli.tables import Column, Table, print_table

    if not result.count:
        common.console.print(f"0 episodes of {result.topic}", highlight=False)
        return
    table = Table(
        [
            Column("bag"),
            Column("from (s)", numeric=True),
            Column("to (s)", numeric=True),
            Column("start (UTC)"),
            Column("end (UTC)"),
            Column("seconds", numeric=True),
            Column("count", numeric=True),
        ],
        title=f"{counted(result.count, 'episode')} of {result.topic}",
    )
    for e in result.episodes:
        seconds = f"{(e.end_ns - e.start_ns) / 1e9:.3f}"
        first, last = e.offsets
        table.add_row(
            e.bag,
            f"{first:.3f}",
            f"{last:.3f}",
            _utc(e.start_ns),
            _utc(e.end_ns),
            seconds,
            str(e.count),
        )
    print_table(table)
