"""Run one function per item (a bag, a batch of bags) in this process or on a Dask cluster.

Results come back in the order of the items whatever order the tasks finish in, so that what
is merged from them does not depend on scheduling. Tasks lost with a worker are rerun by Dask
on another one; Ctrl-C cancels what has not run.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, TypeVar

from bagkit.fleet.errors import FleetError

if TYPE_CHECKING:
    from distributed import Client

T = TypeVar("T")
R = TypeVar("R")

ItemDone = Callable[[int], None]
"""Called with the index of each item whose task has finished."""


def run_each(
    func: Callable[[T], R],
    items: Sequence[T],
    client: Client | None,
    done: ItemDone | None = None,
) -> list[R]:
    """``[func(item) for item in items]``, on ``client``'s workers when there is a client.

    ``func`` must be importable by the workers (a module-level function or a
    :func:`functools.partial` of one).
    """
    if client is None:
        results = []
        for index, item in enumerate(items):
            results.append(func(item))
            if done is not None:
                done(index)
        return results
    from distributed import KilledWorker, as_completed

    # pure=False: a bag read twice is read again (it may have changed on disk).
    futures = client.map(func, items, pure=False)
    index_of = {future.key: i for i, future in enumerate(futures)}
    gathered: dict[int, R] = {}
    try:
        for future in as_completed(futures):
            index = index_of[future.key]
            gathered[index] = future.result()
            future.release()
            if done is not None:
                done(index)
    except KilledWorker as exc:
        client.cancel(futures)
        raise FleetError(f"a task killed every worker that ran it, given up: {exc}") from None
    except BaseException:
        client.cancel(futures)
        raise
    return [gathered[i] for i in range(len(items))]
