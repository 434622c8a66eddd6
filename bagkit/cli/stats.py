"""``bagkit stats summary``: per-topic counts and rates, exact statistics of every numeric field."""

# Annotations are objects here, not strings (no `from __future__ import annotations`): typer
# reads the command's parameters at every start and compiles each annotation written as a
# string, twice.

import math
import sys
from datetime import datetime, timezone
from pathlib import Path
from typing import TYPE_CHECKING, Any

import typer

from bagkit.cli import common
from bagkit.cli.common import (
    CheckCrcOnRead,
    OutputFormat,
    format_rate,
    handle_errors,
    none_decoded,
    note,
    print_json,
    warn,
)
from bagkit.cli.fleet_options import Scheduler, Workers, end_with_unread
from bagkit.cli.progress import DelayedProgress
from bagkit.cli.selection_options import Distro, End, Start, Where, build_query
from bagkit.cli.stats_options import Bulk, Fields, Format, Inputs, Topics
from bagkit.cli.tables import Cell, Column, Styled, Table, print_line, print_table, print_wrapped
from bagkit.words import counted

if TYPE_CHECKING:
    from bagkit.stats import FieldStats, Summary

# Below this many seconds a summary finishes without a progress bar flashing by.

app = typer.Typer(
    name="stats",
    help="Statistics of the numeric fields of bags, decoded without a ROS install.",
    no_args_is_help=True,
)


@app.command("summary", no_args_is_help=True)
@handle_errors
def summary(  # noqa: PLR0917 (typer maps parameters to options)
    inputs: Inputs,
    topics: Topics = None,
    fields: Fields = None,
    start: Start = None,
    end: End = None,
    where: Where = None,
    output: Format = OutputFormat.TABLE,
    bulk: Bulk = True,
    workers: Workers = None,
    scheduler: Scheduler = None,
    check_crc: CheckCrcOnRead = True,
    distro: Distro = None,
) -> None:
    """Count and rate per topic; count, NaN count, min, max, mean and std per numeric field.

    Field names are dotted paths (linear_acceleration.x), fixed arrays by index
    (orientation_covariance[0]), variable-length arrays pooled over their elements (ranges[]);
    booleans count as 0/1 and strings are left out. std is the sample standard deviation
    (ddof=1, as pandas). Messages are decoded from the definitions stored in the bag.

    Several bags run on a local Dask cluster (or --scheduler), each bag on one worker, with the
    same results as in one process; see docs/fleet.md.

    --where keeps the messages satisfying a condition (topics whose type lacks its fields are
    left out): bagkit stats summary flight1 -t /imu/data --where 'linear_acceleration.z < 0'

    Example:

      bagkit stats summary 'flights/2026-11-*' -t /imu/data --workers 4
    """
    from bagkit.fleet import expand_bags

    query = build_query(topics, fields, start, end, where)  # one error before any bag is read
    bags = expand_bags(inputs)
    options = {"query": query, "bulk": bulk, "check_crc": check_crc}
    result = _summarize(bags, options, workers=workers, scheduler=scheduler)
    for topic, reason in result.skipped.items():
        warn(f"topic {topic} skipped: {reason}")
    for problem in result.problems:
        warn(problem)
    summarized = {t.topic for t in result.topics}
    if output is OutputFormat.JSON:
        services = _service_latencies(bags, summarized)
        # "services" only where there are some: otherwise the JSON is the library's result.
        extra = {"services": services} if services else {}
        print_json(_json_safe({**result.to_dict(), **extra}))
    elif output is OutputFormat.CSV:
        _print_csv(result, _latency_rows(bags, summarized))
    else:
        _print_tables(result)
        _print_services(_service_latencies(bags, summarized))
    lost = {t.topic: t.count for t in result.topics if t.undecodable and t.undecodable == t.count}
    if lost:  # a topic none of whose messages decode: not a summary of it
        raise none_decoded(lost)
    end_with_unread(len(result.unread), len(bags))


def _service_latencies(bags: list[Path], topics: set[str]) -> list[dict[str, Any]]:
    """Per service whose event topic was summarized: its call latency (count, p50, p99, max
    in seconds), from the whole bag (calls are paired across the window's edges)."""
    from bagkit.selection.services import is_service_event_topic

    if not any(is_service_event_topic(t) for t in topics):
        return []
    from bagkit.data.service_summaries import service_summaries  # a bag with services only

    found = []
    for bag in bags:
        for service in service_summaries(bag):
            if service.topic not in topics:
                continue
            latency = service.latency
            found.append(
                {
                    "bag": str(bag),
                    "service": service.service,
                    "count": latency.count,
                    **{
                        key: None if value is None else value / 1e9
                        for key, value in (
                            ("p50_s", latency.p50_ns),
                            ("p99_s", latency.p99_ns),
                            ("max_s", latency.max_ns),
                        )
                    },
                }
            )
    return found


def _latency_rows(bags: list[Path], topics: set[str]) -> "dict[str, FieldStats]":
    """Per summarized event topic, CSV's ``latency_s`` row: the latency (s) of the service's
    answered calls, pooled over the bags (the table and JSON give p50/p99/max per bag)."""
    from bagkit.selection.services import is_service_event_topic

    if not any(is_service_event_topic(t) for t in topics):
        return {}
    import numpy as np

    from bagkit.data.services import call_latencies  # a bag with services only
    from bagkit.stats import value_stats

    pooled: dict[str, list[int]] = {}
    for bag in bags:
        for topic, latencies in call_latencies(bag).items():
            if topic in topics:
                pooled.setdefault(topic, []).extend(latencies)
    return {
        topic: value_stats("latency_s", np.array(latencies, dtype=np.float64) / 1e9)
        for topic, latencies in pooled.items()
    }


