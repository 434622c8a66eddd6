"""Reading chunks: bounded decompression, CRC check, the walk over a chunk's records.

Decompression never produces more than the chunk declares, and a chunk may declare at most
``max_chunk_size`` bytes (:data:`DEFAULT_MAX_CHUNK_SIZE`), so a compression bomb costs one
error, not the machine's memory. Message positions come from the Message Index records as
numpy arrays (:func:`~bagkit.bag.mcapio.records.message_index_dtype`) instead of the ``mcap``
package's reader, which builds a Python object per message: kept for "read 100,000 messages ...
bagkit/mcap reader" of ``python -m benchmarks info`` (figures in benchmarks/README.md,
"bagkit.bag.mcapio"), or, for chunks without them, from :func:`walk_chunk`. numpy is imported
by the functions that use it: ``bagkit info`` starts without numpy (benchmarks/README.md,
start-up).
"""

from __future__ import annotations

import sys
from array import array
from collections.abc import Mapping
from collections.abc import Set as AbstractSet
from dataclasses import dataclass
from itertools import chain
from typing import TYPE_CHECKING, TypeGuard

import zstandard

# zlib-ng's CRC-32 (same polynomial as zlib's) is many times faster than zlib's (PCLMUL), and
# every chunk is checksummed on write and on read.
from zlib_ng.zlib_ng import crc32

from bagkit.bag.errors import ChunkError, CorruptBagError
from bagkit.bag.mcapio.message_index import index_arrays, message_index_bytes
from bagkit.bag.mcapio.records import (
    MESSAGE_INDEX_ENTRY_SIZE,
    MESSAGE_PREFIX,
    MESSAGE_RECORD_HEADER,
    RECORD_HEADER,
    Channel,
    Chunk,
    ChunkIndex,
    Opcode,
    Schema,
    iter_records,
    parse_channel,
    parse_chunk,
    parse_schema,
)
from bagkit.bag.mcapio.source import Source
from bagkit.words import counted

if TYPE_CHECKING:
    import numpy as np

# A chunk holds at least its largest message: 256 MiB admits any ROS 2 message seen in practice
# (an uncompressed 8K RGB image is 100 MB) while a reader holds only a few chunks at a time.
DEFAULT_MAX_CHUNK_SIZE = 256 << 20
# Incompressible records come out of zstd/lz4 slightly larger than they went in; a chunk record
# is refused beyond this multiple of the maximum chunk size.
_MAX_COMPRESSED_RATIO = 2


@dataclass(frozen=True, slots=True)
class MessageRun:
    """Consecutive Message records outside any chunk (unchunked files), found by scanning."""

    offset: int
    length: int
    message_start_time: int
    message_end_time: int


Block = ChunkIndex | MessageRun
"""Where messages are stored: a chunk (by its index) or a run of loose messages."""


@dataclass(frozen=True, slots=True)
class ChunkContents:
    """The decompressed records of one chunk and where each channel's messages are in them.

    ``entries[channel_id]`` holds the channel's Message Index entries as stored (16 bytes each,
    ``log_time`` and ``offset`` of the Message record in ``records``, little-endian) in the
    order the messages were written; offsets are as stored (check them with
    :func:`payload_spans`). Kept as bytes: the message-by-message path orders them without
    numpy (:func:`~bagkit.bag.mcapio.message_index.ordered_offsets`).
    """

    records: bytes
    entries: Mapping[int, bytes | memoryview]

    @property
    def message_index(self) -> dict[int, np.ndarray]:
        """``entries`` as ``message_index_dtype`` arrays (views of the same bytes)."""
        return index_arrays(self.entries)


def extent(block: Block) -> tuple[int, int]:
    """(offset, length) of a chunk record or a run of loose messages in its file."""
    if isinstance(block, MessageRun):
        return block.offset, block.length
    return block.chunk_start_offset, block.chunk_length


