"""The ``fusion`` command: run the live system, all nodes or one."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import TYPE_CHECKING

import typer
from rich.table import Table

from bagkit.cli import (
    OutputFormat,
    console,
    err_console,
    fail,
    handle_errors,
    print_json,
    run_app,
)
from bagkit.words import counted
from fusion.launch import Launcher, validate_parameter_file
from fusion.processors import NODE_NAMES

if TYPE_CHECKING:
    from fusion.nodes.monitor import LiveCheck

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
        raise fail(f"{counted(len(unknown), 'unknown node')}: {', '.join(unknown)}. {_NODES_HELP}")


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
    if params is not None:
        # Say what is wrong with the file once, up front, instead of from every node.
        validate_parameter_file(params, names)
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
    if params is not None:
        validate_parameter_file(params, [node])
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


@app.command(
    help="Measure the running system over DDS: each topic's rate against nominal and the fused "
    "altitude's RMS error against the simulated truth (/sim/truth), next to GPS's. Exits 1 when a "
    "rate is off by more than 10 % or the fused altitude is not better than GPS."
)
@handle_errors
def check(
    duration: float = typer.Option(30.0, "--duration", min=1.0, help="Seconds to measure."),
    launch_nodes: bool = typer.Option(
        False, "--launch", help="Start the system (fusion launch) for the check, then stop it."
    ),
    params: Path | None = typer.Option(
        None, "--params", exists=True, dir_okay=False, help="Parameter file for --launch."
    ),
    output_format: OutputFormat = typer.Option(
        OutputFormat.TABLE, "--format", help="table or json."
    ),
) -> None:
    if output_format is OutputFormat.CSV:
        raise fail("fusion check supports --format table or json")
    from fusion.nodes.monitor import check_system

    with err_console.status(f"measuring for {duration:g} s ..."):
        result = check_system(duration, launch=launch_nodes, params_file=params)
    if output_format is OutputFormat.JSON:
        print_json(result.as_dict())
    else:
        _print_check(result)
    raise typer.Exit(0 if result.targets_met() else 1)


def _print_check(result: LiveCheck) -> None:
    table = Table(title=f"fusion check over {result.duration_s:g} s")
    for column in ("topic", "nominal Hz", "messages", "measured Hz", "ratio", "max gap s"):
        table.add_column(column, justify="left" if column == "topic" else "right")
    for rate in result.rates:
        style = "" if rate.within(0.1) else "red"
        table.add_row(
            rate.topic,
            f"{rate.nominal_hz:g}",
            str(rate.count),
            f"{rate.rate_hz:.2f}",
            f"{rate.rate_hz / rate.nominal_hz:.3f}",
            f"{rate.max_gap_s:.3f}",
            style=style,
        )
    console.print(table)
    console.print(
        f"altitude RMS error vs truth: fused {result.fused_rms_m:.2f} m, GPS "
        f"{result.gps_rms_m:.2f} m (fused/GPS {result.fused_rms_m / result.gps_rms_m:.2f}, "
        f"{counted(result.altitude_samples, 'sample')})"
    )
    for alert in result.alerts:
        console.print(f"alert: {alert}", highlight=False)
    console.print("targets met" if result.targets_met() else "[red]targets missed[/]")


@app.command(
    help="Ask the running data logger for its current summary (the /logger/get_summary "
    "service): per sensor topic the messages it has seen. Exits 1 when it is not running."
)
@handle_errors
def summary(
    timeout: float = typer.Option(10.0, "--timeout", min=0.1, help="Seconds to wait."),
    every: float = typer.Option(
        0.0,
        "--every",
        min=0.0,
        help="Ask again every this many seconds until Ctrl-C (0: once). A logger that does "
        "not answer is asked again.",
    ),
) -> None:
    from fusion.nodes.summary_client import request_summaries, request_summary

    if every > 0:
        for message in request_summaries(every, timeout):
            console.print(message, markup=False, highlight=False)
        raise typer.Exit(0)
    response = request_summary(timeout)
    console.print(response.message, markup=False, highlight=False)
    raise typer.Exit(0 if response.success else 1)


def main() -> None:
    """Entry point of the ``fusion`` console script; no arguments means ``fusion launch``."""
    if len(sys.argv) == 1:
        sys.argv.append("launch")
    run_app(app)
