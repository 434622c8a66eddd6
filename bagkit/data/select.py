"""What to read: topics by name, fields by path or glob, a time window."""

from __future__ import annotations

import datetime as dt
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from bagkit.data.errors import DataError, UnknownFieldError, UnknownTopicError
from bagkit.decode import LeafField
from bagkit.selection.fields import path_matches
from bagkit.times import check_seconds

# Times at or beyond this many seconds are read as absolute (Unix epoch) times; below it, as
# seconds from the bag's first message (about 31.7 years of recording).
ABSOLUTE_AFTER_S = 1e9

TimeLike = float | int | str | dt.datetime | Any
"""Seconds from the bag start, or absolute: epoch seconds, a datetime, an ISO 8601 string."""


@dataclass(frozen=True, slots=True)
class Window:
    """A log-time window ``start_ns <= log_time < end_ns`` (None: unbounded)."""

    start_ns: int | None = None
    end_ns: int | None = None


def to_ns(value: TimeLike | None, bag_start_ns: int) -> int | None:
    """An absolute log time in ns from a user's time.

    Numbers below ``ABSOLUTE_AFTER_S`` are seconds from ``bag_start_ns``; larger ones are Unix
    epoch seconds. ``datetime``, ``pandas.Timestamp``, ``numpy.datetime64`` and ISO 8601 strings
    are absolute (naive ones are UTC).
    """
    if value is None:
        return None
    if isinstance(value, str):
        value = _parse_time(value)
    if hasattr(value, "to_datetime64"):  # pandas.Timestamp (a datetime with nanoseconds)
        value = value.to_datetime64()
    if isinstance(value, np.datetime64):
        return int(value.astype("datetime64[ns]").astype(np.int64))
    if isinstance(value, dt.datetime):
        if value.tzinfo is None:
            value = value.replace(tzinfo=dt.UTC)
        delta = value - dt.datetime(1970, 1, 1, tzinfo=dt.UTC)
        return (delta.days * 86_400 + delta.seconds) * 1_000_000_000 + delta.microseconds * 1000
    seconds = check_seconds(float(value), value, DataError)
    if abs(seconds) >= ABSOLUTE_AFTER_S:
        return round(seconds * 1e9)
    return bag_start_ns + round(seconds * 1e9)


def _parse_time(text: str) -> float | dt.datetime:
    """A time option's text: a number of seconds, or ISO 8601 (``Z`` for UTC allowed)."""
    try:
        return check_seconds(float(text), text, DataError)
    except ValueError:
        pass
    try:
        return dt.datetime.fromisoformat(text.strip().replace("Z", "+00:00"))
    except ValueError:
        raise DataError(
            f"bad time {text!r} (seconds from the bag start, epoch seconds or ISO 8601)"
        ) from None


def window(start: TimeLike | None, end: TimeLike | None, bag_start_ns: int) -> Window:
    """The :class:`Window` of ``start``/``end`` as :func:`to_ns` reads them."""
    return Window(to_ns(start, bag_start_ns), to_ns(end, bag_start_ns))


def check_topics(wanted: Iterable[str], known: Iterable[str]) -> None:
    """Raise UnknownTopicError naming the bag's topics when one of ``wanted`` is not there."""
    known = sorted(known)
    missing = [topic for topic in wanted if topic not in known]
    if missing:
        raise UnknownTopicError(
            f"topic {', '.join(missing)} not in the bag (it has {', '.join(known) or 'none'})"
        )


def select_fields(
    leaves: Sequence[LeafField],
    patterns: Sequence[str] | None,
    *,
    topic: str,
    must_match: bool = True,
) -> list[LeafField]:
    """The leaves matching any of ``patterns`` (all when None), in definition order.

    A pattern is a path or glob as in ``stats summary`` (``linear_acceleration.*``,
    ``orientation_covariance[0]``, ``ranges[]``); a path also selects everything under it
    (``header`` is ``header.stamp.sec``, ``header.stamp.nanosec``, ``header.frame_id``).

    Raises:
        UnknownFieldError: with ``must_match``, a pattern matches no leaf (the message lists
            the topic's fields).
    """
    if not patterns:
        return list(leaves)
    unmatched = [p for p in patterns if not any(path_matches(leaf.path, p) for leaf in leaves)]
    if unmatched and must_match:
        raise UnknownFieldError(
            f"{topic} has no field {', '.join(unmatched)} (it has {describe_fields(leaves)})"
        )
    return [leaf for leaf in leaves if any(path_matches(leaf.path, p) for p in patterns)]


def describe_fields(leaves: Sequence[LeafField], limit: int = 40) -> str:
    """The leaf paths, comma-separated, at most ``limit`` of them."""
    paths = [leaf.path for leaf in leaves]
    more = f", ... ({len(paths) - limit} more)" if len(paths) > limit else ""
    return ", ".join(paths[:limit]) + more