def indexed(block: Block) -> TypeGuard[ChunkIndex]:
    """True for a chunk with Message Index records (not a salvaged one, nor loose messages)."""
    return isinstance(block, ChunkIndex) and bool(block.message_index_offsets)


def may_hold(block: Block, channel_ids: AbstractSet[int]) -> bool:
    """False when a chunk's message indexes show none of ``channel_ids`` (skip reading it)."""
    if indexed(block):
        return not channel_ids.isdisjoint(block.message_index_offsets)
    return True


def decompress(
    compression: str, data: bytes | bytearray | memoryview, size: int, max_size: int
) -> bytes:
    """Decompress chunk records (``""``, ``zstd`` or ``lz4``) declared to be ``size`` bytes.

    Never allocates more than ``size`` bytes (plus one) of output, whatever the data says.

    Raises:
        ChunkError: ``size`` over ``max_size``, unknown compression, data that does not
            decompress to exactly ``size`` bytes.
    """
    if size > max_size:
        raise ChunkError(
            f"declares {size} bytes uncompressed, over the maximum chunk size of {max_size}"
        )
    if compression == "":
        return bytes(data)
    if size == 0:  # zstd reads max_output_size=0 as "no limit"
        raise ChunkError(f"{compression} chunk declares 0 bytes uncompressed")
    try:
        if compression == "zstd":
            declared = zstandard.frame_content_size(data)
            if declared not in (-1, size):
                raise ChunkError(f"zstd frame holds {declared} bytes, the chunk declares {size}")
            out = zstandard.ZstdDecompressor().decompress(data, max_output_size=size)
        elif compression == "lz4":
            import lz4.frame  # lz4 chunks only: rosbag2 and bagkit write zstd by default

            out = lz4.frame.LZ4FrameDecompressor().decompress(data, max_length=size + 1)
        else:
            raise ChunkError(f"unsupported chunk compression {compression!r}")
    except (zstandard.ZstdError, RuntimeError) as exc:
        raise ChunkError(f"{compression} data does not decompress ({exc})") from None
    if len(out) != size:
        raise ChunkError(f"{compression} data does not decompress to the declared {size} bytes")
    return out


def _read_chunk_record(source: Source, offset: int, max_size: int) -> tuple[Chunk, int]:
    """The Chunk record at ``offset`` (its data still compressed) and its whole length."""
    opcode, length = RECORD_HEADER.unpack(source.read(offset, RECORD_HEADER.size))
    if opcode != Opcode.CHUNK:
        raise ChunkError("no chunk record there")
    if length > _MAX_COMPRESSED_RATIO * max_size:
        raise ChunkError(
            f"a chunk record of {length} bytes, over the maximum chunk size of {max_size}"
        )
    content = source.read(offset + RECORD_HEADER.size, length)
    return parse_chunk(memoryview(content)), RECORD_HEADER.size + length


def _load(source: Source, block: Block, check_crc: bool, max_size: int) -> tuple[bytes, bool]:
    """A block's records, and whether its index agrees with the chunk record found.

    Raises:
        ChunkError: see :func:`read_block_records`.
    """
    offset, length = extent(block)
    try:
        if isinstance(block, MessageRun):
            if length > max_size:
                raise ChunkError(f"{length} bytes of messages, over the maximum of {max_size}")
            return source.read(offset, length), True
        chunk, record_length = _read_chunk_record(source, offset, max_size)
    except ChunkError:
        raise
    except CorruptBagError as exc:
        raise ChunkError(str(exc)) from None
    records = decompress(chunk.compression, chunk.data, chunk.uncompressed_size, max_size)
    if check_crc and chunk.uncompressed_crc and crc32(records) != chunk.uncompressed_crc:
        raise ChunkError("CRC mismatch (the chunk is damaged)")
    agrees = (
        record_length == block.chunk_length
        and chunk.uncompressed_size == block.uncompressed_size
        and chunk.message_start_time == block.message_start_time
        and chunk.message_end_time == block.message_end_time
    )
    return records, agrees


