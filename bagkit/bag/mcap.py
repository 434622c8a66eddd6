"""The MCAP record layer: record dataclasses named like the spec, parsing, scanning, chunks.

Everything here works on bytes and open files and knows nothing of ROS. ``BagReader`` builds on
:func:`read_file_index` (summary when present, salvage scan otherwise) and :func:`read_chunk`
(decompressed chunk records plus message-index offsets per channel, for bulk decoding).

Spec: https://mcap.dev/spec
"""

from __future__ import annotations

import contextlib
import enum
import struct
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import BinaryIO

import lz4.frame
import numpy as np
import zstandard

# zlib-ng's CRC-32 (same polynomial as zlib's) runs at ~17x zlib's speed here (PCLMUL), and
# every chunk is checksummed on write and on verified reads.
from zlib_ng.zlib_ng import crc32

from bagkit.bag.errors import CorruptBagError, NotABagError

MAGIC = b"\x89MCAP0\r\n"
RECORD_HEADER = struct.Struct("<BQ")
# Message record content before the payload: channel_id, sequence, log_time, publish_time.
MESSAGE_PREFIX = struct.Struct("<HIQQ")
# A whole message record header (opcode, length, then MESSAGE_PREFIX); the payload follows.
MESSAGE_RECORD_HEADER = struct.Struct("<BQHIQQ")
MESSAGE_DATA_OFFSET = MESSAGE_RECORD_HEADER.size  # payload offset from the record start
# One entry of a Message Index record, as a numpy dtype: (log_time, offset in the chunk records).
MESSAGE_INDEX_DTYPE = np.dtype([("log_time", "<u8"), ("offset", "<u8")])

_U16 = struct.Struct("<H")
_U32 = struct.Struct("<I")
_U64 = struct.Struct("<Q")
_CHUNK_PREFIX = struct.Struct("<QQQI")
_CHUNK_INDEX_PREFIX = struct.Struct("<QQQQ")
_STATISTICS_PREFIX = struct.Struct("<QHIIIIQQ")
_FOOTER = struct.Struct("<QQI")
_SUMMARY_OFFSET = struct.Struct("<BQQ")
# Loose messages are grouped into runs of at most this many bytes, read like chunks.
_MAX_RUN_BYTES = 1 << 20


class Opcode(enum.IntEnum):
    """MCAP record opcodes."""

    HEADER = 0x01
    FOOTER = 0x02
    SCHEMA = 0x03
    CHANNEL = 0x04
    MESSAGE = 0x05
    CHUNK = 0x06
    MESSAGE_INDEX = 0x07
    CHUNK_INDEX = 0x08
    ATTACHMENT = 0x09
    ATTACHMENT_INDEX = 0x0A
    STATISTICS = 0x0B
    METADATA = 0x0C
    METADATA_INDEX = 0x0D
    SUMMARY_OFFSET = 0x0E
    DATA_END = 0x0F


@dataclass(frozen=True, slots=True)
class Header:
    """Header record."""

    profile: str
    library: str


@dataclass(frozen=True, slots=True)
class Footer:
    """Footer record."""

    summary_start: int
    summary_offset_start: int
    summary_crc: int


@dataclass(frozen=True, slots=True)
class Schema:
    """Schema record."""

    id: int
    name: str
    encoding: str
    data: bytes


@dataclass(frozen=True, slots=True)
class Channel:
    """Channel record."""

    id: int
    schema_id: int
    topic: str
    message_encoding: str
    metadata: dict[str, str]


@dataclass(frozen=True, slots=True)
class Message:
    """Message record."""

    channel_id: int
    sequence: int
    log_time: int
    publish_time: int
    data: bytes


@dataclass(frozen=True, slots=True)
class Chunk:
    """Chunk record; ``records`` is still compressed."""

    message_start_time: int
    message_end_time: int
    uncompressed_size: int
    uncompressed_crc: int
    compression: str
    records: bytes


