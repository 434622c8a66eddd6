"""Mutations of an MCAP file's bytes: fields set to edge values, lengths, truncations, bit flips,
swapped records, and decompression bombs built from scratch. Each returns its recipe."""

from __future__ import annotations

import random
import struct
import zlib
from pathlib import Path
from typing import Any

import lz4.frame
import mcap_layout as layout
import zstandard

# Values a length, offset, count or time field is set to (reduced to the field's width).
EDGE_VALUES = {
    "0": lambda old, size: 0,
    "1": lambda old, size: 1,
    "-1": lambda old, size: -1,
    "old+1": lambda old, size: old + 1,
    "old-1": lambda old, size: old - 1,
    "2**31": lambda old, size: 1 << 31,
    "2**32-1": lambda old, size: (1 << 32) - 1,
    "2**62": lambda old, size: 1 << 62,
    "2**63": lambda old, size: 1 << 63,
    "2**64-1": lambda old, size: (1 << 64) - 1,
    "filesize": lambda old, size: size,
    "filesize+1": lambda old, size: size + 1,
    "old*2": lambda old, size: old * 2,
}


def _pick_record(rng: random.Random, data: bytearray, name: str | None) -> layout.Record | None:
    candidates = [r for r in layout.records(data) if name is None or r.name == name]
    return rng.choice(candidates) if candidates else None


def _fix_crc(data: bytearray, record: layout.Record) -> None:
    """Recompute the CRC of the uncompressed chunk holding ``record`` (so the change is read)."""
    if record.in_chunk is None:
        return
    chunk = next(r for r in layout.records(data) if r.offset == record.in_chunk)
    fields = {f.name: f for f in layout.fields_of(data, chunk)}
    body = fields.get("records")
    if body is not None and "uncompressed_crc" in fields:
        crc = zlib.crc32(data[body.offset : body.offset + body.width])
        layout.write_int(data, fields["uncompressed_crc"].offset, 4, crc)


def set_field(rng: random.Random, data: bytearray, record_name: str | None = None) -> str:
    """One integer or length field of one record set to an edge value."""
    record = _pick_record(rng, data, record_name)
    fields = [f for f in layout.fields_of(data, record) if f.kind != "text"] if record else []
    if record is None or not fields:
        return f"set_field {record_name}: none in file (unchanged)"
    field = rng.choice(fields)
    label = rng.choice(sorted(EDGE_VALUES))
    old = layout.read_int(data, field.offset, field.width)
    layout.write_int(data, field.offset, field.width, EDGE_VALUES[label](old, len(data)))
    fixed = record.in_chunk is not None and rng.random() < 0.7
    if fixed:
        _fix_crc(data, record)
    where = f"{record.name}@{record.offset}" + (" in chunk, crc fixed" if fixed else "")
    return f"set {where}.{field.name} = {label} (was {old})"


def set_record_length(rng: random.Random, data: bytearray) -> str:
    """A record header's length field set to an edge value."""
    record = _pick_record(rng, data, None)
    if record is None:
        return "set_record_length: no record (unchanged)"
    label = rng.choice(sorted(EDGE_VALUES))
    layout.write_int(data, record.offset + 1, 8, EDGE_VALUES[label](record.length, len(data)))
    return f"set {record.name}@{record.offset}.record_length = {label} (was {record.length})"


def set_opcode(rng: random.Random, data: bytearray) -> str:
    """A record's opcode byte replaced (another record type, or an unknown one)."""
    record = _pick_record(rng, data, None)
    if record is None:
        return "set_opcode: no record (unchanged)"
    opcode = rng.choice([*layout.OPCODES, 0x00, 0x80, 0xFF])
    data[record.offset] = opcode
    return f"set {record.name}@{record.offset}.opcode = {opcode:#04x}"


