"""Where a replay may seek to (no rclpy): the replayed window's span, and clamping to it."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from bagkit.playback.options import PlayWindow
from bagkit.playback.source import PlaySource
from bagkit.selection.times import format_ns


@dataclass(frozen=True, slots=True)
class WindowSpan:
    """The log times a pass covers: ``start_ns`` to ``last_ns``; ``end_ns`` exclusive or None."""

    start_ns: int
    end_ns: int | None
    last_ns: int

    @classmethod
    def of(cls, window: PlayWindow, source: PlaySource) -> WindowSpan:
        """The span of ``window`` in ``source``.

        Raises:
            PlayerError: the window starts past the bags' last message.
        """
        start, end = window.bounds(source.start_ns, source.end_ns, Path(source.name))
        last = source.end_ns if end is None else min(end - 1, source.end_ns)
        return cls(start, end, last)

    def clamp(self, wanted_ns: int) -> tuple[int, str | None]:
        """``wanted_ns`` clamped to the span, and the warning when it had to be."""
        target = min(max(wanted_ns, self.start_ns), self.last_ns)
        if target == wanted_ns:
            return target, None
        where = "past the end" if wanted_ns > self.last_ns else "before the start"
        return target, (
            f"seek to {format_ns(wanted_ns)} is {where} of the replayed window "
            f"({format_ns(self.start_ns)} to {format_ns(self.last_ns)}): going to "
            f"{format_ns(target)}"
        )