@dataclass(slots=True)
class ChunkIndex:
    """Chunk Index record (also built by the salvage scan for files without a summary)."""

    message_start_time: int
    message_end_time: int
    chunk_start_offset: int
    chunk_length: int
    message_index_offsets: dict[int, int]
    message_index_length: int
    compression: str
    compressed_size: int
    uncompressed_size: int


@dataclass(frozen=True, slots=True)
class Statistics:
    """Statistics record."""

    message_count: int
    schema_count: int
    channel_count: int
    attachment_count: int
    metadata_count: int
    chunk_count: int
    message_start_time: int
    message_end_time: int
    channel_message_counts: dict[int, int]


@dataclass(frozen=True, slots=True)
class Metadata:
    """Metadata record."""

    name: str
    metadata: dict[str, str]


@dataclass(frozen=True, slots=True)
class MetadataIndex:
    """Metadata Index record."""

    offset: int
    length: int
    name: str


@dataclass(frozen=True, slots=True)
class MessageRun:
    """Consecutive Message records outside any chunk (unchunked files), found by scanning."""

    offset: int
    length: int
    message_start_time: int
    message_end_time: int


@dataclass(slots=True)
class FileIndex:
    """What one MCAP file holds, from its summary or, when it has none, from a salvage scan.

    Attributes:
        summary: True when the file's summary section was used (the file was closed cleanly).
        channel_message_counts: messages per channel id.
        problems: what the scan could not read (empty for intact files).
    """

    header: Header
    schemas: dict[int, Schema] = field(default_factory=dict)
    channels: dict[int, Channel] = field(default_factory=dict)
    chunk_indexes: list[ChunkIndex] = field(default_factory=list)
    message_runs: list[MessageRun] = field(default_factory=list)
    channel_message_counts: dict[int, int] = field(default_factory=dict)
    message_start_time: int = 0
    message_end_time: int = 0
    metadata: list[Metadata] = field(default_factory=list)
    summary: bool = False
    problems: list[str] = field(default_factory=list)

    @property
    def message_count(self) -> int:
        """Messages in the file."""
        return sum(self.channel_message_counts.values())


@dataclass(frozen=True, slots=True)
class ChunkData:
    """The decompressed records of one chunk and where each channel's messages are in them.

    ``message_index[channel_id]`` is a structured array (``MESSAGE_INDEX_DTYPE``: ``log_time``,
    ``offset``) in the order the messages were written; ``offset`` is the start of the Message
    record in ``records``, so the payload starts at ``offset + MESSAGE_DATA_OFFSET`` and its length
    is the record length (``u64`` at ``offset + 1``) minus ``MESSAGE_PREFIX.size``.
    """

    records: bytes
    message_index: dict[int, np.ndarray]


class _Cursor:
    """Reads the primitive MCAP types from a buffer, advancing an offset."""

    __slots__ = ("buf", "pos")

    def __init__(self, buf: bytes | memoryview, pos: int = 0) -> None:
        self.buf = buf
        self.pos = pos

    def u16(self) -> int:
        (value,) = _U16.unpack_from(self.buf, self.pos)
        self.pos += 2
        return int(value)

    def u32(self) -> int:
        (value,) = _U32.unpack_from(self.buf, self.pos)
        self.pos += 4
        return int(value)

    def u64(self) -> int:
        (value,) = _U64.unpack_from(self.buf, self.pos)
        self.pos += 8
        return int(value)

    def raw(self, length: int) -> bytes:
        if self.pos + length > len(self.buf):
            raise CorruptBagError("record field runs past the end of its record")
        value = bytes(self.buf[self.pos : self.pos + length])
        self.pos += length
        return value

    def string(self) -> str:
        return self.raw(self.u32()).decode("utf-8")

    def string_map(self) -> dict[str, str]:
        size = self.u32()
        end = self.pos + size
        result: dict[str, str] = {}
        while self.pos < end:
            key = self.string()
            result[key] = self.string()
        return result

    def int_map(self, key_format: str) -> dict[int, int]:
        size = self.u32()
        entry = struct.Struct(f"<{key_format}Q")
        items = entry.iter_unpack(self.raw(size))
        return {int(k): int(v) for k, v in items}


