"""``bagkit control``: call a running recorder's or player's services, set its parameters."""

from __future__ import annotations

from typing import TYPE_CHECKING

import typer

from bagkit.cli.common import ReportFormat, console, handle_errors, print_json
from bagkit.cli.surgery_options import Format
from bagkit.extras import ROS, require

if TYPE_CHECKING:
    from bagkit.ros.control import Controller

HELP = """Control a running bagkit recorder or player from another terminal, without the ROS 2
CLI: CONTROL is one of its services (pause, resume, toggle_paused, play_next, is_paused,
get_rate, play, stop; the recorder's pause, resume, is_paused, split, snapshot) or one of the
player's parameters with a VALUE (rate 2.0, seek 30, seek 1700000012.5, burst 10). The node that
offers it is found on the graph of this ROS_DOMAIN_ID (--node when several do); 'bagkit control
list' shows what each offers. Prints the node's answer; exit 0 done, 1 the node refused (a
rate of 0, play_next while playing; is_paused: not paused), 2 no such control or no node
offering it. A negative value follows '--': bagkit control seek -- -5.

Examples:

  bagkit control pause

  bagkit control rate 0.5 --node /bagkit_player

  bagkit control snapshot
"""


@handle_errors
def control(
    name: str = typer.Argument(..., metavar="CONTROL", help="A service, a parameter, or list."),
    value: str | None = typer.Argument(None, help="The parameter's value (rate, seek, burst)."),
    node: str | None = typer.Option(
        None, "--node", help="The node to control, e.g. /bagkit_player (default: the one found)."
    ),
    timeout: float = typer.Option(
        5.0, "--timeout", min=0.1, help="Seconds to wait for the node and for its answer."
    ),
    output_format: Format = ReportFormat.TABLE,
) -> None:
    """Call a service or set a parameter of a running recorder or player."""
    require(ROS, "bagkit control")
    from bagkit.ros.control import Controller

    with Controller(timeout_s=timeout) as controller:
        if name == "list":
            _list(controller, node, output_format)
            return
        answer = controller.control(name, value, node)
    if output_format == ReportFormat.JSON:
        print_json(answer.to_dict())
    else:
        console.print(
            f"{answer.node} {answer.control}: {_verdict(answer.control, answer.success)}"
            + (f" ({answer.message})" if answer.message else ""),
            highlight=False,
            soft_wrap=True,
            markup=False,
        )
    raise typer.Exit(0 if answer.success else 1)


def _verdict(control: str, success: bool) -> str:
    """``done``/``refused``; for a question (``is_paused``) its answer."""
    if control == "is_paused":
        return "yes" if success else "no"
    return "done" if success else "refused"


def _list(controller: Controller, node: str | None, output_format: ReportFormat) -> None:
    """Print what each recorder and player offers (waiting for one to be discovered)."""
    controller.targets("is_paused", node)  # waits for discovery, or fails naming the domain
    offers = controller.offers()
    if node:
        offers = {n: c for n, c in offers.items() if n in (node, f"/{node}")}
    if output_format == ReportFormat.JSON:
        print_json({"nodes": offers})
        return
    for owner, controls in sorted(offers.items()):
        console.print(f"{owner}: {', '.join(controls)}", highlight=False, soft_wrap=True)
