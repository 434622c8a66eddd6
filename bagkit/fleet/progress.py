"""One progress bar over the bags of a fleet run, in bags and in bytes.

It advances as each bag's task finishes, wherever it ran (here, local workers, a remote
cluster): the driver learns of each completion from the scheduler.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING

from bagkit.storage.paths import remembered_size
from bagkit.storage.urls import is_url, location
from bagkit.words import counted

if TYPE_CHECKING:
    from rich.console import Console


def bag_size(path: str | Path) -> int:
    """Bytes of a bag (its files for a directory); 0 where it cannot be read (in storage:
    what the listing that found it said, no request)."""
    if is_url(path):
        return remembered_size(location(path))
    path = Path(path)
    try:
        if path.is_dir():
            return sum(f.stat().st_size for f in path.iterdir() if f.is_file())
        return path.stat().st_size
    except OSError:
        return 0


class BagProgress:
    """A transient rich progress bar on ``console``: bags done of all, bytes done of all.

    Call the instance with the index of each finished bag; use it as a context manager.
    ``sizes``: the bags' sizes where the caller has them (else :func:`bag_size` of each).
    """

    def __init__(
        self,
        bags: Sequence[str | Path],
        console: Console,
        *,
        label: str = "bags",
        sizes: Sequence[int] | None = None,
    ) -> None:
        # Here: importing this module (stats and find of one bag do) costs no rich.
        from rich.progress import (
            BarColumn,
            DownloadColumn,
            Progress,
            TextColumn,
            TimeRemainingColumn,
        )

        self._sizes = list(sizes) if sizes is not None else [bag_size(bag) for bag in bags]
        self._count = 0
        self._bar = Progress(
            TextColumn(label),
            BarColumn(),
            TextColumn("{task.fields[bags]}"),
            DownloadColumn(),
            TimeRemainingColumn(),
            console=console,
            transient=True,
            disable=not console.is_terminal,
        )
        self._task = self._bar.add_task(label, total=sum(self._sizes), bags=self._bags())

    def _bags(self) -> str:
        return f"{self._count}/{counted(len(self._sizes), 'bag')}"

    def __call__(self, index: int) -> None:
        self._count += 1
        self._bar.update(self._task, advance=self._sizes[index], bags=self._bags())

    def __enter__(self) -> BagProgress:
        self._bar.start()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self._bar.stop()
