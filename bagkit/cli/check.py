"""``bagkit check``: whether bags keep a health contract (``--spec health.yaml``), or a
starting contract from a good bag (``--suggest``)."""

# Annotations are objects here, not strings (no `from __future__ import annotations`): typer
# reads the command's parameters at every start and compiles each annotation written as a
# string, twice.

from pathlib import Path
from typing import TYPE_CHECKING

import typer

from bagkit.cli import common
from bagkit.cli.common import ReportFormat, handle_errors, print_json, warn
from bagkit.cli.fleet_options import BAGS_HELP, Scheduler, Workers, end_with_unread, fleet_run
from bagkit.cli.option_parsing import bag_location
from bagkit.cli.selection_options import End, Start, build_query
from bagkit.cli.tables import Styled, print_command, print_line
from bagkit.words import counted

if TYPE_CHECKING:
    from bagkit.health import CheckResult, HealthReport

HELP = """Check BAGS against a health contract (--spec health.yaml): topics required and
forbidden, their type, rate bounds over a sliding window, the longest gap, value bounds and
any condition over time that must never hold (docs/health.md). For each assertion broken:
where (seconds from the bag's start), commands that replay or cut it, and a Foxglove link
where bags are served (--bags-url or $BAGKIT_BAGS_URL). Several bags run on a local Dask
cluster (--workers, or --scheduler); a bag that cannot be read is reported among the others.

--suggest prints a starting contract from one good bag (observed topics, types, rates, gaps,
value ranges with margins, no NaN where none was seen), to edit. --topics checks only the
contracts of those topics, --start/--end only the messages of that window (each bag's own:
10 is ten seconds after its first message).

Exit status: 0 every bag healthy, 1 a contract broken (a required topic missing included),
2 bad input (a spec that does not parse, an unknown key or field: one error naming its line;
a bag that cannot be read).

Examples:

  bagkit check flight1 --suggest > health.yaml

  bagkit check flights/ --spec health.yaml --junit check.xml

  bagkit check flight1 --spec health.yaml --html check.html

  bagkit check flight1 --spec health.yaml -t /imu/data --start 10
"""


@handle_errors
def check(  # noqa: PLR0917 (typer maps parameters to options)
    inputs: list[Path] = typer.Argument(
        ..., help=BAGS_HELP + ".", metavar="BAGS...", show_default=False, parser=bag_location
    ),
    spec: Path | None = typer.Option(None, "--spec", help="The contract (YAML).", metavar="FILE"),
    topics: list[str] | None = typer.Option(
        None,
        "--topics",
        "-t",
        help="Check only the contracts of these topics (repeat, or a comma list).",
        metavar="TOPICS",
    ),
    start: Start = None,
    end: End = None,
    suggest: bool = typer.Option(
        False,
        "--suggest",
        help="Print a starting contract from one good bag (YAML; --format json: JSON).",
    ),
    output_format: ReportFormat = typer.Option(
        ReportFormat.TABLE, "--format", help="table or json (one object per bag in a list)."
    ),
    junit: Path | None = typer.Option(
        None, "--junit", help="Also write JUnit XML (one test per assertion).", metavar="FILE"
    ),
    html: Path | None = typer.Option(
        None, "--html", help="Also write an HTML report (a plot per failure).", metavar="FILE"
    ),
    bags_url: str | None = typer.Option(
        None,
        "--bags-url",
        help="Where the bags are served over HTTP(S), for Foxglove links (default: "
        "$BAGKIT_BAGS_URL).",
        metavar="URL",
    ),
    workers: Workers = None,
    scheduler: Scheduler = None,
) -> None:
    from bagkit.fleet import expand_bags
    from bagkit.fleet.cluster import CHECK_RATE
    from bagkit.health import HealthSpec, SpecError, check_bags
    from bagkit.health.check import restrict

    query = build_query(topics, start=start, end=end)  # a bad time: one error, first
    if suggest:
        from bagkit.health.suggest import suggest_spec, suggested_contract

        if spec is not None or len(inputs) != 1 or query.topics or query.span.bounded:
            raise SpecError("--suggest takes one bag and no --spec, --topics, --start or --end")
        if output_format is ReportFormat.JSON:
            print_json(suggested_contract(inputs[0]))
        else:
            common.console.print(suggest_spec(inputs[0]), end="", highlight=False, soft_wrap=True)
        return
    if spec is None:
        raise SpecError("give the contract: --spec health.yaml (or --suggest to write one)")
    contract = HealthSpec.load(spec)  # a bad spec is one error before any bag is read
    restrict(contract, query)  # as a topic the contract lacks
    bags = expand_bags(inputs)
    with fleet_run(
        bags, workers=workers, scheduler=scheduler, label="checking", rate=CHECK_RATE
    ) as (client, done):
        result = check_bags(
            bags, contract, client=client, done=done, bags_url=bags_url, query=query
        )
    _write_files(result, junit, html)
    for report in result.reports:
        for problem in report.problems:
            warn(problem if problem.startswith(report.bag) else f"{report.bag}: {problem}")
    if output_format == ReportFormat.JSON:
        print_json(result.to_list())
    else:
        for report in result.reports:
            _print(report)
    unread = sum(report.error is not None for report in result.reports)
    end_with_unread(unread, len(result.reports))  # each is in the report (docs/fleet.md)
    raise typer.Exit(result.exit_code)


def _write_files(result: "CheckResult", junit: Path | None, html: Path | None) -> None:
    if junit is not None:
        from bagkit.health.junit import write_junit

        write_junit(result.reports, junit)
    if html is not None:
        from bagkit.health.report_html import write_report

        write_report(result, html)


def _print(report: "HealthReport") -> None:
    # print_line: plain text into a pipe without importing rich, colours on a terminal.
    if report.error is not None:
        why = report.error.removeprefix(f"{report.bag}: ")  # the bag named once
        print_line([f"{report.bag}: ", Styled("not read", "bold red"), f": {why}"])
        return
    broken = report.broken
    verdict = (
        Styled("healthy", "bold green")
        if not broken
        else Styled(f"{len(broken)} broken", "bold red")
    )
    count = len(report.assertions)
    print_line([f"{report.bag}: {counted(count, 'assertion')}, ", verdict])
    lead = " " * 7
    for assertion in broken:
        # The assertion and where it broke fit 80 columns, a command goes on over lines; a
        # link stays whole.
        print_line([f"  FAIL {assertion.headline}"])
        if where := assertion.where(report.start_ns):
            print_line([lead + where])
        for command in assertion.commands(report.bag, report.start_ns):
            print_command(command, lead=lead)
        if link := report.link(assertion):
            print_line([lead + link])
