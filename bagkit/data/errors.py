"""Errors of ``bagkit.data`` (echo, export, DataFrames, plots)."""

from __future__ import annotations

from collections.abc import Collection, Iterable
from typing import TYPE_CHECKING

from bagkit.errors import BagkitError
from bagkit.selection.errors import UnknownFieldError, UnknownTopicError

if TYPE_CHECKING:
    from bagkit.bag import BagReader

__all__ = [
    "DataError",
    "DataLossWarning",
    "UndecodableTopicError",
    "UnknownFieldError",
    "UnknownTopicError",
    "could_have_lost",
    "nothing_read",
    "unread_topics",
]


class DataLossWarning(UserWarning):
    """Part of the bag could not be read (a salvaged file, messages that do not decode)."""


class DataError(BagkitError):
    """A selection of messages or fields that cannot be read as asked."""


class UndecodableTopicError(DataError):
    """The topic's messages cannot be decoded (no or a broken definition, not CDR)."""


def nothing_read(topics: Iterable[str], lost: Iterable[str]) -> DataError:
    """The error of a read that got no message of ``topics`` while parts of the bag(s) were
    lost (``lost``: the readers' problems): a result made of nothing (no line, an empty table,
    no episode) would pass for "nothing there" (echo, export, find)."""
    return DataError(
        f"no message of {', '.join(topics)} could be read ({'; '.join(dict.fromkeys(lost))})"
    )


def unread_topics(counts: Iterable[tuple[str, int]], losing: Collection[str]) -> list[str]:
    """The topics of ``counts`` (topic, messages read: one pair per bag) no message of which
    was read in any bag, among ``losing`` (those that :func:`could_have_lost` messages)."""
    read: dict[str, int] = {}
    for topic, count in counts:
        read[topic] = read.get(topic, 0) + count
    return [t for t, n in read.items() if not n and t in losing]


def could_have_lost(reader: BagReader, topic: str) -> bool:
    """Whether messages of ``topic`` may be among what ``reader`` lost so far: parts of the bag
    were lost and the bag does not say the topic has none (its summary counts none: rosbag2's
    /parameter_events, often; a salvaged file's counts are only what could be read)."""
    said_empty = reader.has_summary and not reader.topic_counts.get(topic, 0)
    return bool(reader.problems) and not said_empty
