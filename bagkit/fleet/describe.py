"""What the catalogue says of one bag, read from its summary only (what each task runs).

Kept apart from :mod:`bagkit.fleet.catalog` so that workers describe bags without importing
pandas.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from bagkit.bag import BagError, BagReader
from bagkit.storage.errors import StorageError
from bagkit.storage.paths import stamp
from bagkit.storage.urls import is_url

COLUMNS = [
    "path",
    "topic",
    "type",
    "count",
    "start",
    "end",
    "duration",
    "size",
    "compression",
    "problems",
    "mtime_ns",
]


def bag_stamp(path: str | Path) -> tuple[int, int]:
    """(total bytes, latest mtime in ns) of a bag's files: what changes when a bag does."""
    if is_url(path):
        return stamp(str(getattr(path, "url", path)))
    try:
        if os.path.isdir(path):
            with os.scandir(path) as entries:
                stats = [entry.stat() for entry in entries if entry.is_file()]
        else:
            stats = [os.stat(path)]
    except OSError:
        return (0, 0)
    return sum(s.st_size for s in stats), max((s.st_mtime_ns for s in stats), default=0)


def _row(path: str, stamp: tuple[int, int], **values: Any) -> dict[str, Any]:
    row: dict[str, Any] = dict.fromkeys(COLUMNS)
    row.update(path=path, size=stamp[0], mtime_ns=stamp[1], problems="")
    row.update(values)
    return row


def describe_bag(path: str) -> list[dict[str, Any]]:
    """The catalogue rows of one bag (read from its summary only)."""
    stamp = bag_stamp(path)
    try:
        with BagReader(path, allow_empty=True) as reader:
            # A bag without messages has no times (its 0 would read 1970-01-01 in a query).
            timed = any(reader.topic_counts.values())
            common = {
                "start": reader.start_ns if timed else None,
                "end": reader.end_ns if timed else None,
                "duration": (reader.end_ns - reader.start_ns) / 1e9,
                "compression": reader.compression_label,
                "problems": "; ".join(reader.problems),
            }
            topics = sorted(reader.topics.items())
            if not topics:
                return [
                    _row(path, stamp, **{**common, "problems": common["problems"] or "no topics"})
                ]
            return [
                _row(
                    path,
                    stamp,
                    topic=name,
                    type=info.type,
                    count=reader.topic_counts[name],
                    **common,
                )
                for name, info in topics
            ]
    except (BagError, StorageError) as exc:
        return [_row(path, stamp, problems=str(exc))]
