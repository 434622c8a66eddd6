"""Circular recording and the free-space guard of a bag being written.

``--max-bag-files N`` keeps the newest N files of a split bag; ``--min-free-space SIZE``
(``2GiB``, ``500MB``, ``5%`` of the filesystem) deletes the oldest file of a circular bag, or
stops the writing with an error, before the disk fills. :class:`FileRotation` decides;
:class:`bagkit.bag.BagWriter` deletes and keeps ``metadata.yaml`` to the files that exist.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path

from bagkit.bag.errors import BagError

_UNITS = {
    "": 1,
    "b": 1,
    "k": 1000,
    "kb": 1000,
    "m": 1000**2,
    "mb": 1000**2,
    "g": 1000**3,
    "gb": 1000**3,
    "t": 1000**4,
    "tb": 1000**4,
    "kib": 1 << 10,
    "mib": 1 << 20,
    "gib": 1 << 30,
    "tib": 1 << 40,
}
_SIZE = re.compile(r"\s*(\d+(?:\.\d+)?)\s*([a-zA-Z]*|%)\s*")


@dataclass(frozen=True, slots=True)
class FreeSpace:
    """A free-space floor: ``bytes``, or a ``fraction`` of the filesystem's size."""

    bytes: int = 0
    fraction: float = 0.0
    text: str = ""

    @classmethod
    def parse(cls, text: str) -> FreeSpace:
        """``2GiB``, ``500MB``, ``1000000``, ``5%``.

        Raises:
            BagError: not a size or a percentage below 100.
        """
        match = _SIZE.fullmatch(text)
        unit = match.group(2).lower() if match else ""
        if match is None or (unit != "%" and unit not in _UNITS):
            raise BagError(f"--min-free-space {text!r}: expected a size (2GiB, 500MB) or 5%")
        number = float(match.group(1))
        if unit == "%":
            if not 0 < number < 100:
                raise BagError(f"--min-free-space {text!r}: a percentage between 0 and 100")
            return cls(fraction=number / 100, text=text)
        return cls(bytes=int(number * _UNITS[unit]), text=text)

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
