"""A user's time: seconds from the bag start, epoch seconds, datetimes, ISO 8601; bad ones are
one DataError, never a ValueError or OverflowError."""

from __future__ import annotations

import datetime as dt

import numpy as np
import pytest

from bagkit.data.errors import DataError
from bagkit.data.select import ABSOLUTE_AFTER_S, to_ns

BAG_START = 1_763_900_000_123_456_789


@pytest.mark.parametrize(
    ("given", "expected"),
    [
        (None, None),
        (0, BAG_START),
        (2.5, BAG_START + 2_500_000_000),
        ("2.5", BAG_START + 2_500_000_000),
        (-1, BAG_START - 1_000_000_000),
        (1_763_900_010.5, 1_763_900_010_500_000_000),
        ("1763900010.5", 1_763_900_010_500_000_000),
        ("2025-11-23T12:00:00Z", 1_763_899_200_000_000_000),
        ("2025-11-23T13:00:00+01:00", 1_763_899_200_000_000_000),
        ("2025-11-23T12:00:00", 1_763_899_200_000_000_000),  # naive: UTC
        (dt.datetime(2025, 11, 23, 12, tzinfo=dt.timezone.utc), 1_763_899_200_000_000_000),
        (np.datetime64(1_763_899_200_000_000_001, "ns"), 1_763_899_200_000_000_001),
    ],
)
def test_times_read_as_documented(given: object, expected: int | None) -> None:
    assert to_ns(given, BAG_START) == expected


def test_the_absolute_threshold_is_about_31_years() -> None:
    assert to_ns(ABSOLUTE_AFTER_S - 1, 0) == (ABSOLUTE_AFTER_S - 1) * 1e9
    assert to_ns(ABSOLUTE_AFTER_S, BAG_START) == ABSOLUTE_AFTER_S * 1e9


@pytest.mark.parametrize(
    "given", ["nan", "inf", "-inf", "1e400", "1e300", float("nan"), 1e19, "", "abc", "12:00 today"]
)
def test_bad_times_are_one_data_error(given: object) -> None:
    with pytest.raises(DataError, match=r"^bad time "):
        to_ns(given, BAG_START)
