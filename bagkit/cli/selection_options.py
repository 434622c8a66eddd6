"""The options every bag command shares for choosing messages: ``--start``/``--end``,
``--where``; and ``--distro``, for reading bags that store no message definitions.

One declaration, one help text, one grammar (bagkit.selection.times; docs/cli.md's table).
"""

# Annotations are objects here, not strings (no `from __future__ import annotations`): typer
# reads the callbacks' parameters at every start and compiles each annotation written as a
# string, twice.

from typing import TYPE_CHECKING, Annotated

import typer

if TYPE_CHECKING:
    from bagkit.selection.query import Query

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


def _use_distro(name: str | None) -> str | None:
    """Check ``--distro`` and hand it to every reader of this process (and its workers)."""
    if name is not None:
        import os

        from bagkit.bag.distro_definitions import DISTRO_ENV, DISTROS

        if name.strip().lower() not in DISTROS:
            raise typer.BadParameter(f"{name!r} is not one of {', '.join(DISTROS)}")
        os.environ[DISTRO_ENV] = name.strip().lower()
    return name


Distro = Annotated[
    str | None,
    typer.Option(
        "--distro",
        help="Decode the types a bag stores no definition of (Foxy to Humble .db3) as this "
        "ROS 2 distribution defines them (default: the bag's ros_distro, else jazzy).",
        metavar="NAME",
        callback=_use_distro,
    ),
]


def build_query(
    topics: list[str] | str | None = None,
    fields: list[str] | None = None,
    start: str | None = None,
    end: str | None = None,
    where: str | None = None,
) -> "Query":
    """The one place the CLI turns its selection options into a query (parsed once: a bad time
    or condition is one error, before any bag is read).

    Raises:
        SelectionError: a time or the condition does not parse.
    """
    from bagkit.cli.option_parsing import split_list
    from bagkit.selection.errors import SelectionError
    from bagkit.selection.query import Query

    names = [topics] if isinstance(topics, str) else split_list(topics)
    try:
        return Query.create(names, split_list(fields), start, end, where)
    except SelectionError:
        if where is not None:
            _check_no_topic(where)
        raise


def _check_no_topic(where: str) -> None:
    """A user who learnt ``'TOPIC: CONDITION'`` from ``--when`` and ``--around`` is told how
    ``--where`` says it, not where its parser stopped.

    Raises:
        SelectionError: ``where`` is a topic and a condition.
    """
    from bagkit.selection.conditions import topic_of
    from bagkit.selection.errors import SelectionError

    try:
        named = topic_of(where)
    except SelectionError:  # a topic and a bad condition: the condition's own error, below
        return
    if named is None:
        return
    raise SelectionError(
        f"--where {where!r}: this command's --where takes the condition alone (--where "
        f"{named.condition.text!r}), for the topics it reads ({named.topic}: --topics, -t "
        "or its TOPIC argument)"
    )
