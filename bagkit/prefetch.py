"""Run an iterator one step ahead in a thread: chunk reading and decompression (which release
the GIL) overlap with the numpy work on the previous chunk."""

from __future__ import annotations

import queue
import threading
from collections.abc import Generator, Iterator
from typing import TypeVar

T = TypeVar("T")

_DONE = object()


def prefetch(items: Iterator[T], *, depth: int = 2) -> Generator[T, None, None]:
    """Yield ``items``, produced by a worker thread at most ``depth`` items ahead.

    Exceptions of the producer are raised in the consumer. Closing the generator early stops
    the worker after its current item. ``depth`` 0: no thread, the items as they come (for a
    caller whose other cores are busy already).
    """
    if depth == 0:
        yield from items
        return
    ready: queue.Queue[object] = queue.Queue(maxsize=depth)
    stop = threading.Event()

    def produce() -> None:
        try:
            for item in items:
                if stop.is_set():
                    return
                ready.put(item)
        except BaseException as exc:  # handed to the consumer, raised there
            ready.put(exc)
            return
        ready.put(_DONE)

    worker = threading.Thread(target=produce, name="bagkit-prefetch", daemon=True)
    worker.start()
    try:
        while True:
            item = ready.get()
            if item is _DONE:
                return
            if isinstance(item, BaseException):
                raise item
            yield item  # type: ignore[misc]
    finally:
        stop.set()
        while worker.is_alive():  # unblock a producer waiting on a full queue
            try:
                ready.get_nowait()
            except queue.Empty:
                worker.join(timeout=0.01)
