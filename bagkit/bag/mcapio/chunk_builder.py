"""The open chunk of a writer: Message records appended in place, their index per channel.

bagkit's own (the ``mcap`` package's ``Writer`` builds a record object and a Python list entry
per message): kept for "ratio bagkit/mcap Writer" and "ratio to the recorder's need" of
``python -m benchmarks info`` (figures in benchmarks/README.md, "bagkit.bag.mcapio").

Small records are copied into one buffer; a large payload (``bytes`` of at least
:data:`LARGE_PAYLOAD`) is kept by reference, so that a chunk is a list of pieces, checksummed
piece by piece and, when stored uncompressed, written without ever being joined ("Snapshot
mode" in benchmarks/README.md). A chunk that would not get smaller is stored uncompressed
(compression ``""``, as MCAP allows), which also saves its readers the work: a chunk of large
payloads is compressed only when a sample of it compresses (see :data:`SAMPLED_CHUNK`), any
other when its compressed data is smaller than its records.
"""

from __future__ import annotations

import time
from array import array
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from zlib_ng.zlib_ng import crc32

from bagkit.bag.mcapio.records import (
    MESSAGE_PREFIX,
    MESSAGE_RECORD_HEADER,
    Chunk,
    Opcode,
    encode_chunk_header,
    encode_message_index,
)

if TYPE_CHECKING:
    import numpy as np

Buffer = bytes | bytearray | memoryview
# Compresses the pieces of a chunk's records into its data, returned in pieces (the "none"
# compression returns the pieces themselves).
Compress = Callable[[Sequence[Buffer]], Sequence[Buffer]]

# Payloads (``bytes``) from this size on are kept by reference instead of being copied.
LARGE_PAYLOAD = 64 << 10
# Chunks holding this many bytes of large payloads (and what came between them) are compressed
# only if spans sampled evenly over them (_SAMPLES of _SAMPLE_SPAN bytes) compress by at least
# 1/_MIN_SAVING: already compressed or noisy data (JPEG images, encoded point clouds) is stored
# as it is instead of being compressed in vain.
SAMPLED_CHUNK = 256 << 10
_SAMPLES = 8
_SAMPLE_SPAN = 8 << 10
_MIN_SAVING = 32
_MESSAGE = int(Opcode.MESSAGE)
_PREFIX_SIZE = MESSAGE_PREFIX.size
_SEQUENCE_MASK = 0xFFFFFFFF  # MCAP stores the sequence as a u32
_NO_TIME = 1 << 64


@dataclass(frozen=True, slots=True)
class ClosedChunk:
    """A finished chunk ready to be written: the Chunk record and its Message Index records.

    The Chunk record is ``header`` followed by ``pieces`` (its compressed data, in one piece or
    several). ``index_offsets`` are relative to the start of ``message_indexes``.
    """

    header: bytes
    pieces: tuple[Buffer, ...]
    message_indexes: bytes
    index_offsets: dict[int, int]
    message_start_time: int
    message_end_time: int
    compression: str
    uncompressed_size: int
    message_counts: dict[int, int]
    uncompressed_crc: int = 0  # 0: not computed (MCAP's "no CRC")

    @property
    def data(self) -> Buffer:
        """The compressed data in one buffer (joined only when it is in several pieces)."""
        return self.pieces[0] if len(self.pieces) == 1 else b"".join(self.pieces)

    @property
    def compressed_size(self) -> int:
        """Bytes of the compressed data."""
        return sum(map(len, self.pieces))

    @property
    def length(self) -> int:
        """Bytes of the Chunk record."""
        return len(self.header) + self.compressed_size


