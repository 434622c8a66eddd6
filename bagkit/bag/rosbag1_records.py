"""The record-level pieces of the ROS 1 back-end: a chunk record, a message read at its offset
(with rosbags' record readers), bounded decompression, and a chunk's messages as MCAP records."""

from __future__ import annotations

import bz2
import io
import struct
from collections.abc import Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING, BinaryIO

import lz4.frame
from rosbags.rosbag1.reader import (
    ChunkInfo,
    Header,
    ReaderError,
    RecordType,
    read_bytes,
    read_uint32,
)

from bagkit.bag.mcapio.records import (
    MESSAGE_PREFIX,
    MESSAGE_RECORD_HEADER,
    Opcode,
    message_index_dtype,
)

if TYPE_CHECKING:
    import numpy as np

_MESSAGE = int(Opcode.MESSAGE)
# What rosbags' record readers raise on bytes that are not what they expect (some checks are
# asserts).
RECORD_ERRORS = (
    ReaderError,
    AssertionError,
    struct.error,
    KeyError,
    ValueError,
    IndexError,
    OverflowError,
    UnicodeDecodeError,
    OSError,  # a seek to an offset no file has
)


@dataclass(frozen=True, slots=True)
class ChunkRecord:
    """A chunk record: where its data is, how it is compressed, its declared size."""

    info: ChunkInfo
    compression: str
    size: int
    data_pos: int
    data_size: int
    index_pos: int  # the index-data records after the data


def message_at(stream: io.BytesIO, offset: int) -> bytes:
    """The payload of the message data record at ``offset`` (connection records skipped),
    read with rosbags' record readers, as its ``Reader.messages`` does."""
    stream.seek(offset)
    while True:
        header = Header.read(stream)
        op = header.get_uint8("op")
        if op != RecordType.CONNECTION:
            break
        stream.seek(read_uint32(stream), io.SEEK_CUR)
    if op != RecordType.MSGDATA:
        raise ReaderError(f"a record of type {op}, not message data")
    return read_bytes(stream, read_uint32(stream))


def decompress(compression: str, raw: bytes, size: int) -> bytes:
    """``raw`` decompressed, never to more than ``size + 1`` bytes (a bomb stops there)."""
    if compression == "none":
        return raw
    if compression == "lz4":
        return lz4.frame.LZ4FrameDecompressor().decompress(raw, max_length=size + 1)
    if compression == "bz2":
        return bz2.BZ2Decompressor().decompress(raw, max_length=size + 1)
    raise ValueError(f"compression {compression!r} is not supported")


def chunk_data(bio: BinaryIO, chunk: ChunkRecord, max_size: int) -> bytes:
    """The decompressed data of ``chunk`` read from ``bio``.

    Raises:
        ChunkDataError: it declares more than ``max_size`` bytes, cannot be read or
            decompressed, or holds other than it declares (the text says which).
    """
    if chunk.size > max_size:
        raise ChunkDataError(f"declares {chunk.size} bytes, more than {max_size}")
    try:
        bio.seek(chunk.data_pos)
        data = decompress(chunk.compression, read_bytes(bio, chunk.data_size), chunk.size)
    except (ReaderError, OSError, ValueError, RuntimeError, EOFError) as exc:
        raise ChunkDataError(f"is unreadable ({exc})") from None
    if len(data) != chunk.size:
        raise ChunkDataError(f"holds {len(data)} bytes, not the {chunk.size} it declares")
    return data


class ChunkDataError(Exception):
    """A ROS 1 chunk whose data cannot be had (its messages are lost)."""


def mcap_records(
    payloads: Iterable[tuple[int, int, bytes]], topic_of: dict[int, str]
) -> tuple[bytes, dict[str, np.ndarray]] | None:
    """``(time, connection, CDR payload)`` as MCAP Message records back to back, with each
    topic's ``message_index_dtype`` entries (None without messages): a ROS 1 chunk as the bulk
    readers take an MCAP chunk."""
    import numpy as np

    records = bytearray()
    index: dict[str, list[tuple[int, int]]] = {}
    for time, conn_id, payload in payloads:
        index.setdefault(topic_of[conn_id], []).append((time, len(records)))
        records += MESSAGE_RECORD_HEADER.pack(
            _MESSAGE, MESSAGE_PREFIX.size + len(payload), conn_id & 0xFFFF, 0, time, time
        )
        records += payload
    if not index:
        return None
    dtype = message_index_dtype()
    return bytes(records), {t: np.array(e, dtype=dtype) for t, e in index.items()}


def chunk_contents(data: bytes) -> tuple[dict[int, list[tuple[int, int]]], set[int]]:
    """What a chunk's data holds, walked record by record with rosbags' header reader: the
    ``(time, offset)`` of each message data record by connection, and the connections of its
    connection records.

    Raises:
        ReaderError (or what rosbags' readers raise on bad bytes): a record does not parse.
    """
    stream = io.BytesIO(data)
    messages: dict[int, list[tuple[int, int]]] = {}
    connections: set[int] = set()
    while (offset := stream.tell()) < len(data):
        header = Header.read(stream)
        op = header.get_uint8("op")
        size = read_uint32(stream)
        if op == RecordType.MSGDATA:
            messages.setdefault(header.get_uint32("conn"), []).append(
                (header.get_time("time"), offset)
            )
        elif op == RecordType.CONNECTION:
            connections.add(header.get_uint32("conn"))
        if stream.seek(size, io.SEEK_CUR) > len(data):
            raise ReaderError(f"a record at offset {offset} ends after the chunk's data")
    return messages, connections
