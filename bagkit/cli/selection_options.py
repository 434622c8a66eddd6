"""The options every bag command shares for choosing messages: ``--start``/``--end``,
``--where``.

One declaration, one help text, one grammar (bagkit.selection.times; docs/cli.md's table).
"""

from __future__ import annotations

from typing import Annotated

import typer

TIME_HELP = (
    "seconds from the bag start (10, 1m30s), before its end (-5), or absolute "
    "(epoch seconds, ISO 8601, NNNns); docs/cli.md"
)

Start = Annotated[
    str | None,
    typer.Option("--start", help=f"Messages logged at or after TIME: {TIME_HELP}.", metavar="TIME"),
]
End = Annotated[
    str | None,
    typer.Option(
        "--end", help="Messages logged before TIME (exclusive), read as --start.", metavar="TIME"
    ),
]

Where = Annotated[
    str | None,
    typer.Option(
        "--where",
        help="Only messages satisfying this condition, e.g. 'status[*].level >= 2' "
        "(PATH OP VALUE, and/or/not; docs/cli.md).",
        metavar="CONDITION",
    ),
]

StateTopics = Annotated[
    list[str] | None,
    typer.Option(
        "--state-topics",
        help="Topics whose messages hold until the next one, as transient-local topics do: "
        "an episode lasts until the state changes (repeated or a,b).",
        metavar="TOPICS",
    ),
]


def duration_seconds(text: str | None, option: str) -> float | None:
    """A duration option (``90``, ``1m30s``, ``250ms``) in seconds, as the library takes it.

    Raises:
        SelectionError: not a duration of the one grammar.
    """
    from bagkit.selection.times import NS_PER_S, parse_duration

    return None if text is None else parse_duration(text, option) / NS_PER_S
