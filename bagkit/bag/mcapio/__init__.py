"""The MCAP record layer, split by concern; works on bytes and open files, knows nothing of ROS.

- :mod:`~bagkit.bag.mcapio.records`: framing, bounded parsing, encoding (``mcap`` record types)
- :mod:`~bagkit.bag.mcapio.source`: a file whose size bounds every read
- :mod:`~bagkit.bag.mcapio.summary`: :class:`FileIndex` from the summary section
- :mod:`~bagkit.bag.mcapio.salvage`: :func:`read_file_index` (summary, or a scan without one)
- :mod:`~bagkit.bag.mcapio.data_section`: the data section's records, walked (salvage, doctor)
- :mod:`~bagkit.bag.mcapio.chunks`: bounded decompression, CRC, the walk over a chunk's records,
  message positions, payload spans
- :mod:`~bagkit.bag.mcapio.message_index`: Message Index records; first/last times per channel
- :mod:`~bagkit.bag.mcapio.chunk_builder`, :mod:`~bagkit.bag.mcapio.file_writer`: writing

Spec: https://mcap.dev/spec
"""

from __future__ import annotations

from bagkit.bag.mcapio.chunks import (
    DEFAULT_MAX_CHUNK_SIZE,
    Block,
    ChunkContents,
    MessageRun,
    count_messages,
    extent,
    indexed,
    may_hold,
    payload_spans,
    read_chunk,
    unreadable_chunk,
)
from bagkit.bag.mcapio.records import MAGIC, message_index_dtype
from bagkit.bag.mcapio.salvage import read_file_index
from bagkit.bag.mcapio.source import Source
from bagkit.bag.mcapio.summary import FileIndex

__all__ = [
    "DEFAULT_MAX_CHUNK_SIZE",
    "MAGIC",
    "Block",
    "ChunkContents",
    "FileIndex",
    "MessageRun",
    "Source",
    "count_messages",
    "extent",
    "indexed",
    "may_hold",
    "message_index_dtype",
    "payload_spans",
    "read_chunk",
    "read_file_index",
    "unreadable_chunk",
]