def parse_header(content: bytes | memoryview) -> Header:
    """Parse a Header record's content."""
    cur = _Cursor(content)
    return Header(profile=cur.string(), library=cur.string())


def parse_footer(content: bytes | memoryview) -> Footer:
    """Parse a Footer record's content."""
    return Footer(*_FOOTER.unpack_from(content))


def parse_schema(content: bytes | memoryview) -> Schema:
    """Parse a Schema record's content."""
    cur = _Cursor(content)
    return Schema(id=cur.u16(), name=cur.string(), encoding=cur.string(), data=cur.raw(cur.u32()))


def parse_channel(content: bytes | memoryview) -> Channel:
    """Parse a Channel record's content."""
    cur = _Cursor(content)
    return Channel(
        id=cur.u16(),
        schema_id=cur.u16(),
        topic=cur.string(),
        message_encoding=cur.string(),
        metadata=cur.string_map(),
    )


def parse_message(content: bytes | memoryview) -> Message:
    """Parse a Message record's content."""
    channel_id, sequence, log_time, publish_time = MESSAGE_PREFIX.unpack_from(content)
    return Message(channel_id, sequence, log_time, publish_time, bytes(content[22:]))


def parse_chunk(content: bytes | memoryview) -> Chunk:
    """Parse a Chunk record's content."""
    start, end, uncompressed_size, crc = _CHUNK_PREFIX.unpack_from(content)
    cur = _Cursor(content, _CHUNK_PREFIX.size)
    compression = cur.string()
    records = cur.raw(cur.u64())
    return Chunk(start, end, uncompressed_size, crc, compression, records)


def parse_message_index(content: bytes | memoryview) -> tuple[int, np.ndarray]:
    """Parse a Message Index record's content into (channel id, ``MESSAGE_INDEX_DTYPE`` array)."""
    cur = _Cursor(content)
    channel_id = cur.u16()
    size = cur.u32()
    entries = np.frombuffer(cur.raw(size), dtype=MESSAGE_INDEX_DTYPE)
    return channel_id, entries


def parse_chunk_index(content: bytes | memoryview) -> ChunkIndex:
    """Parse a Chunk Index record's content."""
    start, end, offset, length = _CHUNK_INDEX_PREFIX.unpack_from(content)
    cur = _Cursor(content, _CHUNK_INDEX_PREFIX.size)
    offsets = cur.int_map("H")
    index_length = cur.u64()
    compression = cur.string()
    compressed_size = cur.u64()
    uncompressed_size = cur.u64()
    return ChunkIndex(
        start,
        end,
        offset,
        length,
        offsets,
        index_length,
        compression,
        compressed_size,
        uncompressed_size,
    )


def parse_statistics(content: bytes | memoryview) -> Statistics:
    """Parse a Statistics record's content."""
    message_count, schemas, channels, attachments, metadata, chunks, start, end = (
        _STATISTICS_PREFIX.unpack_from(content)
    )
    cur = _Cursor(content, _STATISTICS_PREFIX.size)
    return Statistics(
        message_count,
        schemas,
        channels,
        attachments,
        metadata,
        chunks,
        start,
        end,
        cur.int_map("H"),
    )


def parse_metadata(content: bytes | memoryview) -> Metadata:
    """Parse a Metadata record's content."""
    cur = _Cursor(content)
    return Metadata(name=cur.string(), metadata=cur.string_map())


def parse_metadata_index(content: bytes | memoryview) -> MetadataIndex:
    """Parse a Metadata Index record's content."""
    cur = _Cursor(content)
    return MetadataIndex(offset=cur.u64(), length=cur.u64(), name=cur.string())


def iter_records(buf: bytes | memoryview, start: int = 0) -> Iterator[tuple[int, int, memoryview]]:
    """Yield ``(offset, opcode, content)`` for each complete record of ``buf`` from ``start``.

    Stops silently at an incomplete trailing record; chunk records are not opened.
    """
    view = memoryview(buf)
    end = len(view)
    pos = start
    header_size = RECORD_HEADER.size
    while pos + header_size <= end:
        opcode, length = RECORD_HEADER.unpack_from(view, pos)
        content_start = pos + header_size
        if content_start + length > end:
            return
        yield pos, opcode, view[content_start : content_start + length]
        pos = content_start + length


