"""Loss accounting from publication sequence numbers (pure: no middleware involved)."""

from __future__ import annotations

import random

from bagkit.recording.loss import SequenceTracker


def feed(numbers: list[int], publishers: int) -> tuple[int, int]:
    tracker = SequenceTracker()
    lost = sum(tracker.observe(n, lambda: publishers) for n in numbers)
    return lost, tracker.publishers


def test_one_publisher_counts_every_hole() -> None:
    received = [n for n in range(1, 101) if n not in {5, 6, 50, 99}]
    assert feed(received, 1) == (4, 1)


def test_first_message_after_matching_is_not_a_loss() -> None:
    # Joined late: the publisher was at 1000 already.
    assert feed(list(range(1000, 1010)), 1) == (0, 1)


def test_interleaved_publishers_with_losses() -> None:
    rng = random.Random(7)
    a = [n for n in range(1, 301) if rng.random() > 0.05]
    b = [n for n in range(40, 341) if rng.random() > 0.05]
    # What a tracker can see: the holes between each publisher's first and last message.
    expected = sum(s[-1] - s[0] + 1 - len(s) for s in (a, b))
    merged: list[int] = []
    ia = ib = 0
    while ia < len(a) or ib < len(b):
        if ib >= len(b) or (ia < len(a) and rng.random() < 0.5):
            merged.append(a[ia])
            ia += 1
        else:
            merged.append(b[ib])
            ib += 1
    assert feed(merged, 2) == (expected, 2)


def test_new_publisher_starting_below_the_others_is_not_a_gap() -> None:
    # One publisher at 500; a second one appears (starts at 1) while the first goes on.
    numbers = [*range(500, 510), 1, 510, 2, 511, 3]
    assert feed(numbers, 2) == (0, 2)


def test_restarted_publisher_is_not_a_gap() -> None:
    # The node restarted: its new writer counts from 1 again.
    assert feed([*range(1, 50), *range(1, 10)], 1) == (0, 1)


def test_observe_many_counts_as_one_observe_per_number() -> None:
    # Two publishers with holes, a restart, unknown (0) numbers; fed in batches of any size.
    rng = random.Random(11)
    numbers = [n for n in range(1, 2000) if rng.random() > 0.02]
    numbers[700:700] = [0, 0, *range(5, 40)]
    numbers[1500:1500] = list(range(1, 30))
    for _ in range(20):
        one, batched = SequenceTracker(), SequenceTracker()
        expected = sum(one.observe(n, lambda: 2) for n in numbers if n)
        position, lost = 0, 0
        while position < len(numbers):
            size = rng.choice([1, 2, 5, 64, 300])
            lost += batched.observe_many(numbers[position : position + size], lambda: 2)
            position += size
        assert lost == expected > 0
        assert batched.publishers == one.publishers


def test_observe_many_fast_path_continues_the_stream() -> None:
    tracker = SequenceTracker()
    assert tracker.observe_many(list(range(10, 20)), lambda: 1) == 0
    assert tracker.observe_many(list(range(20, 300)), lambda: 1) == 0
    assert tracker.observe_many([300, 302, 303], lambda: 1) == 1
    assert tracker.observe_many([305], lambda: 1) == 1