def read_block_records(
    source: Source, block: Block, *, check_crc: bool = True, max_size: int = DEFAULT_MAX_CHUNK_SIZE
) -> bytes:
    """The records of a chunk (decompressed, CRC-checked) or of a run of loose messages.

    Raises:
        ChunkError: no chunk record where the block says, one over ``max_size``, data that
            does not decompress to its declared size, or a CRC mismatch.
    """
    return _load(source, block, check_crc, max_size)[0]


@dataclass(frozen=True, slots=True)
class MessagePositions:
    """Where the Message records of a walked chunk are (:func:`walk_chunk`).

    ``by_channel[channel_id]`` holds ``(log_time, offset)`` of each of the channel's Message
    records in stored order; ``offset`` is the record's start in the walked buffer, and the
    whole record lies inside it.
    """

    by_channel: dict[int, list[tuple[int, int]]]

    def counts(self) -> dict[int, int]:
        """Messages per channel."""
        return {channel_id: len(found) for channel_id, found in self.by_channel.items()}

    def entries(self) -> dict[int, bytes]:
        """The positions as the entries of Message Index records (16 bytes each)."""
        packed = {}
        for channel_id, found in self.by_channel.items():
            words = array("Q", chain.from_iterable(found))
            if sys.byteorder == "big":  # MCAP is little-endian
                words.byteswap()
            packed[channel_id] = words.tobytes()
        return packed

    def message_index(self) -> dict[int, np.ndarray]:
        """The positions as ``message_index_dtype`` arrays, like Message Index records."""
        return index_arrays(self.entries())


def walk_chunk(
    records: bytes | memoryview,
    *,
    schemas: dict[int, Schema] | None = None,
    channels: dict[int, Channel] | None = None,
) -> MessagePositions:
    """Walk the records of a decompressed chunk (or of a run of loose messages).

    The one walker over the records inside a chunk: the reader (chunks without usable Message
    Index records), salvage and ``bagkit doctor`` use it. Each record's length is checked
    against ``records``, and each Message record's against its fixed fields, before it is read.

    Args:
        records: the chunk's records.
        schemas, channels: when given, the Schema and Channel records met are parsed (bounded)
            and added to them (the first of an id is kept); rosbag2 writes them inside chunks.
            Those met before a damaged record are kept.

    Raises:
        CorruptBagError: a record runs past the end, a Message record is too short, or a
            Schema or Channel record asked for is malformed.
    """
    by_channel: dict[int, list[tuple[int, int]]] = {}
    unpack = MESSAGE_PREFIX.unpack_from
    for offset, opcode, content in iter_records(records):
        if opcode == Opcode.MESSAGE:
            if len(content) < MESSAGE_PREFIX.size:
                raise CorruptBagError(f"message record at byte {offset} is too short")
            channel_id, _, log_time, _ = unpack(content)
            found = by_channel.get(channel_id)
            if found is None:
                found = by_channel[channel_id] = []
            found.append((log_time, offset))
        elif opcode == Opcode.SCHEMA and schemas is not None:
            schema = parse_schema(content)
            schemas.setdefault(schema.id, schema)
        elif opcode == Opcode.CHANNEL and channels is not None:
            channel = parse_channel(content)
            channels.setdefault(channel.id, channel)
    return MessagePositions(by_channel)


