"""bagkit.fleet.execute: items batched into tasks, results in item order, each item reported."""

from __future__ import annotations

import os
import time

import pytest
from distributed import Client

from bagkit.fleet.execute import MAX_BATCH, TASKS_PER_WORKER, batch_ranges, run_each


@pytest.mark.parametrize("items", [0, 1, 7, 8, 9, 40, 513, 20_000])
@pytest.mark.parametrize("workers", [1, 2, 3, 32])
def test_batches_cover_every_item_once_in_order(items: int, workers: int) -> None:
    ranges = batch_ranges(items, workers)
    assert [i for span in ranges for i in span] == list(range(items))
    assert all(0 < len(span) <= MAX_BATCH for span in ranges)
    # Several tasks per worker (as many as there are items, if fewer), evenly sized.
    assert len(ranges) >= min(items, workers * TASKS_PER_WORKER)
    assert max(map(len, ranges), default=0) - min(map(len, ranges), default=0) <= 1
    # No more tasks than that, unless one task fewer would hold more than MAX_BATCH items.
    fewer = len(ranges) - 1
    assert len(ranges) == min(items, workers * TASKS_PER_WORKER) or -(-items // fewer) > MAX_BATCH


def test_without_workers_yet_each_item_is_a_task() -> None:
    assert batch_ranges(5, 0) == [range(i, i + 1) for i in range(5)]


def test_results_come_in_item_order_and_each_item_is_reported(client: Client) -> None:
    items = list(range(37))
    reported: list[int] = []
    got = run_each(lambda i: (i * i, os.getpid()), items, client, reported.append)
    assert [square for square, _ in got] == [i * i for i in items]
    assert sorted(reported) == items
    assert len({pid for _, pid in got}) == 2, "both workers took tasks"
    assert os.getpid() not in {pid for _, pid in got}


def test_a_failing_item_raises_its_error(client: Client) -> None:
    def fail_on_five(i: int) -> int:
        if i == 5:
            raise ValueError("item five")
        return i

    with pytest.raises(ValueError, match="item five"):
        run_each(fail_on_five, list(range(20)), client)


def test_threads_in_this_process_keep_the_order_and_run_at_once() -> None:
    """Items in storage (waiting on requests) run several at a time after the first, read
    alone (what it learns of its fleet's tails, the others use): the other 8 are in flight
    together, results still in item order, each reported."""
    import threading

    barrier = threading.Barrier(8, timeout=30)
    first_done = threading.Event()

    def wait_for_all(i: int) -> tuple[int, int, bool]:
        if i == 0:
            first_done.set()
            return 0, threading.get_ident(), True
        after_first = first_done.is_set()
        barrier.wait()  # breaks (an error) unless 8 items run at once
        return i * i, threading.get_ident(), after_first

    reported: list[int] = []
    got = run_each(wait_for_all, list(range(9)), None, reported.append, threads=8)
    assert [square for square, _, _ in got] == [i * i for i in range(9)]
    assert reported == list(range(9))
    assert all(after_first for _, _, after_first in got)
    assert len({thread for _, thread, _ in got[1:]}) == 8


def test_an_error_in_a_thread_stops_what_has_not_started() -> None:
    started: list[int] = []

    def fail_on_zero(i: int) -> int:
        started.append(i)
        if i == 0:
            raise ValueError("item zero")
        time.sleep(0.01)  # a request's wait: 1,000 of them outlast the error by far
        return i

    with pytest.raises(ValueError, match="item zero"):
        run_each(fail_on_zero, list(range(1000)), None, threads=2)
    assert len(started) < 1000
