"""prefetch(): same items in order, producer errors raised in the consumer, early close."""

from __future__ import annotations

import threading
from collections.abc import Iterator

import pytest

from bagkit.prefetch import prefetch


def test_items_in_order() -> None:
    assert list(prefetch(iter(range(1000)), depth=3)) == list(range(1000))


def test_producer_error_is_raised_in_consumer() -> None:
    def failing() -> Iterator[int]:
        yield 1
        raise ValueError("chunk unreadable")

    items = prefetch(failing())
    assert next(items) == 1
    with pytest.raises(ValueError, match="chunk unreadable"):
        next(items)


def test_early_close_stops_the_worker() -> None:
    produced: list[int] = []

    def endless() -> Iterator[int]:
        i = 0
        while True:
            produced.append(i)
            yield i
            i += 1

    items = prefetch(endless(), depth=2)
    assert [next(items) for _ in range(5)] == [0, 1, 2, 3, 4]
    items.close()
    assert not any(t.name == "bagkit-prefetch" and t.is_alive() for t in threading.enumerate())
    assert len(produced) <= 5 + 2 + 2


def test_depth_zero_runs_no_thread() -> None:
    seen_in: list[str] = []

    def items() -> Iterator[int]:
        for i in range(3):
            seen_in.append(threading.current_thread().name)
            yield i

    assert list(prefetch(items(), depth=0)) == [0, 1, 2]
    assert seen_in == [threading.current_thread().name] * 3