def decompress(compression: str, data: bytes, uncompressed_size: int) -> bytes:
    """Decompress chunk records (``""``, ``zstd`` or ``lz4``).

    Raises:
        CorruptBagError: unknown compression or data that does not decompress.
    """
    try:
        if compression == "":
            return data
        if compression == "zstd":
            return zstandard.ZstdDecompressor().decompress(data, max_output_size=uncompressed_size)
        if compression == "lz4":
            return bytes(lz4.frame.decompress(data))
    except (zstandard.ZstdError, RuntimeError) as exc:
        raise CorruptBagError(f"{compression} chunk does not decompress: {exc}") from exc
    raise CorruptBagError(f"unsupported chunk compression {compression!r}")


def _read_exact(f: BinaryIO, offset: int, length: int) -> bytes:
    f.seek(offset)
    data = f.read(length)
    if len(data) != length:
        raise CorruptBagError(f"file ends inside a record at byte {offset}")
    return data


def read_header(f: BinaryIO) -> Header:
    """Check the leading magic and read the Header record.

    Raises:
        NotABagError: the file does not start with the MCAP magic.
        CorruptBagError: the header record is unreadable.
    """
    f.seek(0)
    start = f.read(len(MAGIC) + RECORD_HEADER.size)
    if not start.startswith(MAGIC):
        raise NotABagError("not an MCAP file (bad magic)")
    if len(start) < len(MAGIC) + RECORD_HEADER.size:
        raise CorruptBagError("MCAP file ends inside its header")
    opcode, length = RECORD_HEADER.unpack_from(start, len(MAGIC))
    if opcode != Opcode.HEADER:
        raise CorruptBagError("MCAP file does not start with a Header record")
    content = f.read(length)
    if len(content) != length:
        raise CorruptBagError("MCAP file ends inside its header")
    return parse_header(content)


def _read_summary(f: BinaryIO, file_size: int, header: Header) -> FileIndex | None:
    """Build the index from the summary section, or None when the file has no usable summary."""
    tail = len(MAGIC) + RECORD_HEADER.size + _FOOTER.size
    if file_size < len(MAGIC) + tail:
        return None
    f.seek(file_size - tail)
    end = f.read(tail)
    if end[-len(MAGIC) :] != MAGIC or end[0] != Opcode.FOOTER:
        return None
    footer = parse_footer(end[RECORD_HEADER.size :])
    if footer.summary_start == 0:
        return None
    footer_offset = file_size - tail
    summary = _read_exact(f, footer.summary_start, footer_offset - footer.summary_start)
    index = FileIndex(header=header, summary=True)
    statistics: Statistics | None = None
    metadata_indexes: list[MetadataIndex] = []
    for _, opcode, content in iter_records(summary):
        if opcode == Opcode.SCHEMA:
            schema = parse_schema(content)
            index.schemas[schema.id] = schema
        elif opcode == Opcode.CHANNEL:
            channel = parse_channel(content)
            index.channels[channel.id] = channel
        elif opcode == Opcode.CHUNK_INDEX:
            index.chunk_indexes.append(parse_chunk_index(content))
        elif opcode == Opcode.STATISTICS:
            statistics = parse_statistics(content)
        elif opcode == Opcode.METADATA_INDEX:
            metadata_indexes.append(parse_metadata_index(content))
    if statistics is None or (statistics.message_count and not index.chunk_indexes):
        # Counts are only in Statistics, and messages are found through chunk indexes: without
        # them (or in an unchunked file) the data section must be read.
        return None
    index.channel_message_counts = dict(statistics.channel_message_counts)
    # Chunk indexes before Statistics: the Go writer's statistics skip log_time 0.
    if index.chunk_indexes:
        index.message_start_time = min(c.message_start_time for c in index.chunk_indexes)
        index.message_end_time = max(c.message_end_time for c in index.chunk_indexes)
    else:
        index.message_start_time = statistics.message_start_time
        index.message_end_time = statistics.message_end_time
    for entry in metadata_indexes:
        record = _read_exact(f, entry.offset, entry.length)
        index.metadata.append(parse_metadata(record[RECORD_HEADER.size :]))
    return index


