"""The tables and progress line of ``bagkit record``, readable at 80 columns."""

from __future__ import annotations

from typing import TYPE_CHECKING

from bagkit.cli.common import format_rate
from bagkit.cli.tables import INDENT, Column, Styled, Table, print_line, print_table, print_wrapped
from bagkit.recording.loss_causes import large_message_cause
from bagkit.words import counted

if TYPE_CHECKING:
    from bagkit.recording.report import RecordProgress, RecordReport


def _human_bytes(count: float) -> str:
    for unit in ("B", "KiB", "MiB", "GiB"):
        if count < 1024 or unit == "GiB":
            return f"{count:.0f} {unit}" if unit == "B" else f"{count:.1f} {unit}"
        count /= 1024
    raise AssertionError("unreachable")


def print_record_table(report: RecordReport) -> None:
    """The end-of-recording table: per topic messages, lost, rate, bytes and type.

    The bag's path has a line of its own: it is as long as the user made it, and the figures
    after it are read (and parsed) whole.
    """
    discovery = (
        f"topics subscribed after {report.discovery_s:.1f} s"
        if report.discovery_s is not None
        else "a named topic never appeared"
    )
    print_line([Styled(str(report.path), "bold")])
    figures = [Column(c, numeric=True) for c in ("messages", "lost", "rate", "bytes")]
    table = Table(
        [Column("topic"), *figures, Column("type")],
        title=f"({report.duration_s:.1f} s, {discovery})",
    )
    for topic in report.topics:
        table.add_row(
            topic.topic,
            str(topic.messages),
            Styled(str(topic.lost), "red") if topic.lost else "0",
            format_rate(topic.rate_hz, digits=1),
            _human_bytes(topic.bytes),
            topic.type,
        )
    table.add_footer(
        "total", str(report.messages), str(report.lost), "", _human_bytes(report.bytes), ""
    )
    print_table(table)
    _print_notes(report)
    if report.snapshots is not None:
        _print_snapshots(report)
    if report.health is not None:
        _print_health(report)


def _print_notes(report: RecordReport) -> None:
    for topic in report.topics:
        notes = []
        if topic.lost:
            notes.append(
                f"{topic.gaps} lost in the middleware (sequence gaps), {topic.overflow} in "
                f"queue overflows, {topic.write_failed} in write failures"
            )
        if topic.before_clock:
            notes.append(f"{topic.before_clock} taken before the first /clock, not written")
        cause = large_message_cause(topic.topic, topic.gaps, topic.messages, topic.bytes)
        if cause is not None:
            notes.append(cause.removeprefix(f"{topic.topic}: "))
        if topic.paused:
            notes.append(f"{topic.paused} taken while paused, not written (not lost)")
        for note in notes:
            print_wrapped(f"{topic.topic}: {note}".split(" "), lead=INDENT)


def _print_snapshots(report: RecordReport) -> None:
    """Snapshot mode: what each snapshot holds, and what the buffer's bound evicted."""
    assert report.snapshots is not None
    evicted = sum(report.evicted.values())
    print_wrapped(
        f"snapshot mode: {counted(len(report.snapshots), 'snapshot')}; "
        f"{counted(evicted, 'message')} evicted from "
        "the buffer by its bound (not lost: not kept by design)".split(" ")
    )
    for snapshot in report.snapshots:
        held = ", ".join(f"{topic} {count}" for topic, count in sorted(snapshot.messages.items()))
        span = (snapshot.end_ns - snapshot.start_ns) / 1e9
        before = (snapshot.trigger_ns - snapshot.start_ns) / 1e9
        line = (
            f"{snapshot.path.name}: {span:.1f} s ({before:.1f} s before the trigger), "
            f"trigger {snapshot.trigger}"
            + (f" (x{snapshot.triggers})" if snapshot.triggers > 1 else "")
            + f", {counted(sum(snapshot.messages.values()), 'message')} ({held or 'none'})"
            + f", {snapshot.latched} latched at its start"
            + (f", FAILED: {snapshot.error}" if snapshot.error else "")
        )
        print_wrapped(line.split(" "), lead=INDENT)


def _print_health(report: RecordReport) -> None:
    """--health: per assertion that broke, how often it broke and cleared."""
    assert report.health is not None
    broke = [count for count in report.health if count.breaks]
    print_wrapped(f"health: {counted(len(report.health), 'check')}, {len(broke)} broke".split(" "))
    for count in broke:
        still = ", broken at the end" if count.broken_since_ns is not None else ""
        line = (
            f"{count.topic}: {count.assertion}: broke {count.breaks}, cleared {count.clears}{still}"
        )
        print_wrapped(line.split(" "), lead=INDENT)


def progress_line(progress: RecordProgress, *, subscribed: bool) -> str:
    """The status line while recording (waiting for topics, then counts)."""
    if not subscribed:
        return f"waiting for topics ({progress.topics} subscribed, {progress.elapsed_s:.0f} s)"
    lost = f", [red]{progress.lost} lost[/]" if progress.lost else ""
    if progress.before_clock:
        lost += f", {progress.before_clock} before the first /clock (not written)"
    if progress.paused:
        lost += f", {progress.paused} while paused"
    if progress.is_paused:
        return (
            f"paused (space or ~/resume to resume): {counted(progress.messages, 'message')}{lost}"
        )
    return (
        f"recording {counted(progress.topics, 'topic')}: {counted(progress.messages, 'message')}, "
        f"{_human_bytes(progress.bytes)}{lost} ({progress.elapsed_s:.0f} s)"
    )
