"""``bagkit compare``: a candidate bag against a golden one, within tolerances."""

from __future__ import annotations

import json
from pathlib import Path

import typer

from bagkit.cli.common import (
    CheckCrcOnRead,
    ReportFormat,
    console,
    handle_errors,
    print_json,
    status,
    warn,
)
from bagkit.cli.compare_options import (
    Atol,
    Candidate,
    EventWindow,
    Format,
    Golden,
    IgnoreFields,
    IncludeTimes,
    Live,
    MatchWindow,
    PassRate,
    Report,
    Rtol,
    Show,
    Skip,
    Spec,
    Topics,
)
from bagkit.cli.option_parsing import split_list
from bagkit.cli.selection_options import Distro
from bagkit.cli.tables import INDENT, Column, Styled, Table, print_table, print_wrapped
from bagkit.compare import (
    CompareOptions,
    CompareReport,
    Tolerance,
    compare_bags,
    replace_options,
)
from bagkit.words import counted

HELP = (
    "Compare CANDIDATE with GOLDEN, topic by topic, field by field.\n\n"
    "Messages are matched by header stamp (by order where there is none). A float field passes "
    "when |a - b| <= max(atol, rtol * max(|a|, |b|)); integers (enums, levels), strings and "
    "booleans must be equal. Statuses on event topics (/alerts) are matched by (name, level) "
    "within --event-window seconds. Receive and publish times are ignored unless "
    "--include-times.\n\n"
    "Exit status: 0 identical within tolerance, 1 different, 2 unusable input."
)


def _print_table(report: CompareReport, limit: int) -> None:
    counts_columns = (Column(c, numeric=True) for c in ("golden", "cand.", "missing", "extra"))
    table = Table(
        [Column("topic"), Column("counting"), *counts_columns, Column("result")],
        title="golden vs candidate",
    )
    errors: list[str] = []
    for topic in report.topics:
        numeric = [f for f in topic.fields if f.numeric and f.compared]
        worst = max(numeric, key=lambda f: (not f.passed, f.max_abs_error), default=None)
        if topic.matched_by == "event":
            errors.append(
                f"{topic.topic}: events shifted by up to {topic.max_event_shift_ns / 1e9:.3f} s"
            )
        elif worst is not None:
            errors.append(
                f"{topic.topic}: {worst.path} |err| {worst.max_abs_error:.3g} "
                f"(rel {worst.max_rel_error:.3g}; atol {worst.atol:g} rtol {worst.rtol:g})"
            )
        if topic.absent:  # its divergences are its golden messages: why it fails is below
            verdict = Styled("absent", "red")
        elif not topic.passed:
            verdict = Styled(f"{topic.divergence_count} diff", "red")
        elif topic.failed_messages:
            verdict = Styled(f"ok ({counted(topic.failed_messages, 'msg')} out, allowed)", "green")
        else:
            verdict = Styled("ok", "green")
        counts = (topic.golden_count, topic.candidate_count, topic.missing, topic.extra)
        # What the counts count, and how: events count statuses, not messages.
        counting = {"stamp": "msgs by stamp", "order": "msgs in order", "event": "statuses"}
        how = counting.get(topic.matched_by, "type")
        table.add_row(topic.topic, how, *map(str, counts), verdict)
    print_table(table)
    if errors:
        console.print("largest errors:")
        for line in errors:
            print_wrapped(line.split(" "), lead=INDENT)
    divergences = report.first_divergences(limit)
    if divergences:
        console.print("first divergences:")
        for divergence in divergences:
            print_wrapped(divergence.describe().split(" "), lead=INDENT)
    if report.passed:
        console.print("[bold green]PASS[/]: identical within tolerance")
    else:
        for topic in report.topics:
            if topic.absent:
                console.print(f"{topic.topic}: {topic.absent}", highlight=False)
        failed = [t.topic for t in report.topics if not t.passed]
        console.print(f"[bold red]FAIL[/]: differences on {', '.join(failed)}")


@handle_errors
def compare(
    golden: Golden,
    candidate: Candidate,
    *,
    topics: Topics = None,
    atol: Atol = None,
    rtol: Rtol = None,
    ignore_fields: IgnoreFields = None,
    spec: Spec = None,
    live: Live = False,
    event_window: EventWindow = None,
    match_window: MatchWindow = None,
    skip: Skip = None,
    pass_rate: PassRate = None,
    include_times: IncludeTimes = False,
    report: Report = None,
    output_format: Format = ReportFormat.TABLE,
    show: Show = 10,
    check_crc: CheckCrcOnRead = True,
    distro: Distro = None,
) -> None:
    """Compare CANDIDATE with GOLDEN within tolerances (exit 0 same, 1 different, 2 bad input)."""
    base = _spec_options(spec, live)
    options = replace_options(
        base,
        topics=tuple(split_list(topics)) or None,
        tolerance=_tolerance(base.tolerance, atol, rtol),
        ignore_fields=base.ignore_fields + tuple(split_list(ignore_fields)),
        event_window_ns=_ns(event_window, "--event-window"),
        match_window_ns=_ns(match_window, "--match-window"),
        include_times=include_times or None,
        pass_rate=pass_rate,
        skip_ns=_ns(skip, "--skip"),
        max_divergences=show,
    )
    with status("comparing ...") as shown:
        result = compare_bags(
            golden,
            candidate,
            options,
            progress=None if shown is None else lambda t: shown.update(f"comparing {t}"),
            check_crc=check_crc,
        )
    for warning in result.warnings:
        warn(warning)
    if report is not None:
        report.write_text(json.dumps(result.to_dict(), indent=2) + "\n")
    if output_format is ReportFormat.JSON:
        print_json(result.to_dict())
    else:
        _print_table(result, show)
        if report is not None:
            console.print(f"report: {report}", highlight=False)
    raise typer.Exit(result.exit_code)


def _spec_options(spec: Path | None, live: bool) -> CompareOptions:
    """The options of the spec's lockstep (or live) comparison; the defaults without a spec."""
    if spec is None:
        return CompareOptions()
    from bagkit.regression.spec import load_spec

    return load_spec(spec).compare_options("live" if live else "lockstep")


def _tolerance(base: Tolerance, atol: float | None, rtol: float | None) -> Tolerance | None:
    """``--atol``/``--rtol`` over the base tolerance; None when neither is given."""
    if atol is None and rtol is None:
        return None
    return Tolerance(base.atol if atol is None else atol, base.rtol if rtol is None else rtol)


def _ns(duration: str | None, option: str) -> int | None:
    from bagkit.selection.times import parse_duration

    return None if duration is None else parse_duration(duration, option)
