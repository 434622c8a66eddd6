"""The bag itself, without ROS: read and write rosbag2-compatible MCAP bags.

See docs/architecture.md ("bagkit.bag") and docs/bag-format.md.
"""

from __future__ import annotations

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
from bagkit.bag.info import BagInfo, TopicSummary, bag_info
from bagkit.bag.messages import BagMessage, TopicInfo
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
