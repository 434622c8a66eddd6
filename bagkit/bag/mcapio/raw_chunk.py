"""A chunk as stored, ready to be written into another file without recompression.

Surgery (``bagkit filter``/``merge``/``recover``) copies a chunk whose messages all pass: the
Chunk record's bytes go out unchanged, its Message Index records are re-encoded from the entries
(the offsets inside the chunk do not change).
"""

from __future__ import annotations

from zlib_ng.zlib_ng import crc32

from bagkit.bag.errors import ChunkError, CorruptBagError
from bagkit.bag.mcapio.chunk_builder import ClosedChunk
from bagkit.bag.mcapio.chunks import DEFAULT_MAX_CHUNK_SIZE, decompress, walk_chunk
from bagkit.bag.mcapio.message_index import message_index_bytes
from bagkit.bag.mcapio.records import (
    MESSAGE_INDEX_ENTRY_SIZE,
    RECORD_HEADER,
    Chunk,
    ChunkIndex,
    Opcode,
    encode_message_index,
    iter_records,
    parse_chunk,
    parse_message_index,
)
from bagkit.bag.mcapio.source import Source

_MAX_COMPRESSED_RATIO = 2


def read_raw_chunk(
    source: Source,
    chunk_index: ChunkIndex,
    *,
    check_crc: bool = True,
    max_size: int = DEFAULT_MAX_CHUNK_SIZE,
) -> ClosedChunk:
    """The Chunk record at ``chunk_index`` as it is stored, with its Message Index records.

    With ``check_crc`` the records are decompressed to check the CRC (they are not recompressed:
    the stored bytes are what is returned). Message indexes come from the records after the
    chunk when they are where the index says, otherwise from walking the decompressed records.

    Raises:
        ChunkError: no chunk record there, one over ``max_size``, data that does not
            decompress to its declared size, a CRC mismatch, damaged records.
    """
    offset = chunk_index.chunk_start_offset
    try:
        opcode, length = RECORD_HEADER.unpack(source.read(offset, RECORD_HEADER.size))
        if opcode != Opcode.CHUNK or length > _MAX_COMPRESSED_RATIO * max_size:
            raise ChunkError("no chunk record of a readable size there")
        record = source.read(offset, RECORD_HEADER.size + length)
        chunk = parse_chunk(memoryview(record)[RECORD_HEADER.size :])
    except ChunkError:
        raise
    except CorruptBagError as exc:
        raise ChunkError(str(exc)) from None
    records: bytes | None = None
    if check_crc or not chunk_index.message_index_offsets:
        crc = chunk.uncompressed_crc if check_crc else 0
        records = _decompressed(
            chunk.compression, chunk.data, chunk.uncompressed_size, crc, max_size
        )
    indexes = _message_indexes(source, chunk_index, chunk, records, max_size)
    header_length = len(record) - len(chunk.data)
    parts = []
    offsets: dict[int, int] = {}
    position = 0
    for channel_id, entries in sorted(indexes.items()):
        part = encode_message_index(channel_id, bytes(entries))
        offsets[channel_id] = position
        position += len(part)
        parts.append(part)
    return ClosedChunk(
        header=record[:header_length],
        pieces=(memoryview(record)[header_length:],),  # the data as read: not copied again
        message_indexes=b"".join(parts),
        index_offsets=offsets,
        message_start_time=chunk.message_start_time,
        message_end_time=chunk.message_end_time,
        compression=chunk.compression,
        uncompressed_size=chunk.uncompressed_size,
        message_counts={c: len(e) // MESSAGE_INDEX_ENTRY_SIZE for c, e in indexes.items()},
        uncompressed_crc=chunk.uncompressed_crc,
    )


def _message_indexes(
    source: Source, chunk_index: ChunkIndex, chunk: Chunk, records: bytes | None, max_size: int
) -> dict[int, bytes | memoryview]:
    """The chunk's Message Index entries as stored, by channel: from its records after it
    when they are where the index says, otherwise from walking its (decompressed) records."""
    try:
        indexes: dict[int, bytes | memoryview] = dict(message_index_bytes(source, chunk_index))
    except CorruptBagError:
        indexes = {}
    if indexes:
        return indexes
    try:
        if records is None:
            records = decompress(chunk.compression, chunk.data, chunk.uncompressed_size, max_size)
        return dict(walk_chunk(records).entries())
    except CorruptBagError as exc:
        raise ChunkError(str(exc)) from None


def stored_in_log_time_order(chunk: ClosedChunk) -> bool:
    """Whether the chunk's messages are stored in log-time order, from its Message Index
    records (nothing decompressed). Recorders writing per-topic batches store them out of it."""
    import numpy as np

    parts = [
        parse_message_index(content)[1]
        for _, opcode, content in iter_records(chunk.message_indexes)
        if opcode == Opcode.MESSAGE_INDEX
    ]
    if len(parts) > 1:
        entries = np.concatenate(parts)
        entries = entries[np.argsort(entries["offset"], kind="stable")]
    elif parts:
        entries = parts[0]
    else:
        return True
    times = entries["log_time"]
    return bool((times[1:] >= times[:-1]).all())


def check_raw_chunk(chunk: ClosedChunk, max_size: int = DEFAULT_MAX_CHUNK_SIZE) -> None:
    """Check a chunk read with ``check_crc=False``: it decompresses to its size and CRC.

    Thread-safe (it only reads ``chunk``), so copies can check chunks on other cores.

    Raises:
        ChunkError: the data does not decompress to its declared size, or a CRC mismatch.
    """
    _decompressed(
        chunk.compression, chunk.data, chunk.uncompressed_size, chunk.uncompressed_crc, max_size
    )


def _decompressed(
    compression: str, data: bytes | bytearray | memoryview, size: int, crc: int, max_size: int
) -> bytes:
    """The chunk's records, checked against ``crc`` unless it is 0 (MCAP's "no CRC")."""
    records = decompress(compression, data, size, max_size)
    if crc and crc32(records) != crc:
        raise ChunkError("CRC mismatch (the chunk is damaged)")
    return records
