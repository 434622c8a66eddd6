"""MCAP records: framing, bounded parsing of the records bagkit reads, and encoding.

Opcodes are ``mcap.opcode.Opcode``; the summary-level record types (``Header``, ``Footer``,
``Schema``, ``Channel``, ``Chunk``, ``ChunkIndex``, ``Statistics``, ``Metadata``,
``MetadataIndex``, ``SummaryOffset``, ``DataEnd``) are bagkit's NamedTuples
(:mod:`~bagkit.bag.mcapio.record_types`) with the ``mcap`` package's fields, and are encoded by
that package's ``write()``. Parsing is bagkit's: the package's ``read()`` takes lengths
from the file as they are (a short read silently truncates a string, a length of 2**62 is read
as asked), while every length parsed here is checked against its record first and a bad one is a
:class:`CorruptBagError`. Message Index records are parsed into numpy arrays (one
``np.frombuffer`` per record instead of a Python tuple per message: see benchmarks/README.md,
"bagkit.bag.mcapio"); numpy is imported only then, as ``bagkit info`` reads the summary without
it (benchmarks/README.md, start-up).

Spec: https://mcap.dev/spec
"""

from __future__ import annotations

import functools
import struct
from collections.abc import Iterator
from typing import TYPE_CHECKING, Any

from mcap.opcode import Opcode

from bagkit.bag.errors import CorruptBagError
from bagkit.bag.mcapio.record_types import (
    Channel,
    Chunk,
    ChunkIndex,
    DataEnd,
    Footer,
    Header,
    Metadata,
    MetadataIndex,
    Record,
    Schema,
    Statistics,
    SummaryOffset,
)

if TYPE_CHECKING:
    import numpy as np
    from mcap.records import McapRecord

MAGIC = b"\x89MCAP0\r\n"
# Every record: opcode (u8), content length (u64), content.
RECORD_HEADER = struct.Struct("<BQ")
# Message record content before the payload: channel_id, sequence, log_time, publish_time.
MESSAGE_PREFIX = struct.Struct("<HIQQ")
# A whole Message record header (opcode, length, then MESSAGE_PREFIX); the payload follows.
MESSAGE_RECORD_HEADER = struct.Struct("<BQHIQQ")
# One entry of a Message Index record: (log_time u64, offset u64 of the Message record in the
# chunk); message_index_dtype() is its numpy dtype.
MESSAGE_INDEX_ENTRY_SIZE = 16
# A Chunk record's fixed fields before its compression name: start, end, size, CRC.
CHUNK_PREFIX = struct.Struct("<QQQI")
# The most bytes read whole for a summary section, the Message Index records of one chunk, or a
# Schema, Channel or Metadata record: about 1M chunk indexes, far beyond any real file.
MAX_SECTION_SIZE = 256 << 20
# The Metadata record rosbag2 writes its metadata.yaml into, as it closes a file.
ROSBAG2_METADATA = "rosbag2"
FOOTER = struct.Struct("<QQI")
FOOTER_RECORD_SIZE = RECORD_HEADER.size + FOOTER.size
_STATISTICS_PREFIX = struct.Struct("<QHIIIIQQ")
_U16 = struct.Struct("<H")
_U32 = struct.Struct("<I")
_U64 = struct.Struct("<Q")

__all__ = [
    "ROSBAG2_METADATA",
    "Channel",
    "Chunk",
    "ChunkIndex",
    "DataEnd",
    "Footer",
    "Header",
    "Metadata",
    "MetadataIndex",
    "Opcode",
    "Schema",
    "Statistics",
    "SummaryOffset",
]


