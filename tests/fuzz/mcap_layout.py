"""MCAP records and their fields, located in a file's bytes (from the spec, independent of bagkit).

Only what a mutator needs: where each record starts and ends and where each fixed-width field,
length prefix and string sits, including the records inside uncompressed chunks.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

MAGIC = b"\x89MCAP0\r\n"
OPCODES = {
    0x01: "Header",
    0x02: "Footer",
    0x03: "Schema",
    0x04: "Channel",
    0x05: "Message",
    0x06: "Chunk",
    0x07: "MessageIndex",
    0x08: "ChunkIndex",
    0x09: "Attachment",
    0x0A: "AttachmentIndex",
    0x0B: "Statistics",
    0x0C: "Metadata",
    0x0D: "MetadataIndex",
    0x0E: "SummaryOffset",
    0x0F: "DataEnd",
}
# Field kinds: u8..u64 integers; str (u32 length + UTF-8), bytes32/bytes64 (length + bytes),
# maps and arrays (u32 byte length + entries of the given kinds), rest (to the record's end).
LAYOUTS: dict[str, list[tuple[str, str]]] = {
    "Header": [("profile", "str"), ("library", "str")],
    "Footer": [("summary_start", "u64"), ("summary_offset_start", "u64"), ("summary_crc", "u32")],
    "Schema": [("id", "u16"), ("name", "str"), ("encoding", "str"), ("data", "bytes32")],
    "Channel": [
        ("id", "u16"),
        ("schema_id", "u16"),
        ("topic", "str"),
        ("message_encoding", "str"),
        ("metadata", "map:str,str"),
    ],
    "Message": [
        ("channel_id", "u16"),
        ("sequence", "u32"),
        ("log_time", "u64"),
        ("publish_time", "u64"),
        ("data", "rest"),
    ],
    "Chunk": [
        ("message_start_time", "u64"),
        ("message_end_time", "u64"),
        ("uncompressed_size", "u64"),
        ("uncompressed_crc", "u32"),
        ("compression", "str"),
        ("records", "bytes64"),
    ],
    "MessageIndex": [("channel_id", "u16"), ("records", "map:u64,u64")],
    "ChunkIndex": [
        ("message_start_time", "u64"),
        ("message_end_time", "u64"),
        ("chunk_start_offset", "u64"),
        ("chunk_length", "u64"),
        ("message_index_offsets", "map:u16,u64"),
        ("message_index_length", "u64"),
        ("compression", "str"),
        ("compressed_size", "u64"),
        ("uncompressed_size", "u64"),
    ],
    "Attachment": [
        ("log_time", "u64"),
        ("create_time", "u64"),
        ("name", "str"),
        ("media_type", "str"),
        ("data", "bytes64"),
        ("crc", "u32"),
    ],
    "AttachmentIndex": [
        ("offset", "u64"),
        ("length", "u64"),
        ("log_time", "u64"),
        ("create_time", "u64"),
        ("data_size", "u64"),
        ("name", "str"),
        ("media_type", "str"),
    ],
    "Statistics": [
        ("message_count", "u64"),
        ("schema_count", "u16"),
        ("channel_count", "u32"),
        ("attachment_count", "u32"),
        ("metadata_count", "u32"),
        ("chunk_count", "u32"),
        ("message_start_time", "u64"),
        ("message_end_time", "u64"),
        ("channel_message_counts", "map:u16,u64"),
    ],
    "Metadata": [("name", "str"), ("metadata", "map:str,str")],
    "MetadataIndex": [("offset", "u64"), ("length", "u64"), ("name", "str")],
    "SummaryOffset": [("group_opcode", "u8"), ("group_start", "u64"), ("group_length", "u64")],
    "DataEnd": [("data_section_crc", "u32")],
}
WIDTHS = {"u8": 1, "u16": 2, "u32": 4, "u64": 8}
_FORMATS = {1: "<B", 2: "<H", 4: "<I", 8: "<Q"}


@dataclass(frozen=True, slots=True)
class Field:
    """A field of a record: ``width`` bytes at ``offset`` (an integer or a length prefix), or a
    string's bytes (``kind`` ``"text"``, ``width`` its length)."""

    record: str
    name: str
    offset: int
    width: int
    kind: str  # "int", "length" or "text"


