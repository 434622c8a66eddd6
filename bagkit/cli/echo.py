"""``bagkit echo``: the messages of a topic of a bag, like ``ros2 topic echo`` (YAML) or
``mcap cat --json`` (one JSON object per line). Streams; needs no ROS install."""

# Annotations are objects here, not strings (no `from __future__ import annotations`): typer
# reads the command's parameters at every start and compiles each annotation written as a
# string, twice.

import itertools
import os
import sys
from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from bagkit.cli.common import EXIT_INTERRUPTED, fail, handle_errors, warn
from bagkit.cli.option_parsing import BAG_HELP, bag_location
from bagkit.cli.selection_options import Distro, End, Start, Where, build_query
from bagkit.compat import StrEnum
from bagkit.words import counted

if TYPE_CHECKING:
    from bagkit.data.echo import Plain

HELP = """Print the messages of TOPIC of BAG as they are read, each with its log time.

YAML by default (a '# TOPIC at SEC s' comment, then topic, log_time, publish_time in ns and the
message under data, documents separated by ---); --format json prints one object per line with
the same keys. --fields prints only those leaves as {dotted.path: value}. Decoded from the
definitions stored in the bag; the first message appears at once on any bag size.

A recorded service (TOPIC = /service, its events on /service/_service_event) prints one record
per call: client_gid, sequence_number, the events seen, request, response and latency_s (the
client's REQUEST_SENT to RESPONSE_RECEIVED where recorded, else the server's); -n, --start,
--end and --where apply ('response.success == false or latency_s > 0.1').

A recorded action (TOPIC = /action, its topics under /action/_action/) prints the messages of
all its topics (feedback, status, the goal, result and cancel services' events) in log-time
order, each under its own topic; -n, --start and --end apply.

Examples:

  bagkit echo flight1 /imu/data -n 3

  bagkit echo flight1 /gps/fix --format json --start 10 --end 20 \\
    | jq .data.latitude

  bagkit echo flight1 /imu/data --fields 'linear_acceleration.*' \\
    --fields header.stamp
"""

# ros2 topic echo cuts arrays and strings after this many elements by default.
DEFAULT_TRUNCATE_LENGTH = 128


class EchoFormat(StrEnum):
    """Output formats of ``echo``."""

    YAML = "yaml"
    JSON = "json"


Bag = Annotated[
    Path,
    typer.Argument(
        help=BAG_HELP,
        show_default=False,
        metavar="BAG",
        parser=bag_location,
    ),
]
Topic = Annotated[
    str, typer.Argument(help="The topic to print.", show_default=False, metavar="TOPIC")
]
Count = Annotated[
    int | None,
    typer.Option("--count", "-n", help="Stop after N messages.", metavar="N", min=0),
]
Fields = Annotated[
    list[str] | None,
    typer.Option(
        "--fields",
        "-f",
        help="Only these fields: dotted paths or globs as in stats summary "
        "('linear_acceleration.*', 'orientation_covariance[0]', 'header').",
    ),
]
Format = Annotated[EchoFormat, typer.Option("--format", help="yaml or json (one per line).")]
FullLength = Annotated[
    bool,
    typer.Option(
        "--full-length",
        help=f"YAML: print sequences whole (by default cut after {DEFAULT_TRUNCATE_LENGTH} "
        "elements, as ros2 topic echo does). JSON is always whole.",
    ),
]


@handle_errors
def echo(  # noqa: PLR0917 (typer maps parameters to options)
    bag: Bag,
    topic: Topic,
    count: Count = None,
    start: Start = None,
    end: End = None,
    fields: Fields = None,
    output: Format = EchoFormat.YAML,
    full_length: FullLength = False,
    where: Where = None,
    distro: Distro = None,
) -> None:
    from bagkit.bag import BagReader
    from bagkit.data.echo import action_topics, echo_action, names_service
    from bagkit.data.echo import echo as read_messages
    from bagkit.selection.errors import SelectionError

    # Output is a stream: Ctrl-C ends it quietly, as a closed pipe (| head) does every command.
    query = build_query(topic, fields, start, end, where)
    limit = None if full_length or output is EchoFormat.JSON else DEFAULT_TRUNCATE_LENGTH
    try:
        with BagReader(bag, allow_empty=True) as reader:
            bag_start = reader.start_ns
            is_action = bool(action_topics(reader, topic))
            is_service = not is_action and names_service(reader, topic)
        if is_action:
            if fields or where:
                raise SelectionError("--fields, --where: an action prints its topics' messages")
            records = echo_action(bag, query, limit=limit, on_failure=warn)
            _write(itertools.islice(records, count), output, bag_start)
            return
        if is_service:
            if fields:
                raise SelectionError("--fields: a service prints whole calls (use --where)")
            from bagkit.data.services import echo_calls  # services' modules: for a service only

            calls = echo_calls(bag, topic, limit=limit, query=query)
            if not _write(itertools.islice(calls, count), output, bag_start) and where:
                warn(f"no call satisfies {where!r}")
            return
        failures = _Failures()
        records = read_messages(
            bag,
            query,
            count=count,
            limit=limit,
            on_failure=warn if where is not None else failures.add,
        )
        written = _write(records, output, bag_start)
        if failures.count and not written:  # a topic this bag cannot give: not a success
            raise fail(
                f"none of the {counted(failures.count, 'message')} of {topic} decode "
                f"({failures.first})"
            )
        if failures.count:
            warn(
                f"{counted(failures.count, 'message')} of {topic} did not decode, skipped "
                f"({failures.first})"
            )
        if not written and where is not None:
            warn(f"no message satisfies {where!r}")
    except KeyboardInterrupt:
        # No "interrupted" line: the reader asked for it, the output so far is complete.
        _quiet_exit(EXIT_INTERRUPTED)


class _Failures:
    """The messages that did not decode: said once at the end, not once each."""

    def __init__(self) -> None:
        self.count = 0
        self.first = ""

    def add(self, problem: str) -> None:
        self.count += 1
        self.first = self.first or problem


def _write(records: "Iterable[Plain]", output: EchoFormat, bag_start: int) -> int:
    """Print each record as it comes (flushed: a reader sees the first one at once); return
    how many."""
    from bagkit.data.echo import to_json, to_yaml

    written = 0
    for record in records:
        sys.stdout.write(
            to_json(record) + "\n" if output is EchoFormat.JSON else to_yaml(record, bag_start)
        )
        sys.stdout.flush()
        written += 1
    return written


def _quiet_exit(code: int) -> None:
    # Point stdout at /dev/null so that the interpreter's final flush cannot fail again.
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, sys.stdout.fileno())
    raise typer.Exit(code)


def run_alone() -> None:
    """Run ``bagkit echo ARGS`` as a one-command app (see :mod:`bagkit.cli.launch`)."""
    from bagkit.cli.common import CONTEXT_SETTINGS, run_app
    from bagkit.cli.help_text import reflow
    from bagkit.cli.plain_params import use_plain_coercion

    app = typer.Typer(
        add_completion=False,
        pretty_exceptions_enable=False,
        context_settings=CONTEXT_SETTINGS,
        rich_markup_mode=None,  # option names whole at 80 columns (see help_text)
    )
    app.command(help=reflow(HELP), no_args_is_help=True)(echo)
    # click names the program after argv[0]: usage and errors then read "bagkit echo".
    sys.argv = [f"{sys.argv[0]} echo", *sys.argv[2:]]
    command = typer.main.get_command(app)
    use_plain_coercion(command)
    run_app(command)
