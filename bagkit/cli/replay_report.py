"""What ``bagkit replay`` says: warnings before the first message, and when it ends the table of
replayed topics, the timing line, the service requests' outcomes and the exit status."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import typer

from bagkit.cli import common
from bagkit.cli.common import EXIT_INTERRUPTED, ReportFormat, fail, print_json, warn
from bagkit.cli.tables import Column, Table, print_table
from bagkit.playback.options import OnDrift
from bagkit.playback.timing import LATE_THRESHOLD_NS
from bagkit.words import counted

if TYPE_CHECKING:
    from bagkit.playback.report import PlayReport
    from bagkit.playback.service_responses import ServiceReplaySummary
    from bagkit.ros.replay.player import Player


def warn_live_publishers(found: dict[str, list[str]]) -> None:
    """Warn that other nodes publish replayed topics too (``found``: topic -> those nodes)."""
    listed = "; ".join(f"{topic} (by {', '.join(nodes)})" for topic, nodes in found.items())
    warn(
        "replayed topics are also published by running nodes, whose subscribers will get "
        f"both: {listed}"
    )


def warn_skipped(player: Player) -> None:
    """Warn about the selected topics the player does not replay as recorded, and why."""
    topics = player.publishable
    if topics.skipped_types:
        listed = ", ".join(f"{t} ({ty})" for t, ty in sorted(topics.skipped_types.items()))
        warn(f"not replaying topics whose message type is not installed: {listed}")
    if topics.skipped_formats:
        listed = ", ".join(f"{t} ({f})" for t, f in sorted(topics.skipped_formats.items()))
        warn(f"not replaying topics whose serialization format is not cdr: {listed}")
    for name, changes in sorted(topics.drifted.items()):
        done = {
            OnDrift.RAW: "published as recorded",
            OnDrift.MIGRATE: "each message migrated to the installed definition",
        }.get(
            player.options.on_drift,
            "not replayed (--on-drift raw: as recorded, migrate: migrated)",
        )
        warn(
            f"{name}: its definition differs from the installed one ({'; '.join(changes)}): {done}"
        )


def finish(report: PlayReport, bag: str, output_format: ReportFormat) -> None:
    """The report; warnings, the error of a replay that found nothing readable, the exit status."""
    if output_format is ReportFormat.JSON:
        print_json(report.to_dict())
    else:
        print_report(report)
    damage = "; ".join(report.problems)
    if report.problems and report.messages == 0 and not report.interrupted:
        raise fail(f"nothing replayed: {bag} is damaged: {damage}", 2)
    if report.messages == 0 and not report.interrupted:
        warn("no message of the selected topics lies in the replayed window")
    if report.problems:
        unreadable = f", {report.unreadable} could not be read" if report.unreadable else ""
        warn(
            f"the bag is damaged: replayed the {counted(report.messages, 'message')} that could "
            f"be read{unreadable}; {damage}"
        )
    if report.unacknowledged:
        warn(
            "subscribers had not acknowledged every message after 10 s on: "
            + ", ".join(report.unacknowledged)
        )
    if report.interrupted:
        raise typer.Exit(EXIT_INTERRUPTED)
    if report.service_requests is not None and not report.service_requests.ok:
        raise typer.Exit(1)


def print_report(report: PlayReport) -> None:
    """The table of replayed topics, the closing line and the timing error."""
    damaged = report.unreadable > 0
    table = Table(
        [Column("topic"), Column("published as"), Column("type"), Column("messages", numeric=True)]
        + ([Column("unreadable", numeric=True)] if damaged else [])
    )
    for topic in report.topics:
        table.add_row(
            topic.topic,
            "" if topic.published_as == topic.topic else topic.published_as,
            topic.type,
            str(topic.messages),
            *([str(topic.unreadable)] if damaged else []),
        )
    print_table(table)
    lateness = report.lateness
    common.console.print(
        f"{counted(report.messages, 'message')} in {report.played_s:.3f} s "
        + (f"played, {report.paused_s:.3f} s paused " if report.paused_s else "")
        + f"({report.bag_duration_s:.3f} s of bag time, rate {report.rate:g}"
        + (f", {counted(report.loops, 'pass', 'passes')}" if report.loops > 1 else "")
        + (f", {report.latched} of them latched state" if report.latched else "")
        + ")",
        highlight=False,
        soft_wrap=True,
    )
    timing = (
        f"p50 {lateness.p50_ms:.3f} ms, p99 {lateness.p99_ms:.3f} ms, "
        f"max {lateness.max_ms:.3f} ms, {counted(lateness.late, 'message')} late "
        f"(> {LATE_THRESHOLD_NS / 1e6:g} ms)"
    )
    if math.isnan(lateness.p50_ms):
        timing = "no message was published on schedule"
    common.console.print(f"timing error: {timing}", highlight=False, soft_wrap=True)
    if report.service_requests is not None:
        _print_service_requests(report.service_requests)


def _print_service_requests(summary: ServiceReplaySummary) -> None:
    """The requests sent and how the live responses compared, then each call that did not."""
    totals = {k: summary.total(k) for k in ("sent", "matched", "differed", "unanswered")}
    line = ", ".join(f"{n} {k}" for k, n in totals.items())
    if summary.total("not_recorded"):
        line += f", {summary.total('not_recorded')} without a recorded response"
    common.console.print(f"service requests: {line}", highlight=False, soft_wrap=True)
    for call in summary.calls:
        what = "; ".join(call.differences) if call.differences else call.outcome
        common.console.print(
            f"  {call.service} #{call.sequence_number}: {what}",
            highlight=False,
            soft_wrap=True,
            markup=False,
        )
