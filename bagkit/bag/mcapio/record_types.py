"""The summary-level MCAP records bagkit reads and writes, as NamedTuples.

The fields (names and order) are the ``mcap`` package's record dataclasses'. Every command
that reads a bag builds these from its summary at start, where creating the package's 16
dataclasses costs more than reading a small bag's summary; the package's classes are imported
only to encode (:func:`bagkit.bag.mcapio.records.encode`). A record is changed with
``_replace``.
"""

from __future__ import annotations

from typing import NamedTuple


class Header(NamedTuple):
    profile: str
    library: str


class Footer(NamedTuple):
    summary_start: int
    summary_offset_start: int
    summary_crc: int


class Schema(NamedTuple):
    id: int
    data: bytes
    encoding: str
    name: str


class Channel(NamedTuple):
    id: int
    topic: str
    message_encoding: str
    metadata: dict[str, str]
    schema_id: int


class Chunk(NamedTuple):
    compression: str
    data: bytes
    message_end_time: int
    message_start_time: int
    uncompressed_crc: int
    uncompressed_size: int


class ChunkIndex(NamedTuple):
    chunk_length: int
    chunk_start_offset: int
    compression: str
    compressed_size: int
    message_end_time: int
    message_index_length: int
    message_index_offsets: dict[int, int]
    message_start_time: int
    uncompressed_size: int


class DataEnd(NamedTuple):
    data_section_crc: int


class Metadata(NamedTuple):
    name: str
    metadata: dict[str, str]


class MetadataIndex(NamedTuple):
    offset: int
    length: int
    name: str


class Statistics(NamedTuple):
    attachment_count: int
    channel_count: int
    channel_message_counts: dict[int, int]
    chunk_count: int
    message_count: int
    message_end_time: int
    message_start_time: int
    metadata_count: int
    schema_count: int


class SummaryOffset(NamedTuple):
    group_opcode: int
    group_start: int
    group_length: int


Record = (
    Header
    | Footer
    | Schema
    | Channel
    | Chunk
    | ChunkIndex
    | DataEnd
    | Metadata
    | MetadataIndex
    | Statistics
    | SummaryOffset
)
