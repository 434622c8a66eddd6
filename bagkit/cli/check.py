"""``bagkit check``: whether bags keep a health contract (``--spec health.yaml``)."""

from __future__ import annotations

from pathlib import Path

import typer

from bagkit.cli.common import ReportFormat, console, handle_errors, print_json

HELP = """Check BAGS against a health contract (--spec health.yaml): topics required and
forbidden, their type, rate bounds over a sliding window, the longest gap, value bounds and
any condition over time that must never hold (docs/cli.md). For each assertion broken: where
(seconds from the bag's start) and commands that replay or cut it.

Exit status: 0 every bag healthy, 1 a contract broken (a required topic missing included),
2 bad input (a spec that does not parse, an unknown key or field: one error naming its line).

Example: bagkit check flight1 --spec health.yaml
"""


@handle_errors
def check(
    bags: list[Path] = typer.Argument(..., help="The bags to check.", metavar="BAGS..."),
    spec: Path = typer.Option(..., "--spec", help="The contract (YAML).", metavar="FILE"),
    output_format: ReportFormat = typer.Option(
        ReportFormat.TABLE, "--format", help="table or json (one object per bag in a list)."
    ),
) -> None:
    from bagkit.health import HealthSpec, check_bag

    contract = HealthSpec.load(spec)  # a bad spec is one error before any bag is read
    reports = [check_bag(bag, contract) for bag in bags]
    if output_format == ReportFormat.JSON:
        print_json([report.to_dict() for report in reports])
    else:
        for report in reports:
            _print(report)
    raise typer.Exit(max(report.exit_code for report in reports))


def _print(report: object) -> None:
    from bagkit.health import HealthReport

    assert isinstance(report, HealthReport)
    broken = [a for a in report.assertions if not a.passed]
    verdict = "[bold green]healthy[/]" if not broken else f"[bold red]{len(broken)} broken[/]"
    console.print(f"{report.bag}: {len(report.assertions)} assertions, {verdict}")
    for assertion in broken:
        where = ""
        if len(assertion.spans):
            start, end, _ = assertion.spans[0].tolist()
            where = (
                f" {len(assertion.spans)} times, first at "
                f"{(start - report.start_ns) / 1e9:.3f}-{(end - report.start_ns) / 1e9:.3f} s"
            )
        reason = f" ({assertion.reason})" if assertion.reason else ""
        console.print(
            f"  FAIL {assertion.topic}: {assertion.what}{reason}{where}",
            highlight=False,
            soft_wrap=True,
        )
        for command in assertion.commands(report.bag, report.start_ns):
            console.print(f"    {command}", highlight=False, soft_wrap=True)