def _print_services(services: list[dict[str, Any]]) -> None:
    """One line per service and bag; the bag named where there are several."""
    several = len({service["bag"] for service in services}) > 1
    for service in services:
        print_line([])
        where = [f"{service['bag']}:"] if several else []
        figures = [
            f"{name} {_number(service[key] * 1e3 if service[key] is not None else None)} ms"
            for name, key in (("p50", "p50_s"), ("p99", "p99_s"), ("max", "max_s"))
        ]
        print_wrapped(
            [
                *where,
                Styled(service["service"], "bold"),
                f"latency: {counted(service['count'], 'call')},",
                *figures,
            ],
            sep="  ",
        )


def _summarize(
    bags: list[Path], options: dict[str, Any], *, workers: int | None, scheduler: str | None
) -> "Summary":
    """Summarize in this process (a progress bar over messages) or on Dask (over bags)."""
    from bagkit.fleet import fleet_client
    from bagkit.fleet.cluster import SUMMARY_RATE
    from bagkit.fleet.progress import BagProgress, bag_size
    from bagkit.stats import summarize

    sizes = [bag_size(bag) for bag in bags]
    with fleet_client(
        workers=workers,
        scheduler=scheduler,
        bags=len(bags),
        size_bytes=sum(sizes),
        rate=SUMMARY_RATE,
        announce=note,
    ) as client:
        if client is not None:
            from bagkit.fleet import summarize_fleet

            with BagProgress(bags, common.err_console, label="summarizing", sizes=sizes) as done:
                return summarize_fleet(bags, client=client, done=done, **options)
        progress = DelayedProgress("summarizing")
        try:
            return summarize(bags, progress=progress, **options)
        finally:
            progress.close()


def _json_safe(value: object) -> object:
    """Replace non-finite floats by strings (``"NaN"``, ``"inf"``): JSON has no such numbers."""
    if isinstance(value, float) and not math.isfinite(value):
        return str(value) if not math.isnan(value) else "NaN"
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_json_safe(v) for v in value]
    return value


def _utc(ns: int) -> str:
    stamp = datetime.fromtimestamp(ns / 1e9, tz=timezone.utc).isoformat(timespec="milliseconds")
    return stamp.replace("+00:00", "Z")


def _number(value: float | int | None) -> str:
    """Six significant digits, more for large values so that a stamp's seconds stay readable."""
    if value is None:
        return "-"
    if isinstance(value, int) or not math.isfinite(value):
        return str(value)
    integer_digits = len(str(int(abs(value)))) if abs(value) >= 1 else 0
    return f"{value:.{min(15, max(6, integer_digits + 3))}g}"


def _print_tables(result: "Summary") -> None:
    bags = [f"{bag}," for bag in result.bags[:-1]] + [f"{result.bags[-1]}:"]
    span = (
        [f"{_utc(result.start_ns)} ..", f"{_utc(result.end_ns)},"]
        if result.start_ns is not None and result.end_ns is not None
        else ["no message selected,"]
    )
    print_wrapped(
        [
            *(Styled(bag, "bold") for bag in bags),
            f"{result.duration_s:.3f} s,",
            *span,
            counted(len(result.topics), "topic"),
        ]
    )
    for topic in result.topics:
        rate = format_rate(topic.rate_hz, digits=3)
        print_line([])
        heading: list[Cell] = [Styled(topic.topic, "bold"), topic.type]
        heading += [counted(topic.count, "msg"), rate]
        print_wrapped(heading, sep="  ")
        if not topic.fields or topic.undecodable == topic.count:
            continue  # none decoded: the error line at the end says so, no table of zeros
        table = Table(
            [Column(FIELD_COLUMNS[0]), *(Column(c, numeric=True) for c in FIELD_COLUMNS[1:])]
        )
        for f in topic.fields:
            figures = [_number(v) for v in (f.min, f.max, f.mean, f.std)]
            table.add_row(f.field, str(f.count), str(f.nan_count), *figures)
        print_table(table)


# The per-topic table: field names left-aligned, numbers right-aligned (bagkit.cli.tables).
FIELD_COLUMNS = ("field", "count", "nan", "min", "max", "mean", "std")


def _print_csv(result: "Summary", latencies: "dict[str, FieldStats]") -> None:
    import csv  # here: the table and JSON start without it

    writer = csv.writer(sys.stdout, lineterminator="\n")
    writer.writerow(
        [
            "topic",
            "type",
            "topic_count",
            "rate_hz",
            "field",
            "count",
            "nan_count",
            "min",
            "max",
            "mean",
            "std",
        ]
    )
    for topic in result.topics:
        head = [topic.topic, topic.type, topic.count, _csv(topic.rate_hz)]
        latency = latencies.get(topic.topic)
        fields = (*topic.fields, latency) if latency is not None else topic.fields
        if not fields:
            writer.writerow([*head, "", "", "", "", "", "", ""])
        for f in fields:
            writer.writerow(
                [
                    *head,
                    f.field,
                    f.count,
                    f.nan_count,
                    _csv(f.min),
                    _csv(f.max),
                    _csv(f.mean),
                    _csv(f.std),
                ]
            )


def _csv(value: float | int | None) -> str:
    return "" if value is None else repr(value)
