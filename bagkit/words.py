"""A count and its noun in agreement (``1 file``, ``3 files``): the one rule every printed
count follows, from the lowest layer so that library messages use it as the CLI does."""

from __future__ import annotations


def counted(count: int, noun: str, plural: str = "") -> str:
    """``count`` and ``noun``, plural unless it is one (``plural`` when not ``noun + "s"``);
    counts of a thousand or more grouped (``12,345 messages``)."""
    return f"{count:,} {noun if count == 1 else plural or noun + 's'}"
