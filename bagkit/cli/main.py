"""The ``bagkit`` command: one typer sub-app or command per module in this package.

Command modules are imported when their command runs, not before: ``bagkit --help`` and
``bagkit info BAG`` would otherwise pay for numpy, pandas, dask and rclpy-adjacent imports
that only other commands use. The list below carries each command's one-line help, so the
top-level help is printed without importing any of them.
"""

# Annotations are objects here, not strings (no `from __future__ import annotations`): typer
# reads the callbacks' parameters at every start and compiles each annotation written as a
# string, twice.

import importlib
from typing import Any, NamedTuple

import typer
from typer.core import TyperCommand, TyperGroup

from bagkit.cli.common import CONTEXT_SETTINGS, ClickCommand, ClickContext, run_app
from bagkit.cli.help_text import reflow_command_help
from bagkit.cli.plain_params import use_plain_coercion, use_plain_params
from bagkit.version import __version__


# A NamedTuple, not a dataclass: this table is made at every start, --help and info included.
class _Lazy(NamedTuple):
    """A command whose module is imported on first use.

    ``attribute`` is a command function (with ``HELP`` beside it in its module) or a
    ``typer.Typer``: named, it is a command group; unnamed, its command ``name`` is taken.
    """

    module: str
    attribute: str
    summary: str


# Command groups register themselves here, one module each (bagkit/cli/<group>.py).
_COMMANDS = {
    "catalog": _Lazy("bagkit.cli.catalog", "app", "A Parquet catalogue of many bags."),
    "check": _Lazy("bagkit.cli.check", "check", "Check bags against a health contract."),
    "compare": _Lazy("bagkit.cli.compare", "compare", "Compare a candidate bag to a golden."),
    "control": _Lazy(
        "bagkit.cli.control", "control", "Control a running recorder or player (pause, rate)."
    ),
    "convert": _Lazy(
        "bagkit.cli.convert", "convert", "Convert bags to a rosbag2 MCAP or SQLite3 bag."
    ),
    "doctor": _Lazy("bagkit.cli.doctor", "doctor", "Check a bag for problems (like mcap doctor)."),
    "echo": _Lazy("bagkit.cli.echo", "echo", "Print the messages of a topic."),
    "export": _Lazy("bagkit.cli.export", "export", "Write topics to Parquet or CSV files."),
    "filter": _Lazy("bagkit.cli.filter", "filter_command", "Copy a selection of a bag."),
    "find": _Lazy("bagkit.cli.find", "find", "Find the episodes where a condition holds."),
    "golden": _Lazy("bagkit.cli.golden", "app", "Golden-bag regression checks."),
    "info": _Lazy("bagkit.cli.info", "info", "Show what a bag holds (like ros2 bag info)."),
    "merge": _Lazy("bagkit.cli.merge", "merge", "Merge bags into one, in log-time order."),
    "migrate": _Lazy(
        "bagkit.cli.migrate", "migrate", "Rewrite a bag to other message definitions."
    ),
    "play": _Lazy("bagkit.cli.replay", "app", "The same command as replay (ros2 bag's name)."),
    "plot": _Lazy("bagkit.cli.plot", "plot", "Plot fields of a bag over time."),
    "record": _Lazy("bagkit.cli.record", "record", "Record topics into an MCAP bag."),
    "recover": _Lazy("bagkit.cli.recover", "recover", "Rewrite a crashed or cut bag whole."),
    "reindex": _Lazy("bagkit.cli.recover", "recover", "The same command as recover."),
    "replay": _Lazy("bagkit.cli.replay", "app", "Publish a bag's messages on their topics."),
    "stats": _Lazy("bagkit.cli.stats", "app", "Statistics of the numeric fields of bags."),
}


def load_command(name: str) -> ClickCommand | None:
    """Import command ``name``'s module and build its click command (None if unknown)."""
    lazy = _COMMANDS.get(name)
    if lazy is None:
        return None
    module = importlib.import_module(lazy.module)
    target: Any = getattr(module, lazy.attribute)
    holder = typer.Typer(add_completion=False, context_settings=CONTEXT_SETTINGS)
    if isinstance(target, typer.Typer):
        # A named app is a command group; an unnamed one's commands sit at the top level
        # (replay and its alias). Added under a holder as `bagkit` would add it, so that a
        # group of one command stays a group.
        holder.add_typer(target)
    else:
        # COMMAND_CLASS: a command's own parsing, e.g. options that take several values.
        cls = getattr(module, "COMMAND_CLASS", None)
        holder.command(name, help=module.HELP, no_args_is_help=True, cls=cls)(target)
    # With a second command beside it the holder is always a group.
    holder.command("_", hidden=True)(lambda: None)
    group = typer.main.get_command(holder)
    assert isinstance(group, TyperGroup)
    command = group.commands.get(name)
    if command is not None:
        use_plain_coercion(command)
        reflow_command_help(command)
    return command


class _LazyGroup(TyperGroup):
    """The top-level group: commands from :data:`_COMMANDS`, imported when they run."""

    def parse_args(self, ctx: ClickContext, args: list[str]) -> list[str]:
        # Loaded commands get plain coercion in load_command; this is the top level's.
        use_plain_params(self.get_params(ctx))
        return super().parse_args(ctx, args)

    def list_commands(self, ctx: ClickContext) -> list[str]:
        return sorted({*self.commands, *_COMMANDS})

    def get_command(self, ctx: ClickContext, cmd_name: str) -> ClickCommand | None:
        if cmd_name in self.commands:
            return self.commands[cmd_name]
        if getattr(ctx, "_listing_help", False):
            lazy = _COMMANDS.get(cmd_name)
            return TyperCommand(name=cmd_name, help=lazy.summary) if lazy else None
        command = load_command(cmd_name)
        if command is not None:
            self.commands[cmd_name] = command
        return command

    def format_help(self, ctx: ClickContext, formatter: Any) -> None:
        # Listing the commands needs only their one-line help, not their modules.
        ctx._listing_help = True
        try:
            super().format_help(ctx, formatter)
        finally:
            ctx._listing_help = False


app = typer.Typer(
    name="bagkit",
    cls=_LazyGroup,
    help="Record, replay, inspect and compare ROS 2 MCAP bags. bagkit COMMAND -h gives a "
    "command's options.\n\nExample:\n\n  bagkit info my_bag",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    rich_markup_mode=None,
    context_settings=CONTEXT_SETTINGS,
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


def run() -> None:
    """Console entry point of ``bagkit``."""
    run_app(app)
