"""The ``bagkit`` command: one typer sub-app or command per module in this package."""

from __future__ import annotations

import typer

from bagkit import __version__
from bagkit.cli import catalog as _catalog
from bagkit.cli import compare as _compare
from bagkit.cli import doctor as _doctor
from bagkit.cli import echo as _echo
from bagkit.cli import export as _export
from bagkit.cli import filter as _filter
from bagkit.cli import golden as _golden
from bagkit.cli import info as _info
from bagkit.cli import merge as _merge
from bagkit.cli import plot as _plot
from bagkit.cli import record as _record
from bagkit.cli import recover as _recover
from bagkit.cli import replay as _replay
from bagkit.cli import stats as _stats
from bagkit.cli.common import run_app

app = typer.Typer(
    name="bagkit",
    help="Record, replay, inspect and compare ROS 2 MCAP bags.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)


def _version_callback(value: bool) -> None:
    if value:
        typer.echo(f"bagkit {__version__}")
        raise typer.Exit()


@app.callback()
def main(
    version: bool = typer.Option(
        False, "--version", callback=_version_callback, is_eager=True, help="Print the version."
    ),
) -> None:
    """Record, replay, inspect and compare ROS 2 MCAP bags."""


# Command groups register themselves here, one module each (bagkit/cli/<group>.py).
app.command("compare", help=_compare.HELP, no_args_is_help=True)(_compare.compare)
app.command("echo", help=_echo.HELP, no_args_is_help=True)(_echo.echo)
app.command("export", help=_export.HELP, no_args_is_help=True)(_export.export)
app.command("info", help=_info.HELP, no_args_is_help=True)(_info.info)
app.command("plot", help=_plot.HELP, no_args_is_help=True)(_plot.plot)
app.command("record", help=_record.HELP, no_args_is_help=True)(_record.record)
app.add_typer(_replay.app)
# Bag surgery (bagkit/surgery): one module each.
app.command("doctor", help=_doctor.HELP, no_args_is_help=True)(_doctor.doctor)
app.command("recover", help=_recover.HELP, no_args_is_help=True)(_recover.recover)
app.command("reindex", help=_recover.HELP, no_args_is_help=True)(_recover.recover)
app.command("filter", help=_filter.HELP, no_args_is_help=True)(_filter.filter_command)
app.command("merge", help=_merge.HELP, no_args_is_help=True)(_merge.merge)
# `ros2 bag play`'s name for the same command.
app.command(
    "play",
    cls=_replay.ReplayCommand,
    help=_replay.HELP,
    no_args_is_help=True,
    context_settings=_replay.HELP_OPTIONS,
)(_replay.replay)
app.add_typer(_stats.app)
app.add_typer(_golden.app)
app.add_typer(_catalog.app)


def run() -> None:
    """Console entry point of ``bagkit``."""
    run_app(app)
