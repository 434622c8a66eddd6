"""A progress bar for work of unknown length: it appears on stderr once the work has taken a
second, so that quick commands print nothing but their result, and only on a terminal (a log or
a script's pipe gets nothing, not even the blank line a stopped bar leaves)."""

from __future__ import annotations

import time
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from rich.progress import Progress, TaskID

PROGRESS_DELAY_S = 1.0


class DelayedProgress:
    """``progress(done, total)`` in messages, labelled ``label``; ``close()`` when done."""

    def __init__(self, label: str) -> None:
        self._label = label
        self._started = time.monotonic()
        self._bar: Progress | None = None
        self._task: TaskID | None = None
        self._off = False

    def __call__(self, done: int, total: int) -> None:
        if self._bar is None:
            if self._off or time.monotonic() - self._started < PROGRESS_DELAY_S:
                return
            # Here: a command that ends within the delay never imports rich (start-up time).
            from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

            from bagkit.cli.common import err_console

            if not err_console.is_terminal:
                self._off = True
                return
            self._bar = Progress(
                TextColumn(self._label),
                BarColumn(),
                TextColumn("{task.completed:,}/{task.total:,} messages"),
                TimeRemainingColumn(),
                console=err_console,
                transient=True,
            )
            self._bar.start()
            self._task = self._bar.add_task(self._label, total=total)
        assert self._task is not None
        self._bar.update(self._task, completed=done, total=total)

    def close(self) -> None:
        """Take the bar off the terminal (it is transient)."""
        if self._bar is not None:
            self._bar.stop()
