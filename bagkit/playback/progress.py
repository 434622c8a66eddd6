"""The replay's progress line on a terminal (no rclpy): where it is, how fast, whether paused.

One line on stderr, rewritten in place: bag time from the window's start and as a log time,
the share of the window done, the effective rate against the rate asked for, messages, late
messages, ``paused`` and the pass. Off when stderr is not a terminal (a log gets no progress).
Plain writes: a rich render costs about a millisecond, which would delay messages.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TextIO

from bagkit.playback.report import PlayProgress
from bagkit.selection.times import format_ns
from bagkit.words import counted


def progress_text(progress: PlayProgress) -> str:
    """The progress line's text (without the terminal's control characters)."""
    stamp = format_ns(progress.bag_ns)[11:23] if progress.bag_ns else ""
    parts = [
        f"bag {progress.bag_time_s:8.2f} s {stamp}",
        f"{100 * progress.fraction:5.1f}%",
        f"rate {progress.effective_rate:5.2f}x of {progress.rate:g}",
        counted(progress.messages, "msg"),
        f"{progress.late} late",
    ]
    if progress.paused:
        parts.append("paused")
    if progress.loop:
        parts.append(f"loop {progress.loop + 1}")
    return "  ".join(parts)


class ProgressLine:
    """The live progress line: rewritten in place on a terminal, nothing otherwise.

    Args:
        stream: where it goes (stderr).
        warn: prints a warning line; the progress line is ended first so that they do not mix.
    """

    def __init__(self, stream: TextIO, warn: Callable[[str], None]) -> None:
        self.stream = stream
        self.interactive = stream.isatty()
        self._warn = warn
        self.shown = False

    def update(self, progress: PlayProgress) -> None:
        """Show ``progress`` (on a terminal)."""
        if not self.interactive:
            return
        self.stream.write(f"\r{progress_text(progress)}\x1b[K")
        self.stream.flush()
        self.shown = True

    def warn(self, message: str) -> None:
        """A warning on a line of its own; the progress line comes back with the next update."""
        self.finish()
        self._warn(message)

    def finish(self) -> None:
        """End the line (before the report or a warning)."""
        if self.shown:
            self.stream.write("\n")
            self.stream.flush()
            self.shown = False
