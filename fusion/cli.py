"""The ``fusion`` command: run the live system, all nodes or one."""

from __future__ import annotations

import sys
from pathlib import Path

import typer

from bagkit.cli.common import fail, handle_errors
from fusion.launch import Launcher
from fusion.processors import NODE_NAMES

app = typer.Typer(
    name="fusion",
    help="The live fusion system: a simulated sensor suite and its ROS 2 pipeline.",
    add_completion=False,
    pretty_exceptions_enable=False,
)

_NODES_HELP = f"Nodes: {', '.join(NODE_NAMES)}."


def _check_nodes(names: list[str]) -> None:
    unknown = [n for n in names if n not in NODE_NAMES]
    if unknown:
        raise fail(f"unknown node(s) {', '.join(unknown)}. {_NODES_HELP}")


@app.command(help=f"Start the nodes, each in its own process, until Ctrl-C. {_NODES_HELP}")
@handle_errors
def launch(
    only: str = typer.Option(
        "", "--only", metavar="NODE,...", help="Comma-separated nodes to start (default: all)."
    ),
    params: Path | None = typer.Option(
        None,
        "--params",
        exists=True,
        dir_okay=False,
        help="ROS 2 parameter file overriding the packaged defaults.",
    ),
    use_sim_time: bool = typer.Option(
        False, "--use-sim-time", help="Run every node on /clock (use_sim_time:=true)."
    ),
) -> None:
    names = [n.strip() for n in only.split(",") if n.strip()] or list(NODE_NAMES)
    _check_nodes(names)
    code = Launcher(names, params_file=params, use_sim_time=use_sim_time).run()
    raise typer.Exit(code)


@app.command(
    help=f"Run one node in this process; extra arguments go to ROS (--ros-args ...). {_NODES_HELP}",
    context_settings={"allow_extra_args": True, "ignore_unknown_options": True},
)
@handle_errors
def run(
    ctx: typer.Context,
    node: str = typer.Argument(..., help="The node to run."),
    params: Path | None = typer.Option(
        None, "--params", exists=True, dir_okay=False, help="ROS 2 parameter file."
    ),
    use_sim_time: bool = typer.Option(False, "--use-sim-time", help="use_sim_time:=true."),
) -> None:
    _check_nodes([node])
    from fusion.nodes.shell import run_node

    ros_args = list(ctx.args)
    extra = []
    if params is not None:
        extra += ["--params-file", str(params)]
    if use_sim_time:
        extra += ["-p", "use_sim_time:=true"]
    if extra:
        ros_args += ["--ros-args", *extra]
    raise typer.Exit(run_node(node, ros_args))


def main() -> None:
    """Entry point of the ``fusion`` console script; no arguments means ``fusion launch``."""
    if len(sys.argv) == 1:
        sys.argv.append("launch")
    app()