def read_chunk(
    source: Source, block: Block, *, check_crc: bool = True, max_size: int = DEFAULT_MAX_CHUNK_SIZE
) -> ChunkContents:
    """Read one chunk (or run of loose messages) with the message positions of each channel.

    Uses the Message Index records after the chunk when the chunk index agrees with the chunk
    record and they are where it says; otherwise (swapped or damaged indexes, chunks without
    indexes) the positions are found by walking the records.

    Raises:
        ChunkError: the chunk cannot be read (see :func:`read_block_records`), or its records
            are damaged.
    """
    records, agrees = _load(source, block, check_crc, max_size)
    try:
        if agrees and isinstance(block, ChunkIndex) and block.message_index_offsets:
            try:
                return ChunkContents(records, message_index_bytes(source, block))
            except CorruptBagError:
                pass  # the records themselves are intact: find the messages in them
        return ChunkContents(records, walk_chunk(records).entries())
    except CorruptBagError as exc:
        raise ChunkError(str(exc)) from None


def count_messages(source: Source, block: Block) -> int | None:
    """Messages in a chunk from its Message Index records, without reading it (None: unknown)."""
    if not isinstance(block, ChunkIndex):
        return None
    try:
        indexes = message_index_bytes(source, block)
    except CorruptBagError:
        return None
    return sum(len(e) for e in indexes.values()) // MESSAGE_INDEX_ENTRY_SIZE if indexes else None


def unreadable_chunk(name: str, source: Source, block: Block, what: str) -> str:
    """The problem line of a block of file ``name`` that cannot be read: where it is, ``what``
    went wrong, and the messages lost with it (as its Message Index records count them)."""
    offset, length = extent(block)
    lost = count_messages(source, block)
    return f"{name}: chunk at byte {offset} ({length} bytes) unreadable: {what}; " + (
        f"{counted(lost, 'message')} lost" if lost is not None else "its messages are lost"
    )


def payload_spans(
    records: bytes, entries: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Where the payload of each indexed message is in ``records``.

    Args:
        records: a chunk's decompressed records.
        entries: ``message_index_dtype`` entries of messages in it.

    Returns:
        ``(log_times, starts, lengths, dropped)``: int64 arrays for the entries that point at a
        whole Message record inside ``records``, and how many did not (dropped).
    """
    import numpy as np
    from numpy.lib.stride_tricks import sliding_window_view

    size = len(records)
    offsets = entries["offset"]
    if size >= MESSAGE_RECORD_HEADER.size:
        keep = offsets <= size - MESSAGE_RECORD_HEADER.size
    else:
        keep = np.zeros(len(entries), dtype=bool)
    positions = offsets[keep].astype(np.int64)
    buf = np.frombuffer(records, dtype=np.uint8)
    lengths = np.zeros(len(positions), dtype=np.uint64)
    if len(positions):
        opcodes = buf[positions]
        lengths = sliding_window_view(buf, 8)[positions + 1].view("<u8").ravel()
        room = (size - RECORD_HEADER.size - positions).astype(np.uint64)
        whole = (opcodes == Opcode.MESSAGE) & (lengths >= MESSAGE_PREFIX.size) & (lengths <= room)
        keep[np.flatnonzero(keep)[~whole]] = False
        positions, lengths = positions[whole], lengths[whole]
    dropped = int(len(entries) - keep.sum())
    return (
        entries["log_time"][keep].astype(np.int64),
        positions + MESSAGE_RECORD_HEADER.size,
        lengths.astype(np.int64) - MESSAGE_PREFIX.size,
        dropped,
    )


# publish_time (u64) is the Message record's last field before its payload.
_PUBLISH_TIME_SIZE = 8


def payload_publish_times(records: bytes, starts: np.ndarray) -> np.ndarray:
    """The ``publish_time`` (int64 ns) of the messages whose payloads :func:`payload_spans`
    found at ``starts``: the last field of the Message record before its payload."""
    import numpy as np
    from numpy.lib.stride_tricks import sliding_window_view

    if not len(starts):
        return np.empty(0, dtype=np.int64)
    buf = np.frombuffer(records, dtype=np.uint8)
    before = starts - _PUBLISH_TIME_SIZE
    return sliding_window_view(buf, _PUBLISH_TIME_SIZE)[before].view("<u8").ravel().astype(np.int64)
