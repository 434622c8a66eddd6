"""Windows resolved per bag, and the one warning for a window outside a bag."""

from __future__ import annotations

import numpy as np
import pytest

from bagkit.selection.errors import SelectionError
from bagkit.selection.windows import TimeRange, Window, outside_warning

S = 1_000_000_000


def test_a_range_resolves_against_each_bag_on_its_own() -> None:
    span = TimeRange.parse("10", "-5")
    assert span.resolve(100 * S, 200 * S) == Window(110 * S, 195 * S)
    assert span.resolve(500 * S, 560 * S) == Window(510 * S, 555 * S)
    absolute = TimeRange.parse("1763850000", None)
    assert absolute.resolve(0, 1) == absolute.resolve(7, 9) == Window(1763850000 * S, None)


def test_the_window_is_half_open() -> None:
    window = Window(10, 20)
    times = np.arange(5, 25, dtype=np.int64)
    expected = [t for t in range(5, 25) if 10 <= t < 20]
    assert times[window.mask(times)].tolist() == expected
    assert [t for t in range(5, 25) if window.contains(t)] == expected
    assert window.covers(10, 19) and not window.covers(10, 20)
    assert window.overlaps(0, 10) and not window.overlaps(0, 9) and not window.overlaps(20, 30)
    assert Window().mask(times).all() and not Window().bounded


def test_two_absolute_times_must_leave_something_between() -> None:
    with pytest.raises(SelectionError, match="empty time range"):
        TimeRange.parse("20", "10")
    with pytest.raises(SelectionError, match=r"^bad --end"):
        TimeRange.parse("1", "nope")


def test_one_warning_names_the_bag_as_given_when_the_window_misses_it() -> None:
    window = TimeRange.parse("100", None).resolve(0, 50 * S)
    message = outside_warning("day1/", window, 0, 50 * S)
    assert message is not None and message.startswith("day1/: the time window [")
    assert outside_warning("x", TimeRange.parse("10", None).resolve(0, 50 * S), 0, 50 * S) is None
    assert outside_warning("x", Window(), 0, 1) is None