class ChunkBuilder:
    """Collects messages into one chunk's records until :meth:`close`.

    Attributes:
        records: the Message records since the last large payload (uncompressed).
        held: bytes of the records before ``records`` (``held + len(records)``: :attr:`size`).
        start, end: the first and last log time (``start`` is 2**64 while empty).
        count: messages so far.
        opened: ``time.monotonic()`` when the chunk was started.
    """

    __slots__ = ("_pieces", "count", "end", "held", "index", "opened", "records", "start")

    def __init__(self) -> None:
        self.records = bytearray()
        # The records before ``records``: filled buffers, record headers and large payloads.
        self._pieces: list[Buffer] = []
        self.held = 0
        self.index: dict[int, array[int]] = {}
        self.start = _NO_TIME
        self.end = 0
        self.count = 0
        self.opened = time.monotonic()

    @property
    def size(self) -> int:
        """Bytes of the chunk's records so far."""
        return self.held + len(self.records)

    def add(
        self, channel_id: int, data: bytes, log_time: int, publish_time: int, sequence: int
    ) -> None:
        """Append one Message record and its index entry.

        A large ``bytes`` payload is kept, not copied (``bytes`` cannot change afterwards).
        """
        records = self.records
        offset = self.held + len(records)
        records += MESSAGE_RECORD_HEADER.pack(
            _MESSAGE,
            _PREFIX_SIZE + len(data),
            channel_id,
            sequence & _SEQUENCE_MASK,
            log_time,
            publish_time,
        )
        if len(data) >= LARGE_PAYLOAD and type(data) is bytes:
            self._pieces += (records, data)
            self.held += len(records) + len(data)
            self.records = bytearray()
        else:
            records += data
        entries = self.index.get(channel_id)
        if entries is None:
            entries = self.index[channel_id] = array("Q")
        entries.append(log_time)
        entries.append(offset)
        # Plain comparisons: this is the per-message path, min()/max() calls cost more.
        if log_time < self.start:  # noqa: PLR1730
            self.start = log_time
        if log_time > self.end:  # noqa: PLR1730
            self.end = log_time
        self.count += 1

    def add_records(
        self,
        records: Buffer,
        channel_ids: np.ndarray,
        log_times: np.ndarray,
        offsets: np.ndarray,
    ) -> None:
        """Append whole Message records at once (as stored elsewhere; their channel ids already
        this chunk's), with their index entries.

        Args:
            records: the Message records back to back.
            channel_ids, log_times, offsets: of each record (offsets relative to ``records``).
        """
        if not len(offsets):
            return
        import numpy as np  # here: writing a bag message by message needs no numpy

        base = self.size
        self.records += records
        entries = np.empty((len(offsets), 2), np.uint64)
        entries[:, 0] = log_times
        entries[:, 1] = offsets + base
        first = int(channel_ids[0])
        if (channel_ids == first).all():  # the usual batch: one channel, no sort to find it
            by_channel = [(first, entries)]
        else:
            by_channel = [(c, entries[channel_ids == c]) for c in np.unique(channel_ids).tolist()]
        for channel_id, found in by_channel:
            index = self.index.get(channel_id)
            if index is None:
                index = self.index[channel_id] = array("Q")
            index.frombytes(found.tobytes())
        self.start = min(self.start, int(log_times.min()))
        self.end = max(self.end, int(log_times.max()))
        self.count += len(offsets)

    def message_counts(self) -> dict[int, int]:
        """Messages per channel so far."""
        return {channel_id: len(entries) // 2 for channel_id, entries in self.index.items()}

    def close(self, compression: str, compress: Compress) -> ClosedChunk:
        """Compress the records and build the Chunk and Message Index records.

        Args:
            compression: the name stored in the chunk (``zstd``, ``lz4`` or ``""``).
            compress: compresses the records' pieces (see :data:`Compress`). When its output
                is not smaller than the records, they are stored uncompressed (``""``).
        """
        pieces = [*self._pieces, self.records] if self.records else self._pieces
        size = self.size
        crc = 0
        for piece in pieces:
            crc = crc32(piece, crc)
        sampled = compression and self.held >= SAMPLED_CHUNK
        if sampled and not _compressible(pieces, size, compress):
            compression, data = "", tuple(pieces)
        else:
            data = tuple(compress(pieces)) if pieces else ()
            if compression and sum(map(len, data)) >= size:
                compression, data = "", tuple(pieces)
        header = encode_chunk_header(
            Chunk(
                message_start_time=self.start,
                message_end_time=self.end,
                uncompressed_size=size,
                uncompressed_crc=crc,
                compression=compression,
                data=b"",
            ),
            data_length=sum(map(len, data)),
        )
        index_records = []
        index_offsets: dict[int, int] = {}
        position = 0
        for channel_id, entries in self.index.items():
            record = encode_message_index(channel_id, entries.tobytes())
            index_offsets[channel_id] = position
            position += len(record)
            index_records.append(record)
        return ClosedChunk(
            header=header,
            pieces=data,
            message_indexes=b"".join(index_records),
            index_offsets=index_offsets,
            message_start_time=self.start,
            message_end_time=self.end,
            compression=compression,
            uncompressed_size=size,
            message_counts=self.message_counts(),
        )


def _compressible(pieces: Sequence[Buffer], size: int, compress: Compress) -> bool:
    """Whether spans sampled evenly over the records compress by at least 1/_MIN_SAVING."""
    spans: list[Buffer] = []
    starts = [i * size // _SAMPLES for i in range(_SAMPLES)]
    wanted = 0  # bytes of the current span still to take from the next pieces
    base = 0
    for piece in pieces:
        end = base + len(piece)
        at = 0
        while True:
            if not wanted and starts and starts[0] < end:
                at = max(at, starts.pop(0) - base)
                wanted = _SAMPLE_SPAN
            if not wanted or at >= len(piece):
                break
            span = memoryview(piece)[at : at + wanted]
            spans.append(span)
            at += len(span)
            wanted -= len(span)
        base = end
    sample = b"".join(spans)
    compressed = sum(map(len, compress([sample])))
    return compressed <= len(sample) - len(sample) // _MIN_SAVING