def _chunk_index_from_record(f: BinaryIO, pos: int, length: int) -> ChunkIndex:
    """Read a Chunk record's fixed fields (not its records) into a ChunkIndex without offsets."""
    f.seek(pos + RECORD_HEADER.size)
    prefix = f.read(min(length, _CHUNK_PREFIX.size + 4 + 256 + 8))
    start, end, uncompressed_size, _ = _CHUNK_PREFIX.unpack_from(prefix)
    cur = _Cursor(prefix, _CHUNK_PREFIX.size)
    compression = cur.string()
    compressed_size = cur.u64()
    return ChunkIndex(
        start,
        end,
        pos,
        RECORD_HEADER.size + length,
        {},
        0,
        compression,
        compressed_size,
        uncompressed_size,
    )


def _open_chunk(f: BinaryIO, chunk_index: ChunkIndex, index: FileIndex) -> dict[int, int]:
    """Decompress a chunk, check its CRC, keep schemas/channels found inside; count messages."""
    records = read_block_records(f, chunk_index, verify_crc=True)
    counts: dict[int, int] = {}
    for _, opcode, content in iter_records(records):
        if opcode == Opcode.MESSAGE:
            channel_id = _U16.unpack_from(content)[0]
            counts[channel_id] = counts.get(channel_id, 0) + 1
        elif opcode == Opcode.SCHEMA:
            schema = parse_schema(content)
            index.schemas.setdefault(schema.id, schema)
        elif opcode == Opcode.CHANNEL:
            channel = parse_channel(content)
            index.channels.setdefault(channel.id, channel)
    return counts


