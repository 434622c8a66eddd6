"""The tables and progress line of ``bagkit record``, readable at 80 columns."""

from __future__ import annotations

from typing import TYPE_CHECKING

from rich import box
from rich.table import Table

from bagkit.cli.common import console, format_rate, topic_table_fits

if TYPE_CHECKING:
    from bagkit.recording.report import RecordProgress, RecordReport


# messages, lost, rate and bytes, with the table's padding.
_NUMBER_COLUMNS = 48


def _human_bytes(count: float) -> str:
    for unit in ("B", "KiB", "MiB", "GiB"):
        if count < 1024 or unit == "GiB":
            return f"{count:.0f} {unit}" if unit == "B" else f"{count:.1f} {unit}"
        count /= 1024
    raise AssertionError("unreachable")


def print_record_table(report: RecordReport) -> None:
    """The end-of-recording table: per topic messages, lost, rate, bytes and type."""
    discovery = (
        f", topics subscribed after {report.discovery_s:.1f} s"
        if report.discovery_s is not None
        else ", a named topic never appeared"
    )
    title = f"{report.path} ({report.duration_s:.1f} s{discovery})"
    if not topic_table_fits([t.topic for t in report.topics], _NUMBER_COLUMNS):
        _print_stacked(report, title)
    else:
        _print_table(report, title)
    _print_notes(report)


def _print_stacked(report: RecordReport, title: str) -> None:
    """One topic per line, its figures on the next: for names too long for a table row."""
    console.print(title, highlight=False, markup=False)
    for topic in [*report.topics, None]:
        name = topic.topic if topic else "total"
        messages, lost = (topic.messages, topic.lost) if topic else (report.messages, report.lost)
        size = _human_bytes(topic.bytes if topic else report.bytes)
        figures = f"{messages} messages, {lost} lost, {size}"
        if topic:
            figures += f", {format_rate(topic.rate_hz, digits=1)}, {topic.type}"
        console.print(f"  {name}", style="bold", highlight=False, markup=False, soft_wrap=True)
        console.print(f"      {figures}", highlight=False, markup=False)


def _print_table(report: RecordReport, title: str) -> None:
    table = Table(title=title, title_justify="left", box=box.SIMPLE_HEAD)
    # Topic names and numbers never wrap; on a narrow terminal (80 columns when piped) the
    # type, last, folds.
    table.add_column("topic", no_wrap=True)
    for column in ("messages", "lost", "rate", "bytes"):
        table.add_column(column, justify="right", no_wrap=True)
    table.add_column("type", overflow="fold")
    for topic in report.topics:
        lost = f"[red]{topic.lost}[/]" if topic.lost else "0"
        table.add_row(
            topic.topic,
            str(topic.messages),
            lost,
            format_rate(topic.rate_hz, digits=1),
            _human_bytes(topic.bytes),
            topic.type,
        )
    table.add_section()
    table.add_row(
        "total", str(report.messages), str(report.lost), "", _human_bytes(report.bytes), ""
    )
    console.print(table)


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
        for note in notes:
            console.print(f"  {topic.topic}: {note}", highlight=False, markup=False)


def progress_line(progress: RecordProgress, *, subscribed: bool) -> str:
    """The status line while recording (waiting for topics, then counts)."""
    if not subscribed:
        return f"waiting for topics ({progress.topics} subscribed, {progress.elapsed_s:.0f} s)"
    lost = f", [red]{progress.lost} lost[/]" if progress.lost else ""
    if progress.before_clock:
        lost += f", {progress.before_clock} before the first /clock (not written)"
    return (
        f"recording {progress.topics} topics: {progress.messages} messages, "
        f"{_human_bytes(progress.bytes)}{lost} ({progress.elapsed_s:.0f} s)"
    )
