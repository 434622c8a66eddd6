"""What the commands that take many bags share: their options and how a run is set up.

``stats summary``, ``export``, ``catalog`` and ``golden check`` take bags (directories, globs,
listing files), ``--workers N`` and ``--scheduler ADDRESS``; one :func:`fleet_run` starts the
local cluster or connects to the scheduler, and shows one progress bar over the bags.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from bagkit.cli import common
from bagkit.cli.common import fail, note

if TYPE_CHECKING:
    from distributed import Client

    from bagkit.fleet.cluster import WorkRate

BAGS_HELP = (
    "Bags, directories searched for bags, globs, .txt files listing bag paths, or URLs "
    "(s3://, gs://, az://, https://: bags, or prefixes searched for bags)"
)

Workers = Annotated[
    int | None,
    typer.Option(
        "--workers",
        min=0,
        help="Local Dask worker processes (default: one per core when the bags are enough "
        "work to pay for a cluster's start; 0: in this process).",
        metavar="N",
    ),
]
Scheduler = Annotated[
    str | None,
    typer.Option(
        "--scheduler",
        help="Run on an existing dask.distributed scheduler, e.g. tcp://10.0.0.5:8786 "
        "(the bags must be readable at the same paths on its workers).",
        metavar="ADDRESS",
    ),
]


@contextmanager
def fleet_run(
    bags: Sequence[str | Path],
    *,
    workers: int | None,
    scheduler: str | None,
    label: str,
    rate: WorkRate,
) -> Iterator[tuple[Client | None, Callable[[int], None]]]:
    """The Dask client for a run over ``bags`` (None: in this process) and its progress call.

    ``rate``: what the command costs in one process, which decides whether a local cluster is
    started when neither ``workers`` nor ``scheduler`` is given. The progress bar counts bags
    and bytes; the dashboard of a local cluster is announced.
    """
    from bagkit.fleet import fleet_client
    from bagkit.fleet.progress import BagProgress, bag_size

    sizes = [bag_size(bag) for bag in bags]
    client_run = fleet_client(
        workers=workers,
        scheduler=scheduler,
        bags=len(bags),
        size_bytes=sum(sizes),
        rate=rate,
        announce=note,
    )
    with client_run as client:
        if not sys.stderr.isatty():  # no bar to show: rich is not even imported (start-up time)
            yield client, lambda index: None
            return
        with BagProgress(bags, common.err_console, label=label, sizes=sizes) as done:
            yield client, done


def end_with_unread(unread: int, of: int, what: str = "bags", undone: str = "read") -> None:
    """The rule of every many-bag command (docs/fleet.md, "Bags that cannot be read"), once
    the others' results are out: ``unread`` of ``of`` bags that could not be read (each
    already a ``BAG: not read: why`` warning) end it with one error line and exit 2, as one
    bag that cannot be read does."""
    if unread:
        raise fail(f"{unread} of {of} {what} could not be {undone}", 2)