def _scan(f: BinaryIO, file_size: int, header: Header, name: str) -> FileIndex:
    """Salvage scan: walk the data section record by record, keeping everything intact.

    A chunk followed by its Message Index records is counted from them without being read;
    the last chunk before a cut, and chunks without indexes, are decompressed and checked.
    """
    index = FileIndex(header=header, summary=False)
    pos = len(MAGIC)
    stopped_at: int | None = None
    pending: ChunkIndex | None = None  # the last chunk, not yet counted
    pending_counts: dict[int, int] = {}  # from the Message Index records after it
    run: tuple[int, int, int, int] | None = None  # loose messages: start, end, first/last time

    def settle(trust_indexes: bool) -> None:
        nonlocal pending
        if pending is None:
            return
        chunk_index, pending = pending, None
        if trust_indexes and pending_counts:
            counts = dict(pending_counts)
        else:
            chunk_index.message_index_offsets = {}
            chunk_index.message_index_length = 0
            try:
                counts = _open_chunk(f, chunk_index, index)
            except (CorruptBagError, struct.error, UnicodeDecodeError) as exc:
                index.problems.append(
                    f"{name}: chunk at byte {chunk_index.chunk_start_offset} "
                    f"({chunk_index.chunk_length} bytes) unreadable ({exc}), skipped"
                )
                return
        if not counts:
            return
        for channel_id, count in counts.items():
            total = index.channel_message_counts.get(channel_id, 0) + count
            index.channel_message_counts[channel_id] = total
        index.chunk_indexes.append(chunk_index)

    while True:
        f.seek(pos)
        record_header = f.read(RECORD_HEADER.size)
        if len(record_header) < RECORD_HEADER.size:
            if record_header:
                stopped_at = pos
            break
        opcode, length = RECORD_HEADER.unpack(record_header)
        if pos + RECORD_HEADER.size + length > file_size:
            stopped_at = pos
            break
        try:
            if opcode == Opcode.MESSAGE_INDEX:
                if pending is not None:
                    content = f.read(length)
                    channel_id, entries = parse_message_index(content)
                    pending.message_index_offsets[channel_id] = pos
                    pending.message_index_length += RECORD_HEADER.size + length
                    pending_counts[channel_id] = len(entries)
            else:
                settle(trust_indexes=True)
                if opcode == Opcode.CHUNK:
                    pending = _chunk_index_from_record(f, pos, length)
                    pending_counts = {}
                elif opcode == Opcode.SCHEMA:
                    schema = parse_schema(f.read(length))
                    index.schemas[schema.id] = schema
                elif opcode == Opcode.CHANNEL:
                    channel = parse_channel(f.read(length))
                    index.channels[channel.id] = channel
                elif opcode == Opcode.METADATA:
                    index.metadata.append(parse_metadata(f.read(length)))
                elif opcode == Opcode.MESSAGE:
                    channel_id, _, log_time, _ = MESSAGE_PREFIX.unpack(f.read(MESSAGE_PREFIX.size))
                    counts = index.channel_message_counts
                    counts[channel_id] = counts.get(channel_id, 0) + 1
                    record_end = pos + RECORD_HEADER.size + length
                    if run is not None and run[1] == pos and run[1] - run[0] < _MAX_RUN_BYTES:
                        run = (run[0], record_end, min(run[2], log_time), max(run[3], log_time))
                    else:
                        if run is not None:
                            index.message_runs.append(MessageRun(run[0], run[1] - run[0], *run[2:]))
                        run = (pos, record_end, log_time, log_time)
                elif opcode in (Opcode.DATA_END, Opcode.FOOTER):
                    break
        except (CorruptBagError, struct.error, UnicodeDecodeError, ValueError) as exc:
            index.problems.append(f"{name}: unreadable record at byte {pos} ({exc}), skipped")
        pos += RECORD_HEADER.size + length
    # After a cut, the last chunk's indexes may be incomplete: count it from its records.
    settle(trust_indexes=stopped_at is None)
    if run is not None:
        index.message_runs.append(MessageRun(run[0], run[1] - run[0], run[2], run[3]))
    if stopped_at is not None:
        index.problems.append(
            f"{name}: truncated at byte {stopped_at}: "
            f"{file_size - stopped_at} bytes could not be read"
        )
    # Writers that put Schema/Channel records inside chunks: find the ones still missing.
    for chunk_index in index.chunk_indexes:
        if index.channel_message_counts.keys() <= index.channels.keys():
            break
        with contextlib.suppress(CorruptBagError, struct.error, UnicodeDecodeError):
            _open_chunk(f, chunk_index, index)
    blocks: list[ChunkIndex | MessageRun] = [*index.chunk_indexes, *index.message_runs]
    if blocks:
        index.message_start_time = min(b.message_start_time for b in blocks)
        index.message_end_time = max(b.message_end_time for b in blocks)
    return index


def read_file_index(f: BinaryIO, *, name: str = "") -> FileIndex:
    """Read what an MCAP file holds: from its summary, or by salvage when it has none.

    Args:
        f: the file, opened for binary reading (seekable).
        name: how the file is named in ``problems``.

    Raises:
        NotABagError: not an MCAP file.
        CorruptBagError: the header is unreadable.
    """
    header = read_header(f)
    f.seek(0, 2)
    file_size = f.tell()
    try:
        index = _read_summary(f, file_size, header)
    except (CorruptBagError, struct.error, UnicodeDecodeError):
        index = None
    if index is None:
        index = _scan(f, file_size, header, name or getattr(f, "name", "mcap"))
    index.chunk_indexes.sort(key=lambda c: (c.message_start_time, c.chunk_start_offset))
    return index


def read_block_records(
    f: BinaryIO, block: ChunkIndex | MessageRun, *, verify_crc: bool = False
) -> bytes:
    """Return the records of a chunk (decompressed) or of a run of loose messages.

    Raises:
        CorruptBagError: the chunk does not decompress or its CRC does not match.
    """
    if isinstance(block, MessageRun):
        return _read_exact(f, block.offset, block.length)
    raw = _read_exact(f, block.chunk_start_offset, block.chunk_length)
    chunk = parse_chunk(memoryview(raw)[RECORD_HEADER.size :])
    records = decompress(chunk.compression, chunk.records, chunk.uncompressed_size)
    if verify_crc and chunk.uncompressed_crc and crc32(records) != chunk.uncompressed_crc:
        raise CorruptBagError(f"chunk at byte {block.chunk_start_offset}: CRC mismatch")
    return records