def garble_text(rng: random.Random, data: bytearray, record_name: str | None = None) -> str:
    """A string or byte field's content replaced by bytes that are not UTF-8 (same length)."""
    record = _pick_record(rng, data, record_name)
    fields = [f for f in layout.fields_of(data, record) if f.kind == "text"] if record else []
    fields = [f for f in fields if f.width > 0]
    if record is None or not fields:
        return f"garble_text {record_name}: none in file (unchanged)"
    field = rng.choice(fields)
    for i in range(field.offset, field.offset + field.width, max(1, field.width // 8)):
        data[i] = rng.choice([0xFF, 0xC3, 0x00, 0x80])
    if record.in_chunk is not None:
        _fix_crc(data, record)
    return f"garble {record.name}@{record.offset}.{field.name} ({field.width} bytes)"


def truncate(rng: random.Random, data: bytearray) -> str:
    """The file cut at a random byte, or just inside or after a record."""
    if rng.random() < 0.5:
        at = rng.randrange(len(data))
        label = f"truncate at byte {at} of {len(data)}"
    else:
        record = _pick_record(rng, data, None)
        at = (record.end if record else len(data)) - rng.choice([0, 1, 9])
        label = f"truncate at byte {at} (end of {record.name if record else '?'} - k)"
    del data[max(0, at) :]
    return label


def flip_bits(rng: random.Random, data: bytearray) -> str:
    """1 to 16 random bits flipped, anywhere or inside one record."""
    record = _pick_record(rng, data, None) if rng.random() < 0.6 else None
    start, end = (record.offset, record.end) if record else (0, len(data))
    flips = sorted(rng.randrange(start, end) for _ in range(rng.randint(1, 16)))
    for at in flips:
        data[at] ^= 1 << rng.randrange(8)
    where = f"in {record.name}@{record.offset}" if record else "anywhere"
    return f"flip {len(flips)} bits {where} (first at {flips[0]})"


def swap_records(rng: random.Random, data: bytearray) -> str:
    """Two records of the same type and length swapped, or two neighbours swapped."""
    found = [r for r in layout.records(data) if r.in_chunk is None]
    same = [
        (a, b)
        for i, a in enumerate(found)
        for b in found[i + 1 :]
        if a.name == b.name and a.length == b.length
    ]
    if same and rng.random() < 0.6:
        a, b = rng.choice(same)
    elif len(found) > 1:
        i = rng.randrange(len(found) - 1)
        a, b = found[i], found[i + 1]
    else:
        return "swap_records: fewer than two records (unchanged)"
    first, second = bytes(data[a.offset : a.end]), bytes(data[b.offset : b.end])
    data[a.offset : b.end] = second + data[a.end : b.offset] + first
    return f"swap {a.name}@{a.offset} with {b.name}@{b.offset}"


def _record(opcode: int, content: bytes) -> bytes:
    return struct.pack("<BQ", opcode, len(content)) + content


def _text(value: str) -> bytes:
    raw = value.encode()
    return struct.pack("<I", len(raw)) + raw


def write_bomb(path: Path, compression: str, size: int, declared: int | None) -> str:
    """A bag whose one chunk expands to a message of ``size`` zero bytes (``declared``: the
    uncompressed size the chunk claims, the true one when None), with a summary."""
    message = struct.pack("<BQHIQQ", 0x05, 22 + size, 1, 0, 1000, 1000)
    compressor: Any
    if compression == "zstd":
        compressor = zstandard.ZstdCompressor(level=1).compressobj()
        compressed = compressor.compress(message)
    else:
        compressor = lz4.frame.LZ4FrameCompressor()
        compressed = compressor.begin() + compressor.compress(message)
    zeros = bytes(1 << 24)
    for _ in range(size >> 24):
        compressed += compressor.compress(zeros)
    compressed += compressor.compress(bytes(size & ((1 << 24) - 1))) + compressor.flush()
    total = len(message) + size
    schema = _record(
        0x03,
        struct.pack("<H", 1)
        + _text("std_msgs/msg/String")
        + _text("ros2msg")
        + struct.pack("<I", 11)
        + b"string data",
    )
    channel = _record(
        0x04, struct.pack("<HH", 1, 1) + _text("/bomb") + _text("cdr") + struct.pack("<I", 0)
    )
    chunk = _record(
        0x06,
        struct.pack("<QQQI", 1000, 1000, total if declared is None else declared, 0)
        + _text(compression)
        + struct.pack("<Q", len(compressed))
        + compressed,
    )
    head = layout.MAGIC + _record(0x01, _text("ros2") + _text("fuzz")) + schema + channel
    index = _record(0x07, struct.pack("<HI", 1, 16) + struct.pack("<QQ", 1000, 0))
    data_end = _record(0x0F, struct.pack("<I", 0))
    chunk_at = len(head)
    index_at = chunk_at + len(chunk)
    summary_at = index_at + len(index) + len(data_end)
    chunk_index = _record(
        0x08,
        struct.pack("<QQQQ", 1000, 1000, chunk_at, len(chunk))
        + struct.pack("<I", 10)
        + struct.pack("<HQ", 1, index_at)
        + struct.pack("<Q", len(index))
        + _text(compression)
        + struct.pack("<QQ", len(compressed), total if declared is None else declared),
    )
    footer = _record(0x02, struct.pack("<QQI", summary_at, 0, 0))
    path.write_bytes(
        head + chunk + index + data_end + schema + channel + chunk_index + footer + layout.MAGIC
    )
    claim = "true size" if declared is None else f"declaring {declared}"
    return f"bomb: {compression} chunk of {len(compressed)} bytes expanding to {total} ({claim})"


MUTATIONS = {
    "set_field": set_field,
    "set_record_length": set_record_length,
    "set_opcode": set_opcode,
    "garble_text": garble_text,
    "truncate": truncate,
    "flip_bits": flip_bits,
    "swap_records": swap_records,
}


def mutate(rng: random.Random, data: bytearray) -> str:
    """Apply 1 to 3 mutations (set_field targets every record type in turn); return the recipe."""
    steps = []
    for _ in range(rng.choice([1, 1, 1, 2, 3])):
        name = rng.choice([*MUTATIONS, "set_field", "set_field", "set_field"])
        if name == "set_field":
            steps.append(set_field(rng, data, rng.choice([*layout.LAYOUTS, None])))
        else:
            steps.append(MUTATIONS[name](rng, data))
    return "; ".join(steps)
