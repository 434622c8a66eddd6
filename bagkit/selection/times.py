"""One grammar for times and durations, in every command and in the library.

A time is one of (docs/cli.md has the table):

- seconds from the bag's first message: ``10``, ``2.5``, ``1m30s``, ``0.5s``;
- seconds before the bag's last message: ``-5``, ``-1m``;
- absolute: epoch seconds (``1763850000.25``), ISO 8601 (``2026-11-16T10:00:00Z``; UTC when no
  zone is given), or a ``datetime`` / ``pandas.Timestamp`` / ``numpy.datetime64`` object;
- ``NNNns``: nanoseconds, read by the same rule as seconds.

An offset is told from an epoch time by its size, here and nowhere else: a magnitude of at least
:data:`ABSOLUTE_AFTER_S` seconds (about 31.7 years) is an epoch time, anything smaller is an
offset. A duration (``90``, ``90s``, ``1m30s``, ``1h``, ``250ms``, ``NNNns``) is never absolute.
"""

from __future__ import annotations

import datetime as dt
import numbers
import re
from dataclasses import dataclass
from enum import Enum
from typing import Any

from bagkit.errors import BagkitError
from bagkit.selection.errors import SelectionError

ABSOLUTE_AFTER_S = 1e9
"""Times of at least this many seconds (in magnitude) are epoch times; smaller ones offsets."""

NS_PER_S = 1_000_000_000
MAX_SECONDS = 2**63 / 1e9
"""Log times are int64 ns (MCAP, rosbag2): about 292 years either side of 1970."""
_UNIT_NS = {"h": 3600 * NS_PER_S, "m": 60 * NS_PER_S, "s": NS_PER_S, "ms": 1_000_000, "us": 1000}
_NUMBER = r"\d+(?:\.\d*)?|\.\d+"
_DURATION = re.compile(
    rf"(?:({_NUMBER})h)?(?:({_NUMBER})m(?!s))?(?:({_NUMBER})s)?(?:({_NUMBER})ms)?"
)
_EPOCH = dt.datetime(1970, 1, 1, tzinfo=dt.timezone.utc)
# An ISO 8601 date-time: the part fromisoformat reads, a fraction of a second, a zone.
_ISO_FRACTION = re.compile(
    r"(\d{4}-\d\d-\d\d)(?:[T ](\d\d(?::\d\d(?::\d\d)?)?))?(?:\.(\d{1,9}))?"
    r"(Z|z|[+-]\d\d:?\d\d)?"
)
_GRAMMAR = "seconds (10, -5, 1m30s), epoch seconds, ISO 8601 or NNNns"

TimeLike = float | int | str | dt.datetime | Any
"""What the library takes as a time: a number of seconds, a string of the grammar above, a
``datetime``, ``pandas.Timestamp`` or ``numpy.datetime64``."""


class Anchor(Enum):
    """What a time counts from."""

    START = "start"
    END = "end"
    EPOCH = "epoch"


@dataclass(frozen=True, slots=True)
class TimePoint:
    """A parsed time: ``ns`` after the bag start, before (negative) its end, or since 1970."""

    anchor: Anchor
    ns: int

    def resolve(self, start_ns: int, end_ns: int) -> int:
        """This time as an absolute log time in a bag spanning ``[start_ns, end_ns]``."""
        if self.anchor is Anchor.START:
            return start_ns + self.ns
        if self.anchor is Anchor.END:
            return end_ns + self.ns
        return self.ns

    @property
    def absolute(self) -> bool:
        """Whether the time names one instant whatever the bag."""
        return self.anchor is Anchor.EPOCH


def parse_time(value: TimeLike, option: str = "time") -> TimePoint:
    """A user's time (text or object) as a :class:`TimePoint`.

    Raises:
        SelectionError: not a time of the grammar, or beyond int64 nanoseconds.
    """
    if isinstance(value, TimePoint):
        return value
    if isinstance(value, str):
        return _parse_text(value.strip(), option)
    if isinstance(value, bool):
        raise _bad(value, option)
    if isinstance(value, numbers.Real):  # numpy's numbers too
        check_seconds(float(value), value, SelectionError, option)
        if isinstance(value, numbers.Integral):
            return _parse_text(str(int(value)), option)
        return _parse_text(repr(float(value)), option)
    return TimePoint(Anchor.EPOCH, _object_ns(value, option))


def parse_duration(value: str | float, option: str = "duration") -> int:
    """A duration in ns: ``90``, ``1.5``, ``90s``, ``1m30s``, ``2h``, ``250ms``, ``NNNns``.

    Raises:
        SelectionError: not a duration, negative, or beyond int64 nanoseconds.
    """
    if isinstance(value, int | float) and not isinstance(value, bool):
        ns = seconds_to_ns(float(value), value, SelectionError, option)
    elif isinstance(value, str):
        parsed = _unsigned_ns(value.strip())
        if parsed is None:
            raise SelectionError(f"bad {option} {value!r}: not a duration (90, 90s, 1m30s, 250ms)")
        ns = parsed
    else:
        raise SelectionError(f"bad {option} {value!r}: not a duration (90, 90s, 1m30s, 250ms)")
    if ns < 0:
        raise SelectionError(f"bad {option} {value!r}: a duration cannot be negative")
    if ns >= MAX_SECONDS * NS_PER_S:  # numpy's int64 time columns could not hold it
        raise SelectionError(f"bad {option} {value!r}: beyond int64 nanoseconds")
    return ns