def read_chunk(
    f: BinaryIO, chunk_index: ChunkIndex | MessageRun, *, verify_crc: bool = False
) -> ChunkData:
    """Read and decompress one chunk, with the message-index offsets of each of its channels.

    Uses the Message Index records that follow the chunk when there are any; otherwise (and for
    a run of loose messages) the offsets are found by walking the records.

    Raises:
        CorruptBagError: the chunk does not decompress or its CRC does not match.
    """
    records = read_block_records(f, chunk_index, verify_crc=verify_crc)
    message_index: dict[int, np.ndarray] = {}
    if isinstance(chunk_index, ChunkIndex) and chunk_index.message_index_offsets:
        first = min(chunk_index.message_index_offsets.values())
        last = max(chunk_index.message_index_offsets.values())
        f.seek(last)
        _, last_length = RECORD_HEADER.unpack(f.read(RECORD_HEADER.size))
        block = _read_exact(f, first, last + RECORD_HEADER.size + last_length - first)
        for _, opcode, content in iter_records(block):
            if opcode == Opcode.MESSAGE_INDEX:
                channel_id, entries = parse_message_index(content)
                message_index[channel_id] = entries
    else:
        found: dict[int, list[tuple[int, int]]] = {}
        for offset, opcode, content in iter_records(records):
            if opcode == Opcode.MESSAGE:
                channel_id, _, log_time, _ = MESSAGE_PREFIX.unpack_from(content)
                found.setdefault(channel_id, []).append((log_time, offset))
        message_index = {
            channel_id: np.array(entries, dtype=MESSAGE_INDEX_DTYPE)
            for channel_id, entries in found.items()
        }
    return ChunkData(records=records, message_index=message_index)


def iter_chunk_messages(records: bytes) -> Iterator[tuple[int, int, int, int, int, int]]:
    """Yield ``(channel_id, sequence, log_time, publish_time, data_start, data_end)`` per message.

    ``records`` are decompressed chunk records; the payload is ``records[data_start:data_end]``.
    """
    end = len(records)
    pos = 0
    unpack = MESSAGE_RECORD_HEADER.unpack_from
    header_size = RECORD_HEADER.size
    message = Opcode.MESSAGE
    while pos + header_size <= end:
        if records[pos] == message:
            _, length, channel_id, sequence, log_time, publish_time = unpack(records, pos)
            record_end = pos + header_size + length
            yield (
                channel_id,
                sequence,
                log_time,
                publish_time,
                pos + MESSAGE_DATA_OFFSET,
                record_end,
            )
        else:
            (length,) = _U64.unpack_from(records, pos + 1)
            record_end = pos + header_size + length
        pos = record_end


def encode_string(value: str) -> bytes:
    """Encode an MCAP ``String`` (u32 length prefix, UTF-8)."""
    data = value.encode("utf-8")
    return _U32.pack(len(data)) + data


def encode_string_map(value: dict[str, str]) -> bytes:
    """Encode an MCAP ``Map<String, String>`` (u32 byte length prefix)."""
    body = b"".join(encode_string(k) + encode_string(v) for k, v in value.items())
    return _U32.pack(len(body)) + body


def encode_record(opcode: Opcode, content: bytes) -> bytes:
    """Frame record content with its opcode and length."""
    return RECORD_HEADER.pack(opcode, len(content)) + content


def encode_header(header: Header) -> bytes:
    """Serialize a Header record."""
    return encode_record(
        Opcode.HEADER, encode_string(header.profile) + encode_string(header.library)
    )


def encode_schema(schema: Schema) -> bytes:
    """Serialize a Schema record."""
    content = (
        _U16.pack(schema.id)
        + encode_string(schema.name)
        + encode_string(schema.encoding)
        + _U32.pack(len(schema.data))
        + schema.data
    )
    return encode_record(Opcode.SCHEMA, content)


