"""The bag itself, without ROS: read and write rosbag2-compatible MCAP bags.

See docs/architecture.md ("bagkit.bag") and docs/bag-format.md.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from bagkit.bag.definitions import message_definition, type_description_hash
from bagkit.bag.errors import (
    BagError,
    BagExistsError,
    BagNotFoundError,
    BagWriteError,
    ChunkError,
    CorruptBagError,
    EmptyBagError,
    NotABagError,
    UnknownMessageTypeError,
    UnsupportedStorageError,
)
from bagkit.bag.messages import BagMessage, TopicInfo

if TYPE_CHECKING:
    from bagkit.bag.info import BagInfo, TopicSummary, bag_info
    from bagkit.bag.reader import BagReader
    from bagkit.bag.storage import BagChunk
    from bagkit.bag.writer import BagWriter

__all__ = [
    "BagChunk",
    "BagError",
    "BagExistsError",
    "BagInfo",
    "BagMessage",
    "BagNotFoundError",
    "BagReader",
    "BagWriteError",
    "BagWriter",
    "ChunkError",
    "CorruptBagError",
    "EmptyBagError",
    "NotABagError",
    "TopicInfo",
    "TopicSummary",
    "UnknownMessageTypeError",
    "UnsupportedStorageError",
    "bag_info",
    "message_definition",
    "type_description_hash",
]


# Imported on first use: a command that reads a bag needs neither the writer nor ``bag_info``.
# Import statements, not importlib: ``-X importtime`` (tests/cli/test_startup_imports.py) and
# the layering test see them.
def __getattr__(name: str) -> object:
    if name in ("BagInfo", "TopicSummary", "bag_info"):
        from bagkit.bag import info

        return getattr(info, name)
    if name == "BagReader":
        from bagkit.bag import reader

        return getattr(reader, name)
    if name == "BagChunk":
        from bagkit.bag import storage

        return getattr(storage, name)
    if name == "BagWriter":
        from bagkit.bag import writer

        return getattr(writer, name)
    raise AttributeError(f"module 'bagkit.bag' has no attribute {name!r}")
