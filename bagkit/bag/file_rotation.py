"""Circular recording and the free-space guard of a bag being written.

``--max-bag-files N`` keeps the newest N files of a split bag; ``--min-free-space SIZE``
(``2GiB``, ``500MB``, ``5%`` of the filesystem) deletes the oldest file of a circular bag, or
stops the writing with an error, before the disk fills. :class:`FileRotation` decides;
:class:`bagkit.bag.BagWriter` deletes and keeps ``metadata.yaml`` to the files that exist.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from bagkit.bag.sizes import parse_share, parse_size


@dataclass(frozen=True, slots=True)
class FreeSpace:
    """A free-space floor: ``bytes``, or a ``fraction`` of the filesystem's size."""

    bytes: int = 0
    fraction: float = 0.0
    text: str = ""

    @classmethod
    def parse(cls, text: str) -> FreeSpace:
        """``2GiB``, ``500MB``, ``1000000``, ``5%`` (:mod:`bagkit.bag.sizes`).

        Raises:
            BagError: not a size or a percentage below 100.
        """
        what = "min_free_space"
        share = parse_share(text, what)
        if share is not None:
            return cls(fraction=share, text=text)
        return cls(bytes=parse_size(text, what), text=text)

    def below(self, directory: Path) -> bool:
        """Whether the filesystem of ``directory`` has less free space than this floor."""
        stats = os.statvfs(directory)
        free = stats.f_bavail * stats.f_frsize
        floor = max(self.bytes, int(self.fraction * stats.f_blocks * stats.f_frsize))
        return free < floor


@dataclass(frozen=True, slots=True)
class FileRotation:
    """How many files a bag keeps (0: all) and the free space it leaves (None: no guard)."""

    max_files: int = 0
    min_free: FreeSpace | None = None

    def excess(self, files: int) -> int:
        """How many of the oldest of ``files`` (the open one included) must go."""
        return max(0, files - self.max_files) if self.max_files else 0