def encode_channel(channel: Channel) -> bytes:
    """Serialize a Channel record."""
    content = (
        _U16.pack(channel.id)
        + _U16.pack(channel.schema_id)
        + encode_string(channel.topic)
        + encode_string(channel.message_encoding)
        + encode_string_map(channel.metadata)
    )
    return encode_record(Opcode.CHANNEL, content)


def encode_chunk_header(chunk: Chunk) -> bytes:
    """Serialize a Chunk record up to its records, which follow it as they are.

    Writing the (large) records separately saves copying them into one record buffer.
    """
    content_prefix = (
        _CHUNK_PREFIX.pack(
            chunk.message_start_time,
            chunk.message_end_time,
            chunk.uncompressed_size,
            chunk.uncompressed_crc,
        )
        + encode_string(chunk.compression)
        + _U64.pack(len(chunk.records))
    )
    return (
        RECORD_HEADER.pack(Opcode.CHUNK, len(content_prefix) + len(chunk.records)) + content_prefix
    )


def encode_chunk(chunk: Chunk) -> bytes:
    """Serialize a Chunk record."""
    return encode_chunk_header(chunk) + chunk.records


def encode_message_index(channel_id: int, entries: bytes) -> bytes:
    """Serialize a Message Index record from packed ``(log_time, offset)`` u64 pairs."""
    return encode_record(
        Opcode.MESSAGE_INDEX, _U16.pack(channel_id) + _U32.pack(len(entries)) + entries
    )


def encode_chunk_index(index: ChunkIndex) -> bytes:
    """Serialize a Chunk Index record."""
    offsets = b"".join(_U16.pack(k) + _U64.pack(v) for k, v in index.message_index_offsets.items())
    content = (
        _CHUNK_INDEX_PREFIX.pack(
            index.message_start_time,
            index.message_end_time,
            index.chunk_start_offset,
            index.chunk_length,
        )
        + _U32.pack(len(offsets))
        + offsets
        + _U64.pack(index.message_index_length)
        + encode_string(index.compression)
        + _U64.pack(index.compressed_size)
        + _U64.pack(index.uncompressed_size)
    )
    return encode_record(Opcode.CHUNK_INDEX, content)


def encode_statistics(stats: Statistics) -> bytes:
    """Serialize a Statistics record."""
    counts = b"".join(_U16.pack(k) + _U64.pack(v) for k, v in stats.channel_message_counts.items())
    content = (
        _STATISTICS_PREFIX.pack(
            stats.message_count,
            stats.schema_count,
            stats.channel_count,
            stats.attachment_count,
            stats.metadata_count,
            stats.chunk_count,
            stats.message_start_time,
            stats.message_end_time,
        )
        + _U32.pack(len(counts))
        + counts
    )
    return encode_record(Opcode.STATISTICS, content)


def encode_metadata(metadata: Metadata) -> bytes:
    """Serialize a Metadata record."""
    return encode_record(
        Opcode.METADATA, encode_string(metadata.name) + encode_string_map(metadata.metadata)
    )


def encode_metadata_index(index: MetadataIndex) -> bytes:
    """Serialize a Metadata Index record."""
    return encode_record(
        Opcode.METADATA_INDEX,
        _U64.pack(index.offset) + _U64.pack(index.length) + encode_string(index.name),
    )


def encode_summary_offset(opcode: Opcode, group_start: int, group_length: int) -> bytes:
    """Serialize a Summary Offset record."""
    return encode_record(
        Opcode.SUMMARY_OFFSET, _SUMMARY_OFFSET.pack(opcode, group_start, group_length)
    )


def encode_data_end(data_section_crc: int = 0) -> bytes:
    """Serialize a Data End record (CRC 0: not computed)."""
    return encode_record(Opcode.DATA_END, _U32.pack(data_section_crc))


def encode_footer(summary_start: int, summary_offset_start: int, summary_crc: int) -> bytes:
    """Serialize a Footer record."""
    return encode_record(
        Opcode.FOOTER, _FOOTER.pack(summary_start, summary_offset_start, summary_crc)
    )