class Cursor:
    """Reads MCAP's primitive types from one record's content, checking every length."""

    __slots__ = ("buf", "pos")

    def __init__(self, buf: bytes | memoryview, pos: int = 0) -> None:
        self.buf = buf
        self.pos = pos

    def _take(self, size: int) -> int:
        start = self.pos
        if start + size > len(self.buf):
            raise CorruptBagError(
                f"a field of {size} bytes at byte {start} runs past the end of its "
                f"{len(self.buf)}-byte record"
            )
        self.pos = start + size
        return start

    def unpack(self, layout: struct.Struct) -> tuple[int, ...]:
        """Read the fixed fields described by ``layout``."""
        return layout.unpack_from(self.buf, self._take(layout.size))

    def u16(self) -> int:
        return int(_U16.unpack_from(self.buf, self._take(2))[0])

    def u32(self) -> int:
        return int(_U32.unpack_from(self.buf, self._take(4))[0])

    def u64(self) -> int:
        return int(_U64.unpack_from(self.buf, self._take(8))[0])

    def raw(self, length: int) -> memoryview:
        start = self._take(length)
        return memoryview(self.buf)[start : start + length]

    def string(self) -> str:
        data = self.raw(self.u32())
        try:
            return str(data, "utf-8")
        except UnicodeDecodeError as exc:
            raise CorruptBagError(f"a string is not UTF-8 ({exc.reason})") from None

    def string_map(self) -> dict[str, str]:
        inner = Cursor(self.raw(self.u32()))
        result: dict[str, str] = {}
        while inner.pos < len(inner.buf):
            key = inner.string()
            result[key] = inner.string()
        return result

    def int_map(self) -> dict[int, int]:
        """A ``Map<uint16, uint64>`` (channel id to count or offset)."""
        entries = self.raw(self.u32())
        entry = struct.Struct("<HQ")
        if len(entries) % entry.size:
            raise CorruptBagError(f"a map of {len(entries)} bytes is not whole entries")
        return {int(k): int(v) for k, v in entry.iter_unpack(entries)}


def parse_header(content: bytes | memoryview) -> Header:
    """Parse a Header record's content."""
    cur = Cursor(content)
    return Header(profile=cur.string(), library=cur.string())


def parse_footer(content: bytes | memoryview) -> Footer:
    """Parse a Footer record's content."""
    summary_start, summary_offset_start, summary_crc = Cursor(content).unpack(FOOTER)
    return Footer(
        summary_start=summary_start,
        summary_offset_start=summary_offset_start,
        summary_crc=summary_crc,
    )


def parse_schema(content: bytes | memoryview) -> Schema:
    """Parse a Schema record's content."""
    cur = Cursor(content)
    schema_id, name, encoding = cur.u16(), cur.string(), cur.string()
    return Schema(id=schema_id, name=name, encoding=encoding, data=bytes(cur.raw(cur.u32())))


def parse_channel(content: bytes | memoryview) -> Channel:
    """Parse a Channel record's content."""
    cur = Cursor(content)
    channel_id, schema_id, topic = cur.u16(), cur.u16(), cur.string()
    return Channel(
        id=channel_id,
        schema_id=schema_id,
        topic=topic,
        message_encoding=cur.string(),
        metadata=cur.string_map(),
    )


def parse_chunk(content: bytes | memoryview) -> Chunk:
    """Parse a Chunk record's content; ``data`` (still compressed) is a view into ``content``."""
    cur = Cursor(content)
    start, end, uncompressed_size, crc = cur.unpack(CHUNK_PREFIX)
    compression = cur.string()
    data = cur.raw(cur.u64())
    return Chunk(
        message_start_time=start,
        message_end_time=end,
        uncompressed_size=uncompressed_size,
        uncompressed_crc=crc,
        compression=compression,
        data=data,  # type: ignore[arg-type]
    )


@functools.cache
def message_index_dtype() -> np.dtype[Any]:
    """The numpy dtype of a Message Index entry: ``log_time``, ``offset`` (both ``<u8``)."""
    import numpy as np

    return np.dtype([("log_time", "<u8"), ("offset", "<u8")])


def message_record_dtype() -> np.dtype[Any]:
    """The numpy dtype of a Message record up to its payload, as :data:`MESSAGE_RECORD_HEADER`
    packs it: ``opcode``, ``length``, then the Message's ``channel_id``, ``sequence``,
    ``log_time``, ``publish_time``."""
    import numpy as np

    return np.dtype(
        [
            ("opcode", "u1"),
            ("length", "<u8"),
            ("channel_id", "<u2"),
            ("sequence", "<u4"),
            ("log_time", "<u8"),
            ("publish_time", "<u8"),
        ]
    )


