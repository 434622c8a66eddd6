"""``bagkit info DIR`` of a folder of bags (a snapshot-mode output, a fleet folder): each bag's
info, read from its summary as ``info BAG`` reads it, and what could not be read."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

from bagkit.bag import BagError, BagInfo, bag_info
from bagkit.fleet.execute import readers_for, run_each
from bagkit.fleet.inputs import BAG_FILE_SUFFIXES, STORAGE_SUFFIXES, find_bags, is_bag_directory
from bagkit.fleet.url_inputs import in_path_order, url_bags
from bagkit.storage.errors import StorageError
from bagkit.storage.urls import is_url


@dataclass(slots=True)
class FolderInfo:
    """The bags under a folder, in path order; ``unread``: bag path -> why it was not read."""

    root: str
    bags: list[BagInfo] = field(default_factory=list)
    unread: dict[str, str] = field(default_factory=dict)

    @property
    def message_count(self) -> int:
        return sum(bag.message_count for bag in self.bags)

    @property
    def size_bytes(self) -> int:
        return sum(bag.size_bytes for bag in self.bags)

    @property
    def duration_s(self) -> float:
        """The bags' durations summed (the time recorded, not the span across gaps)."""
        return sum(bag.duration_s for bag in self.bags)

    def to_dict(self) -> dict[str, Any]:
        """JSON: the totals, one object per bag (as ``info BAG --format json``), the unread."""
        return {
            "path": self.root,
            "bag_count": len(self.bags),
            "message_count": self.message_count,
            "size_bytes": self.size_bytes,
            "duration_s": self.duration_s,
            "bags": [bag.to_dict() for bag in self.bags],
            "unread": dict(self.unread),
        }


def folder_info(
    root: str | Path, *, check_crc: bool = True, exact_rates: bool | None = None
) -> FolderInfo | None:
    """The bags under ``root`` (a directory or a URL prefix), or None when ``root`` is no
    folder of bags (a bag itself, a file, or a folder holding no bag); ``exact_rates`` as
    :func:`~bagkit.bag.info.bag_info` takes it."""
    text = str(getattr(root, "url", root))
    if is_url(text):
        paths = url_bags(text, STORAGE_SUFFIXES, BAG_FILE_SUFFIXES)
        if paths == [text]:  # the URL is a bag
            return None
    elif not Path(text).is_dir() or is_bag_directory(text):
        return None
    else:
        paths = in_path_order(find_bags(text))
    if not paths:
        return None
    found = FolderInfo(text)
    describe = partial(_described, check_crc=check_crc, exact_rates=exact_rates)
    described = run_each(describe, paths, None, threads=readers_for(paths))
    for path, result in zip(paths, described, strict=True):
        if isinstance(result, BagInfo):
            found.bags.append(result)
        else:
            found.unread[path] = result
    return found


def _described(path: str, check_crc: bool, exact_rates: bool | None) -> BagInfo | str:
    """The bag's info, or why it could not be read."""
    try:
        return bag_info(path, check_crc=check_crc, exact_rates=exact_rates)
    except (BagError, StorageError) as exc:
        return str(exc)
