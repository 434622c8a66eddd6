"""Time windows: ``--start``/``--end`` as given (:class:`TimeRange`) and as log times.

A range is resolved against each bag on its own: ``--start 10`` is ten seconds after the first
message of every bag it is applied to, ``--end -5`` five seconds before each one's last message.
A window holds ``start_ns <= log_time < end_ns``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from bagkit.selection.errors import SelectionError
from bagkit.selection.times import Anchor, TimeLike, TimePoint, format_ns, parse_time

if TYPE_CHECKING:
    import numpy as np
    import numpy.typing as npt


@dataclass(frozen=True, slots=True)
class Window:
    """Log times ``start_ns <= t < end_ns``; None leaves that side open."""

    start_ns: int | None = None
    end_ns: int | None = None

    def contains(self, log_time: int) -> bool:
        """Whether a message logged at ``log_time`` is inside."""
        if self.start_ns is not None and log_time < self.start_ns:
            return False
        return self.end_ns is None or log_time < self.end_ns

    def covers(self, first: int, last: int) -> bool:
        """Whether every log time in ``[first, last]`` is inside."""
        return self.contains(first) and self.contains(last)

    def overlaps(self, first: int, last: int) -> bool:
        """Whether some log time in ``[first, last]`` is inside."""
        if self.start_ns is not None and last < self.start_ns:
            return False
        return self.end_ns is None or first < self.end_ns

    def mask(self, log_times: npt.NDArray[np.int64]) -> npt.NDArray[np.bool_]:
        """Which of ``log_times`` are inside, as a boolean array."""
        import numpy as np

        keep = np.ones(log_times.shape, dtype=bool)
        if self.start_ns is not None:
            keep &= log_times >= self.start_ns
        if self.end_ns is not None:
            keep &= log_times < self.end_ns
        return keep

    @property
    def bounded(self) -> bool:
        """Whether either side is set."""
        return self.start_ns is not None or self.end_ns is not None

    def describe(self) -> str:
        """``[2026-...Z, 2026-...Z)`` for messages."""
        start = "start" if self.start_ns is None else format_ns(self.start_ns)
        end = "end" if self.end_ns is None else format_ns(self.end_ns)
        return f"[{start}, {end})"


@dataclass(frozen=True, slots=True)
class TimeRange:
    """``--start``/``--end`` as the user gave them, to be resolved against each bag."""

    start: TimePoint | None = None
    end: TimePoint | None = None

    @classmethod
    def parse(
        cls, start: TimeLike | None = None, end: TimeLike | None = None, *, prefix: str = "--"
    ) -> TimeRange:
        """Parse both sides (:func:`~bagkit.selection.times.parse_time`).

        Raises:
            SelectionError: a side is not a time, or two absolute times leave nothing between.
        """
        first = None if start is None else parse_time(start, f"{prefix}start")
        last = None if end is None else parse_time(end, f"{prefix}end")
        if first and last and first.anchor is last.anchor and last.ns <= first.ns:
            raise SelectionError(f"empty time range: {prefix}end {end!r} is not after {start!r}")
        return cls(first, last)

    @classmethod
    def of_window(cls, window: Window) -> TimeRange:
        """A window of absolute log times as a range (the same instants in every bag)."""
        return cls(
            None if window.start_ns is None else TimePoint(Anchor.EPOCH, window.start_ns),
            None if window.end_ns is None else TimePoint(Anchor.EPOCH, window.end_ns),
        )

    @property
    def bounded(self) -> bool:
        """Whether either side is set."""
        return self.start is not None or self.end is not None

    def resolve(self, start_ns: int, end_ns: int) -> Window:
        """The window of a bag whose messages span ``[start_ns, end_ns]``."""
        return Window(
            None if self.start is None else self.start.resolve(start_ns, end_ns),
            None if self.end is None else self.end.resolve(start_ns, end_ns),
        )


def outside_warning(label: str, window: Window, start_ns: int, end_ns: int) -> str | None:
    """The one warning for a window that holds none of a bag's messages, or None.

    Every command says this the same way and then gives an empty result, exit 0.
    """
    if not window.bounded or window.overlaps(start_ns, end_ns):
        return None
    return (
        f"{label}: the time window {window.describe()} holds no message "
        f"(the bag spans {format_ns(start_ns)} to {format_ns(end_ns)})"
    )
