"""Seconds as int64 nanoseconds of log time, or one error of the caller's kind."""

from __future__ import annotations

import pytest

from bagkit.errors import BagkitError
from bagkit.selection.times import MAX_SECONDS, seconds_to_ns


class _MineError(BagkitError):
    pass


def test_rounds_to_the_nearest_nanosecond() -> None:
    assert seconds_to_ns(1.5, "1.5", _MineError) == 1_500_000_000
    assert seconds_to_ns(-0.25, "-0.25", _MineError) == -250_000_000
    assert seconds_to_ns(1e-9 * 0.6, "x", _MineError) == 1


@pytest.mark.parametrize("seconds", [float("nan"), float("inf"), -float("inf"), MAX_SECONDS])
def test_no_int64_time_is_the_callers_error(seconds: float) -> None:
    with pytest.raises(_MineError, match=r"^bad time 'given': not a number of seconds"):
        seconds_to_ns(seconds, "given", _MineError)
    assert seconds_to_ns(MAX_SECONDS * 0.999, "", _MineError) < 2**63