@dataclass(frozen=True, slots=True)
class Record:
    """A record: its opcode byte at ``offset``, content from ``offset + 9`` for ``length``."""

    name: str
    offset: int
    length: int
    in_chunk: int | None  # offset of the enclosing Chunk record, None at top level

    @property
    def end(self) -> int:
        return self.offset + 9 + self.length


def read_int(data: bytes | bytearray, offset: int, width: int) -> int:
    return int(struct.unpack_from(_FORMATS[width], data, offset)[0])


def write_int(data: bytearray, offset: int, width: int, value: int) -> None:
    struct.pack_into(_FORMATS[width], data, offset, value % (1 << (8 * width)))


def records(data: bytes | bytearray) -> list[Record]:
    """Every record that parses, top level and inside uncompressed chunks, in file order."""
    found: list[Record] = []
    _scan(data, len(MAGIC), len(data), None, found)
    return found


def _scan(
    data: bytes | bytearray, pos: int, end: int, chunk: int | None, out: list[Record]
) -> None:
    while pos + 9 <= end:
        opcode, length = struct.unpack_from("<BQ", data, pos)
        if opcode not in OPCODES or pos + 9 + length > end:
            return
        record = Record(OPCODES[opcode], pos, length, chunk)
        out.append(record)
        if record.name == "Chunk" and chunk is None:
            inner = _chunk_records(data, record)
            if inner is not None:
                _scan(data, inner[0], inner[1], record.offset, out)
        pos = record.end


def _chunk_records(data: bytes | bytearray, chunk: Record) -> tuple[int, int] | None:
    """(start, end) of an uncompressed chunk's records, None when compressed or malformed."""
    fields = {f.name: f for f in fields_of(data, chunk)}
    compression, records_length = fields.get("compression"), fields.get("records")
    if compression is None or records_length is None or compression.width != 0:
        return None
    start = records_length.offset + 8
    return start, start + read_int(data, records_length.offset, 8)


def fields_of(data: bytes | bytearray, record: Record) -> list[Field]:
    """The fields of ``record`` that lie inside it, in order (stops where the content ends)."""
    out: list[Field] = []
    pos, end = record.offset + 9, record.end
    for name, kind in LAYOUTS[record.name]:
        if kind in WIDTHS:
            if pos + WIDTHS[kind] > end:
                break
            out.append(Field(record.name, name, pos, WIDTHS[kind], "int"))
            pos += WIDTHS[kind]
        elif kind == "rest":
            out.append(Field(record.name, name, pos, end - pos, "text"))
        else:
            width = 8 if kind == "bytes64" else 4
            if pos + width > end:
                break
            size = read_int(data, pos, width)
            out.append(Field(record.name, f"{name}.length", pos, width, "length"))
            pos += width
            if pos + size > end:
                break
            if kind.startswith("map:"):
                out += _entries(
                    data, record.name, name, kind[4:].split(","), pos=pos, end=pos + size
                )
            else:
                out.append(Field(record.name, name, pos, size, "text"))
            pos += size
    return out


def _entries(
    data: bytes | bytearray, record: str, name: str, kinds: list[str], *, pos: int, end: int
) -> list[Field]:
    """The keys and values of a map (or the pairs of an array) as fields of their own."""
    out: list[Field] = []
    index = 0
    while pos < end:
        for part, kind in zip(("key", "value"), kinds, strict=True):
            label = f"{name}[{index}].{part}"
            if kind == "str":
                if pos + 4 > end:
                    return out
                size = read_int(data, pos, 4)
                out.append(Field(record, f"{label}.length", pos, 4, "length"))
                out.append(Field(record, label, pos + 4, min(size, end - pos - 4), "text"))
                pos += 4 + size
            else:
                if pos + WIDTHS[kind] > end:
                    return out
                out.append(Field(record, label, pos, WIDTHS[kind], "int"))
                pos += WIDTHS[kind]
        index += 1
    return out
