"""``bagkit golden``: check, accept and re-record the golden fixtures (fixtures/<name>/)."""

from __future__ import annotations

import tempfile
from pathlib import Path

import typer

from bagkit.cli.common import console, err_console, fail, handle_errors
from bagkit.regression.spec import FixtureSpec, find_fixtures, load_spec

app = typer.Typer(
    name="golden",
    help="Golden-bag regression: check fixtures in lockstep or live, accept changes, re-record.",
    no_args_is_help=True,
)

FIXTURES_ARG = typer.Argument(
    None,
    help="Fixture directories (holding spec.yaml); default: every fixture under ./fixtures.",
    show_default=False,
)


def _specs(fixtures: list[Path] | None) -> list[FixtureSpec]:
    if fixtures:
        return [load_spec(path) for path in fixtures]
    found = find_fixtures(Path("fixtures"))
    if not found:
        raise fail("no fixtures given and none under ./fixtures")
    return found


@app.command()
@handle_errors
def check(
    fixtures: list[Path] | None = FIXTURES_ARG,
    *,
    live: bool = typer.Option(
        False, "--live", help="Replay through the nodes over DDS (use_sim_time) instead."
    ),
    failures: Path = typer.Option(
        Path("golden_failures"), help="Where a failing fixture's report.json and plots go."
    ),
) -> None:
    """Run each fixture's inputs through today's code and compare with its expected outputs.

    Exit status 0 when every fixture matches, 1 when one differs (its report and plots are in
    FAILURES/<fixture>-<mode>/), 2 for unusable input.
    """
    from bagkit.regression.golden import check_lockstep, write_failure_artefacts
    from bagkit.regression.live import check_live

    failed = []
    for spec in _specs(fixtures):
        with tempfile.TemporaryDirectory(prefix="bagkit-golden-") as tmp:
            with err_console.status(f"{spec.name}: {'live' if live else 'lockstep'} ..."):
                result = check_live(spec, Path(tmp)) if live else check_lockstep(spec, Path(tmp))
            speed = ""
            if result.lockstep is not None:
                speed = f" ({result.lockstep.speedup:.0f}x real time)"
            console.print(result.summary(), highlight=False, markup=False)
            if speed:
                console.print(f"  lockstep{speed}", highlight=False)
            if not result.passed:
                folder = failures / f"{spec.name}-{result.mode}"
                write_failure_artefacts(result, folder)
                console.print(f"  report and plots: {folder}", highlight=False)
                failed.append(spec.name)
    if failed:
        raise typer.Exit(1)


@app.command()
@handle_errors
def update(fixtures: list[Path] | None = FIXTURES_ARG) -> None:
    """Accept today's behaviour: rewrite each fixture's expected outputs from lockstep."""
    from bagkit.regression.golden import update_golden

    for spec in _specs(fixtures):
        result = update_golden(spec)
        counts = ", ".join(f"{t} {n}" for t, n in sorted(result.output_counts.items()))
        console.print(f"{spec.name}: outputs rewritten ({counts})", highlight=False)


@app.command()
@handle_errors
def record(fixtures: list[Path] | None = FIXTURES_ARG) -> None:
    """Re-record fixtures from the live system, then rewrite their outputs from lockstep.

    For each fixture, `fusion launch` runs the sensor publisher with the spec's scenario and the
    nodes under test while `bagkit record` records inputs, outputs and /sim/truth for the spec's
    duration; the expected outputs are then computed from the recorded inputs by lockstep.
    Run it with ROS_DOMAIN_ID set to a domain of your own.
    """
    from bagkit.regression.live import record_fixture

    for spec in _specs(fixtures):
        with tempfile.TemporaryDirectory(prefix="bagkit-golden-") as tmp:
            result = record_fixture(spec, Path(tmp), log=err_console.print)
        size = sum(f.stat().st_size for f in spec.bag.iterdir())
        counts = ", ".join(f"{t} {n}" for t, n in sorted(result.output_counts.items()))
        console.print(
            f"{spec.name}: {spec.bag} {size / 1e6:.2f} MB, {result.input_messages} inputs; "
            f"outputs: {counts}",
            highlight=False,
        )