def message_index_entries(content: bytes | memoryview) -> tuple[int, memoryview]:
    """A Message Index record's content as (channel id, its entries' bytes), checked whole."""
    cur = Cursor(content)
    channel_id = cur.u16()
    entries = cur.raw(cur.u32())
    if len(entries) % MESSAGE_INDEX_ENTRY_SIZE:
        raise CorruptBagError(f"a message index of {len(entries)} bytes is not whole entries")
    return channel_id, entries


def parse_message_index(content: bytes | memoryview) -> tuple[int, np.ndarray]:
    """Parse a Message Index record's content into (channel id, ``message_index_dtype`` array)."""
    import numpy as np

    channel_id, entries = message_index_entries(content)
    return channel_id, np.frombuffer(entries, dtype=message_index_dtype())


def parse_statistics(content: bytes | memoryview) -> Statistics:
    """Parse a Statistics record's content."""
    cur = Cursor(content)
    messages, schemas, channels, attachments, metadata, chunks, start, end = cur.unpack(
        _STATISTICS_PREFIX
    )
    return Statistics(
        message_count=messages,
        schema_count=schemas,
        channel_count=channels,
        attachment_count=attachments,
        metadata_count=metadata,
        chunk_count=chunks,
        message_start_time=start,
        message_end_time=end,
        channel_message_counts=cur.int_map(),
    )


def parse_metadata(content: bytes | memoryview) -> Metadata:
    """Parse a Metadata record's content."""
    cur = Cursor(content)
    return Metadata(name=cur.string(), metadata=cur.string_map())


def parse_metadata_index(content: bytes | memoryview) -> MetadataIndex:
    """Parse a Metadata Index record's content."""
    cur = Cursor(content)
    return MetadataIndex(offset=cur.u64(), length=cur.u64(), name=cur.string())


def iter_records(buf: bytes | memoryview, start: int = 0) -> Iterator[tuple[int, int, memoryview]]:
    """Yield ``(offset, opcode, content)`` for each record of ``buf`` from ``start``.

    The one walker over a run of records (a summary section, a chunk's records). Chunk records
    are not opened.

    Raises:
        CorruptBagError: a record runs past the end of ``buf``.
    """
    view = memoryview(buf)
    end = len(view)
    pos = start
    header_size = RECORD_HEADER.size
    unpack = RECORD_HEADER.unpack_from
    while pos + header_size <= end:
        opcode, length = unpack(view, pos)
        content_start = pos + header_size
        if length > end - content_start:
            break
        yield pos, opcode, view[content_start : content_start + length]
        pos = content_start + length
    if pos != end:
        raise CorruptBagError(f"the record at byte {pos} runs past the end of its {end}-byte block")


def encode(record: Record | McapRecord) -> bytes:
    """Serialize a record (bagkit's or the ``mcap`` package's) with its opcode and length, as
    the package writes it."""
    # Imported here: reading a bag needs none of the package's record classes.
    from mcap import records
    from mcap.data_stream import RecordBuilder

    builder = RecordBuilder()
    if isinstance(record, records.McapRecord):
        record.write(builder)
    else:
        getattr(records, type(record).__name__)(**record._asdict()).write(builder)
    return bytes(builder.end())


def encode_chunk_header(chunk: Chunk, data_length: int | None = None) -> bytes:
    """Serialize a Chunk record up to its compressed data, which the caller writes after it.

    Writing the (large) data separately saves copying it into one record buffer.
    ``data_length``: the data's length when ``chunk.data`` does not hold it (default: its own).
    """
    if data_length is None:
        data_length = len(chunk.data)
    prefix = CHUNK_PREFIX.pack(
        chunk.message_start_time,
        chunk.message_end_time,
        chunk.uncompressed_size,
        chunk.uncompressed_crc,
    )
    compression = chunk.compression.encode("utf-8")
    content_prefix = prefix + _U32.pack(len(compression)) + compression + _U64.pack(data_length)
    return RECORD_HEADER.pack(Opcode.CHUNK, len(content_prefix) + data_length) + content_prefix


def encode_message_index(channel_id: int, entries: bytes) -> bytes:
    """Serialize a Message Index record from packed ``(log_time, offset)`` u64 pairs."""
    content_length = _U16.size + _U32.size + len(entries)
    return (
        RECORD_HEADER.pack(Opcode.MESSAGE_INDEX, content_length)
        + _U16.pack(channel_id)
        + _U32.pack(len(entries))
        + entries
    )
