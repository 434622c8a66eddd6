"""Run one function per item (a bag, a fixture) in this process or on a Dask cluster.

On a cluster, items go to the workers a few per task, in order: a task costs the driver and
the scheduler a few milliseconds of CPU, which on a small machine is taken from the workers
(benchmarks/README.md, find on 2 workers). Each worker still gets several tasks, so that one
that finishes early takes more. Results come back in the order of the items whatever order
the tasks finish in, so that what is merged from them does not depend on scheduling. Tasks
lost with a worker are rerun by Dask on another one; Ctrl-C cancels what has not run.
"""

from __future__ import annotations

import functools
import itertools
import math
from collections.abc import Callable, Iterator, Sequence
from typing import TYPE_CHECKING, TypeVar

from bagkit.fleet.errors import FleetError
from bagkit.storage.urls import is_url

if TYPE_CHECKING:
    from distributed import Client

T = TypeVar("T")
R = TypeVar("R")

ItemDone = Callable[[int], None]
"""Called with the index of each item whose task has finished."""

# Tasks per worker to aim for: enough to balance the workers, few enough that each task's
# cost is small against its items' reads.
TASKS_PER_WORKER = 4
MAX_BATCH = 64
"""Items per task at most (a task lost with its worker is rerun whole)."""
REMOTE_READERS = 16
"""Bags in storage read at once per process by the commands that read summaries only."""


def batch_ranges(items: int, workers: int) -> list[range]:
    """Consecutive index ranges covering ``items``, of sizes differing by one at most: about
    TASKS_PER_WORKER per worker, more where that would pass MAX_BATCH items; one item each
    when no worker is known yet (a scheduler whose workers are still coming) (pure)."""
    if workers < 1:
        tasks = items
    else:
        tasks = min(items, max(workers * TASKS_PER_WORKER, math.ceil(items / MAX_BATCH)))
    bounds = [items * k // tasks for k in range(tasks + 1)] if tasks else [0]
    return [range(a, b) for a, b in itertools.pairwise(bounds)]


def readers_for(bags: Sequence[object]) -> int:
    """How many of ``bags`` a process reads at once: REMOTE_READERS when some are in storage
    (each is a few requests that mostly wait), else one."""
    return REMOTE_READERS if any(is_url(bag) for bag in bags) else 1


def _mapped(func: Callable[[T], R], items: Sequence[T], threads: int) -> Iterator[R]:
    """``func`` over ``items``, results in their order, ``threads`` items at a time after the
    first, read alone: the tails of the bags of a fleet in storage are alike, and the first
    one read tells the others how deep to read theirs (one request each where the first
    ``threads`` would each guess, and some read again: benchmarks/README.md)."""
    if threads <= 1 or len(items) <= 1:
        yield from map(func, items)
        return
    yield func(items[0])
    items = items[1:]
    # Threads for bags in storage only: a local bag's command starts without them (or logging).
    from concurrent.futures import ThreadPoolExecutor

    pool = ThreadPoolExecutor(min(threads, len(items)))
    try:
        yield from pool.map(func, items)
    finally:  # on an error or Ctrl-C: what has not started never does
        pool.shutdown(cancel_futures=True)


def _run_batch(func: Callable[[T], R], threads: int, batch: Sequence[T]) -> list[R]:
    """One task: ``func`` over its items, results in order."""
    return list(_mapped(func, batch, threads))


def run_each(
    func: Callable[[T], R],
    items: Sequence[T],
    client: Client | None,
    done: ItemDone | None = None,
    *,
    threads: int = 1,
) -> list[R]:
    """``[func(item) for item in items]``, on ``client``'s workers when there is a client.

    ``func`` must be importable by the workers (a module-level function or a
    :func:`functools.partial` of one). ``threads``: items run at once in this process, or in
    each task (:func:`readers_for`).
    """
    if client is None:
        results = []
        for index, result in enumerate(_mapped(func, items, threads)):
            results.append(result)
            if done is not None:
                done(index)
        return results
    from distributed import KilledWorker, as_completed

    ranges = batch_ranges(len(items), len(client.scheduler_info()["workers"]))
    task = functools.partial(_run_batch, func, threads)
    # pure=False: a bag read twice is read again (it may have changed on disk).
    futures = client.map(task, [[items[i] for i in span] for span in ranges], pure=False)
    range_of = {future.key: span for future, span in zip(futures, ranges, strict=True)}
    gathered: dict[int, R] = {}
    try:
        # with_results: gathered by the client's event loop as each task ends, not with a
        # round trip from this thread per result.
        for future, results in as_completed(futures, with_results=True):
            for index, result in zip(range_of[future.key], results, strict=True):
                gathered[index] = result
                if done is not None:
                    done(index)
    except KilledWorker as exc:
        client.cancel(futures)
        raise FleetError(f"a task killed every worker that ran it, given up: {exc}") from None
    except BaseException:
        client.cancel(futures)
        raise
    return [gathered[i] for i in range(len(items))]
