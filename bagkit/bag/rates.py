"""Message rates: the one definition every command reports (info, stats, record)."""

from __future__ import annotations

MIN_RATE_MESSAGES = 3
"""A rate needs at least this many messages (two intervals: one is no rate, 732.5 Hz for two
messages 1.4 ms apart)."""
MIN_RATE_SPAN_NS = 1_000_000_000
"""...spanning at least this long (four service events within 10 ms are no 300 Hz)."""


def message_rate(count: int, first_ns: int | None, last_ns: int | None) -> float | None:
    """A topic's rate in Hz: (count - 1) / (last - first log time), None where it means nothing.

    The one definition every command reports (info, stats, record): ``count - 1`` intervals
    between the first and the last message, so a steady 10 Hz topic is 10.0 Hz whatever the
    bag's length. None (printed ``-``) below :data:`MIN_RATE_MESSAGES` messages or
    :data:`MIN_RATE_SPAN_NS` between the first and the last.
    """
    if first_ns is None or last_ns is None:
        return None
    return pooled_rate(count, count - 1, last_ns - first_ns)


def pooled_rate(count: int, intervals: int, span_ns: int) -> float | None:
    """The rate of ``count`` messages over several bags: their ``intervals`` (``count - 1``
    within each bag) over the time they span (each bag's first to last message, summed), as
    :func:`message_rate` is for one bag; None where it means nothing."""
    if count < MIN_RATE_MESSAGES or span_ns < MIN_RATE_SPAN_NS:
        return None
    return intervals * 1e9 / span_ns
