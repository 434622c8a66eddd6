"""counted: the one rule of a printed count and its noun."""

from __future__ import annotations

import pytest

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