def format_ns(ns: int) -> str:
    """An absolute log time as ISO 8601 UTC, to the nanosecond (``...T10:00:00.000000001Z``)."""
    seconds, rest = divmod(ns, NS_PER_S)
    stamp = (_EPOCH + dt.timedelta(seconds=seconds)).strftime("%Y-%m-%dT%H:%M:%S")
    return f"{stamp}.{rest:09d}Z"


def _parse_text(text: str, option: str) -> TimePoint:
    negative = text.startswith("-")
    ns = _unsigned_ns(text[1:] if negative else text)
    if ns is not None:
        return _from_ns(-ns if negative else ns, text, option)
    return TimePoint(Anchor.EPOCH, _iso_ns(text, option))


def _iso_ns(text: str, option: str) -> int:
    """ISO 8601 in ns since 1970, the fraction kept to the nanosecond (naive: UTC).

    The fraction and ``Z`` are read here: Python 3.10's ``fromisoformat`` takes neither a
    ``Z`` nor fractions of other than 3 or 6 digits, and no version keeps nanoseconds.
    """
    match = _ISO_FRACTION.fullmatch(text)
    if match is None:
        raise _bad(text, option)
    date, clock, fraction, zone = match.groups()
    if zone in (None, "Z", "z"):
        zone = "+00:00"
    elif ":" not in zone:
        zone = f"{zone[:3]}:{zone[3:]}"
    try:
        stamp = dt.datetime.fromisoformat(f"{date}T{clock or '00:00'}{zone}")
    except ValueError:
        raise _bad(text, option) from None
    return _object_ns(stamp, option) + (_decimal_ns(f"0.{fraction}", NS_PER_S) if fraction else 0)


def _unsigned_ns(text: str) -> int | None:
    """``text`` without sign as ns: plain seconds, ``NNNns`` or a duration; None otherwise."""
    if text.endswith("ns") and text[:-2].isdigit():
        return int(text[:-2])
    if re.fullmatch(_NUMBER, text):
        return _decimal_ns(text, NS_PER_S)
    if re.fullmatch(rf"(?:{_NUMBER})[eE][+-]?\d{{1,3}}", text):  # 1.7e9: no exact digits to keep
        seconds = float(text)
        return round(seconds * NS_PER_S) if seconds < MAX_SECONDS else 2**63
    match = _DURATION.fullmatch(text)
    if not text or match is None or not any(match.groups()):
        return None
    units = (_UNIT_NS["h"], _UNIT_NS["m"], _UNIT_NS["s"], _UNIT_NS["ms"])
    return sum(
        _decimal_ns(part, unit) for part, unit in zip(match.groups(), units, strict=True) if part
    )


def _decimal_ns(number: str, unit_ns: int) -> int:
    """``number`` (digits, maybe a fraction) times ``unit_ns``, exactly, rounded to 1 ns."""
    whole, _, fraction = number.partition(".")
    digits = (fraction + "0" * 18)[:18]
    return int(whole or 0) * unit_ns + (int(digits) * unit_ns + 5 * 10**17) // 10**18


def _from_ns(ns: int, given: object, option: str) -> TimePoint:
    if abs(ns) >= MAX_SECONDS * NS_PER_S:
        raise SelectionError(f"bad {option} {given!r}: beyond int64 nanoseconds")
    if abs(ns) >= ABSOLUTE_AFTER_S * NS_PER_S:
        if ns < 0:
            raise SelectionError(f"bad {option} {given!r}: an epoch time before 1970")
        return TimePoint(Anchor.EPOCH, ns)
    return TimePoint(Anchor.END if ns < 0 or str(given).startswith("-") else Anchor.START, ns)


def _object_ns(value: Any, option: str) -> int:
    """ns since 1970 of a ``datetime``, ``pandas.Timestamp`` or ``numpy.datetime64``."""
    if hasattr(value, "to_datetime64"):  # pandas.Timestamp keeps nanoseconds there
        value = value.to_datetime64()
    if type(value).__name__ == "datetime64":
        ns = int(value.astype("datetime64[ns]").astype("int64"))
    elif isinstance(value, dt.datetime):
        if value.tzinfo is None:
            value = value.replace(tzinfo=dt.timezone.utc)
        delta = value - _EPOCH
        ns = (delta.days * 86_400 + delta.seconds) * NS_PER_S + delta.microseconds * 1000
    else:
        raise _bad(value, option)
    if not 0 <= ns < MAX_SECONDS * NS_PER_S:
        raise SelectionError(f"bad {option} {value!r}: before 1970 or beyond int64 nanoseconds")
    return ns


def _bad(value: object, option: str) -> SelectionError:
    return SelectionError(f"bad {option} {value!r}: not a time ({_GRAMMAR})")


def check_seconds(
    seconds: float, given: object, error: type[BagkitError], what: str = "time"
) -> float:
    """``seconds``, or ``error`` naming ``what`` and ``given`` when it is not a finite
    int64-ns time."""
    if not abs(seconds) < MAX_SECONDS:
        raise error(f"bad {what} {given!r}: not a number of seconds within int64 ns")
    return seconds


def seconds_to_ns(
    seconds: float, given: object, error: type[BagkitError], what: str = "time"
) -> int:
    """``seconds`` in integer nanoseconds (rounded), checked as :func:`check_seconds`."""
    return round(check_seconds(seconds, given, error, what) * 1e9)
