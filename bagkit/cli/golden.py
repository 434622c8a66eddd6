"""``bagkit golden``: check, accept and re-record the golden fixtures (fixtures/<name>/)."""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING

import typer

from bagkit.cli.common import (
    ReportFormat,
    console,
    err_console,
    fail,
    handle_errors,
    note,
    option_flags,
    print_json,
    warn,
)
from bagkit.cli.fleet_options import Scheduler, Workers
from bagkit.cli.option_parsing import bag_location
from bagkit.cli.selection_options import End, Start, build_query
from bagkit.regression.spec import FixtureSpec, find_fixtures, load_spec
from bagkit.words import counted

if TYPE_CHECKING:
    from bagkit.regression.batch import FixtureOutcome

app = typer.Typer(
    name="golden",
    help="Golden-bag regression: check fixtures in lockstep or live, accept changes, re-record.",
    no_args_is_help=True,
    context_settings={"help_option_names": ["-h", "--help"]},
)

FIXTURES_ARG = typer.Argument(
    None,
    help="Fixture directories (holding spec.yaml); default: every fixture under ./fixtures.",
    show_default=False,
)


CHECKED_FIXTURES_ARG = typer.Argument(
    None,
    help="Fixture directories (holding spec.yaml), or their prefixes in storage (s3://...); "
    "default: every fixture under ./fixtures.",
    show_default=False,
    parser=bag_location,
)


def _specs(fixtures: list[Path] | None) -> list[FixtureSpec]:
    # Processor factories import from the current directory too, as under `python -m`.
    if "" not in sys.path and os.getcwd() not in sys.path:
        sys.path.insert(0, os.getcwd())
    if fixtures:
        return [load_spec(path) for path in fixtures]
    found = find_fixtures(Path("fixtures"))
    if not found:
        raise fail("no fixtures given and none under ./fixtures")
    return found


@app.command()
@handle_errors
def check(
    fixtures: list[Path] | None = CHECKED_FIXTURES_ARG,
    *,
    mode: str = typer.Option(
        "lockstep",
        "--mode",
        help="lockstep, live (replay through the nodes over DDS), or all (the spec's modes).",
    ),
    live: bool = typer.Option(False, "--live", help="Shorthand for --mode live."),
    failures: Path = typer.Option(
        Path("golden_failures"), help="Where a failing fixture's report.json/.html and plots go."
    ),
    workers: Workers = None,
    scheduler: Scheduler = None,
    output_format: ReportFormat = typer.Option(
        ReportFormat.TABLE,
        "--format",
        help="table or json (one object per fixture and mode in a list).",
    ),
) -> None:
    """Run each fixture's inputs through today's code and compare with its expected outputs.

    Exit status 0 when every fixture matches, 1 when one differs (its report is in
    FAILURES/<fixture>-<mode>/report.html), 2 for unusable input. Several lockstep checks run
    on a local Dask cluster (or --scheduler); live checks run one after
    another in this process (they share DDS and the wall clock). --format json prints a
    list of one object per fixture and mode: fixture, mode, passed, summary, speedup (lockstep),
    report (when it failed) and error (when its bags could not be read). A fixture is checked
    only in the modes its spec lists (modes:); one --mode leaves out is a warning, an error
    when none is left to check.

    Example:

      bagkit golden check fixtures/takeoff --mode all
    """
    from bagkit.storage.transfer import local_folders

    mode = "live" if live else mode
    if mode not in {"lockstep", "live", "all"}:
        raise fail(f"--mode must be lockstep, live or all, not {mode!r}")
    # Fixtures in storage are copied whole into a temporary folder (spec, inputs, golden).
    with local_folders(fixtures or []) as local:
        _check(
            local or None,
            mode=mode,
            failures=failures,
            workers=workers,
            scheduler=scheduler,
            output_format=output_format,
        )


