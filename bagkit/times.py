"""A number of seconds from a user, spec or bag as integer nanoseconds of log time.

Log times are int64 nanoseconds (MCAP, rosbag2): a value that is not finite or lies beyond
about 292 years either side of 1970 has no such time, and is one clear error wherever it is
given, not an OverflowError from ``int(inf)``.
"""

from __future__ import annotations

from bagkit.errors import BagkitError

MAX_SECONDS = 2**63 / 1e9


def check_seconds(seconds: float, given: object, error: type[BagkitError]) -> float:
    """``seconds``, or ``error`` naming ``given`` when it is not a finite int64-ns time."""
    if not abs(seconds) < MAX_SECONDS:
        raise error(f"bad time {given!r}: not a number of seconds within int64 ns")
    return seconds


def seconds_to_ns(seconds: float, given: object, error: type[BagkitError]) -> int:
    """``seconds`` in integer nanoseconds (rounded), checked as :func:`check_seconds`."""
    return round(check_seconds(seconds, given, error) * 1e9)
