"""A storage file in object storage that its back-end reads from a local copy (SQLite3 and
ROS 1 read files on disk only; MCAP is read by range requests instead)."""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any

from bagkit.bag.storage import StorageFile


class LocalCopy:
    """``inner`` opened on a temporary copy of ``path``; named as ``path``, the copy's
    ``temporary`` directory removed on :meth:`close`. Everything else is ``inner``'s."""

    def __init__(self, inner: StorageFile, path: Path, temporary: Path) -> None:
        self.inner = inner
        self.path = path
        self._temporary = temporary

    def __getattr__(self, name: str) -> Any:
        return getattr(self.inner, name)

    def close(self) -> None:
        """Close ``inner`` and remove the copy."""
        self.inner.close()
        shutil.rmtree(self._temporary, ignore_errors=True)