def _check(
    fixtures: list[Path] | None,
    *,
    mode: str,
    failures: Path,
    workers: int | None,
    scheduler: str | None,
    output_format: ReportFormat,
) -> None:
    """Check ``fixtures`` (local folders; None: every one under ./fixtures) and print."""
    from bagkit.cli.fleet_options import end_with_unread, fleet_run
    from bagkit.errors import not_read
    from bagkit.fleet.cluster import LOCKSTEP_RATE
    from bagkit.regression.batch import check_fixtures

    specs = _specs(fixtures)
    jobs = [(spec, each) for spec in specs for each in spec.modes if mode in {"all", each}]
    # A spec's modes are the checks it is held to (a fixture kept to lockstep may not keep up
    # live under load): one not listed is left out, as the pytest plugin leaves it out.
    left_out = [spec for spec in specs if mode not in {"all", *spec.modes}]
    if left_out and not jobs:
        raise fail(_not_checked(left_out, mode))
    if left_out:
        warn(_not_checked(left_out, mode))
    bags = [spec.bag for spec, each in jobs if each == "lockstep"]
    with fleet_run(
        bags, workers=workers, scheduler=scheduler, label="checking", rate=LOCKSTEP_RATE
    ) as (client, done):
        outcomes = check_fixtures(
            jobs,
            failures,
            client=client,
            done=done,
            before_live=lambda job: note(f"{job[0].name}: live ..."),
        )
    for outcome in outcomes:
        if outcome.error is not None:
            warn(not_read(f"{outcome.fixture} ({outcome.mode})", outcome.error))
    if output_format is ReportFormat.JSON:
        print_json([outcome.to_dict() for outcome in outcomes])
    else:
        for outcome in outcomes:
            if outcome.error is None:
                _print(outcome)
    unread = {outcome.fixture for outcome in outcomes if outcome.error is not None}
    end_with_unread(len(unread), len({outcome.fixture for outcome in outcomes}), "fixtures")
    if not all(outcome.passed for outcome in outcomes):
        raise typer.Exit(1)


def _not_checked(specs: list[FixtureSpec], mode: str) -> str:
    """``fast: its spec's modes are lockstep only, so it is not checked live``."""
    return "; ".join(
        f"{spec.name}: its spec's modes are {' and '.join(spec.modes)} only, "
        f"so it is not checked {mode}"
        for spec in specs
    )


def _print(outcome: FixtureOutcome) -> None:
    console.print(outcome.summary, highlight=False, markup=False, soft_wrap=True)
    if outcome.speedup is not None:
        console.print(f"  lockstep ({outcome.speedup:.0f}x real time)", highlight=False)
    if outcome.report is not None:
        console.print(f"  report: {outcome.report}", highlight=False, soft_wrap=True)


@app.command()
@handle_errors
def update(fixtures: list[Path] | None = FIXTURES_ARG) -> None:
    """Accept today's behaviour: rewrite each fixture's expected outputs from lockstep.

    Outputs within the spec's lockstep tolerance of the golden's are kept: accepting unchanged
    behaviour rewrites no file.

    Example:

      bagkit golden update fixtures/takeoff && git diff --stat fixtures/
    """
    from bagkit.regression.golden import update_golden

    for spec in _specs(fixtures):
        update = update_golden(spec)
        counts = ", ".join(f"{t} {n}" for t, n in sorted(update.lockstep.output_counts.items()))
        verdict = "outputs rewritten" if update.rewritten else "unchanged, nothing rewritten"
        console.print(f"{spec.name}: {verdict} ({counts})", highlight=False)


@app.command("migrate")
@handle_errors
def migrate(
    fixtures: list[Path] | None = FIXTURES_ARG,
    *,
    rules: Path | None = typer.Option(
        None, "--rules", help="A rules file, as bagkit migrate takes.", metavar="FILE"
    ),
    allow_drop: bool = typer.Option(
        False, "--allow-drop", help="Drop the values of fields that no rule carries over."
    ),
    failures: Path = typer.Option(
        Path("golden_failures"), help="Where a failing check's report.json/.html goes."
    ),
) -> None:
    """Rewrite each fixture's golden to the installed message definitions, then check it.

    The golden is migrated as bagkit migrate does (same-named fields copied, new ones at
    their defaults, --rules for the rest) and replaced only when that succeeded; then its
    lockstep check runs. Exit status 0 when every check passes, 1 when one fails, 2 when a
    golden cannot be migrated (it is left as it was).

    Example:

      bagkit golden migrate fixtures/pack --rules battery_v2.yaml
    """
    from bagkit.migrate import Rules, load_rules
    from bagkit.regression.artefacts import write_failure_artefacts
    from bagkit.regression.migrate_golden import migrate_golden
    from bagkit.surgery.migrate import MigrateOptions

    options = MigrateOptions(
        rules=load_rules(rules) if rules is not None else Rules(),
        rules_file=str(rules or ""),
        allow_drop=allow_drop,
    )
    passed = True
    for spec in _specs(fixtures):
        with tempfile.TemporaryDirectory(prefix="bagkit-golden-") as tmp:
            done = migrate_golden(spec, options, Path(tmp))
            if done.check is not None and not done.check.passed:
                write_failure_artefacts(done.check, failures / f"{spec.name}-lockstep")
        for topic in done.migration.migrated:
            changes = "; ".join(topic.changes)
            console.print(
                f"{spec.name}: {topic.topic.name} migrated "
                f"({counted(topic.migrated, 'message')}: {changes})",
                highlight=False,
                soft_wrap=True,
            )
        if not done.migration.migrated:
            console.print(f"{spec.name}: golden already matches the installed definitions")
        if done.check is not None:
            console.print(done.check.summary(), highlight=False, markup=False, soft_wrap=True)
            passed = passed and done.check.passed
    if not passed:
        raise typer.Exit(1)


