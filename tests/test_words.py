"""counted: the one rule of a printed count and its noun."""

from __future__ import annotations

import pytest

from bagkit.bag.errors import BagWriteError
from bagkit.words import counted


@pytest.mark.parametrize(
    ("count", "noun", "plural", "expected"),
    [
        (0, "file", "", "0 files"),
        (1, "file", "", "1 file"),
        (2, "more topic", "", "2 more topics"),
        (12345, "message", "", "12,345 messages"),
        (1, "status", "statuses", "1 status"),
        (3, "status", "statuses", "3 statuses"),
    ],
)
def test_a_count_agrees_with_its_noun(count: int, noun: str, plural: str, expected: str) -> None:
    assert counted(count, noun, plural) == expected


@pytest.mark.parametrize(
    ("lost_by_topic", "expected"),
    [
        ({"/imu": 1}, "disk full (1 message lost)"),
        ({"/imu": 1200, "/gps": 34}, "disk full (1,234 messages lost)"),
        ({}, "disk full"),
    ],
)
def test_a_library_message_counts_in_words(lost_by_topic: dict[str, int], expected: str) -> None:
    """A library error's count agrees with its noun as the CLI's do (it said "1 messages")."""
    assert str(BagWriteError("disk full", lost_by_topic=lost_by_topic)) == expected