@app.command()
@handle_errors
def record(fixtures: list[Path] | None = FIXTURES_ARG) -> None:
    """Record fixtures' goldens from the live system named by the spec's record_launch.

    For each fixture, the spec's record_launch commands run the whole system on the wall clock
    while `bagkit record` records inputs, outputs and record_topics for the spec's duration;
    with a processor factory, the expected outputs are then computed from the recorded inputs
    by lockstep. Run it with ROS_DOMAIN_ID set to a domain of your own.

    Example:

      bagkit golden record fixtures/takeoff
    """
    from bagkit.regression.live import record_golden

    for spec in _specs(fixtures):
        with tempfile.TemporaryDirectory(prefix="bagkit-golden-") as tmp:
            counts = record_golden(spec, Path(tmp), log=err_console.print)
        size = sum(f.stat().st_size for f in spec.bag.iterdir())
        listed = ", ".join(f"{t} {n}" for t, n in sorted(counts.items()))
        console.print(f"{spec.name}: {spec.bag} {size / 1e6:.2f} MB; {listed}", highlight=False)


@app.command("add", no_args_is_help=True)
@handle_errors
def add(  # noqa: PLR0917 (typer maps parameters to options)
    fixture: Path = typer.Argument(
        ..., help="The new fixture folder, e.g. fixtures/gps_outage.", show_default=False
    ),
    bag: Path = typer.Option(..., "--from", help="The recording to cut.", metavar="BAG"),
    start: Start = None,
    end: End = None,
    around: str | None = typer.Option(
        None,
        "--around",
        help="'TOPIC: CONDITION': the window of one of its episodes (instead of --start/--end).",
        metavar="TRIGGER",
    ),
    before: str = typer.Option("0", "--before", help="With --around: this long before it."),
    after: str = typer.Option("0", "--after", help="With --around: this long after it."),
    episode: int = typer.Option(
        1, "--episode", help="With --around: which episode, 1 = the first (as find lists them)."
    ),
    gap: str = typer.Option(
        "0", "--gap", help="With --around: matches closer than this merge into one episode."
    ),
    like: Path | None = typer.Option(
        None,
        "--like",
        help="A fixture whose spec.yaml to copy (its processor makes the expected outputs).",
        metavar="FIXTURE",
    ),
) -> None:
    """Make a fixture from a window of a recording: FIXTURE/golden and FIXTURE/spec.yaml.

    The window (--start/--end, or --around 'TOPIC: CONDITION' --before SEC --after SEC: around
    its first episode, or the --episode N that find lists; with the latched state from before
    it) is cut from BAG. With
    --like, the spec is copied and the window's inputs run through its processor in lockstep,
    the system starting at the window's start: the golden holds the inputs and those outputs,
    and pytest runs the fixture at once. Without it, the golden is the window as recorded and
    spec.yaml a commented template naming its topics.

    Example:

      bagkit golden add fixtures/gps_outage --from flight1 \\
        --around '/alerts: status[*].level >= 2' --before 5 --after 5 \\
        --like fixtures/faults
    """
    from bagkit.cli.surgery_options import AROUND_FLAGS
    from bagkit.regression.add import AddOptions, add_fixture
    from bagkit.selection.times import parse_duration

    if "" not in sys.path and os.getcwd() not in sys.path:  # as _specs: factories from here
        sys.path.insert(0, os.getcwd())
    options = AddOptions(
        bag,
        build_query(start=start, end=end).span,
        like,
        around,
        before_ns=parse_duration(before, "--before"),
        after_ns=parse_duration(after, "--after"),
        gap_ns=parse_duration(gap, "--gap"),
        episode=episode,
    )
    with option_flags({**AROUND_FLAGS, "like": "--like needs a spec with a processor: {}"}):
        added = add_fixture(fixture, options)
    if added.episodes > 1:
        note(
            f"{counted(added.episodes, 'episode')} of {around!r}: episode {episode} made the "
            "fixture (--episode N for another)"
        )
    listed = ", ".join(f"{t} {n}" for t, n in added.counts.items())
    if added.lockstep is not None:
        made = ", ".join(f"{t} {n}" for t, n in sorted(added.lockstep.output_counts.items()))
        listed += f"; outputs from lockstep: {made}"
    console.print(f"{fixture}: {fixture / 'golden'}; {listed}", highlight=False, soft_wrap=True)
    if added.spec is None:
        note(f"edit {fixture / 'spec.yaml'}: name the system under test and its outputs")
