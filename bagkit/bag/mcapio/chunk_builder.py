"""The open chunk of a writer: Message records appended in place, their index per channel.

bagkit's own (the ``mcap`` package's ``Writer`` builds a record object and a Python list entry
per message): kept for "ratio bagkit/mcap Writer" and "ratio to the recorder's need" of
``python -m benchmarks info`` (figures in benchmarks/README.md, "bagkit.bag.mcapio").
"""

from __future__ import annotations

import time
from array import array
from collections.abc import Callable
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

_MESSAGE = int(Opcode.MESSAGE)
_PREFIX_SIZE = MESSAGE_PREFIX.size
_SEQUENCE_MASK = 0xFFFFFFFF  # MCAP stores the sequence as a u32
_NO_TIME = 1 << 64


@dataclass(frozen=True, slots=True)
class ClosedChunk:
    """A finished chunk ready to be written: the Chunk record and its Message Index records.

    ``index_offsets`` are relative to the start of ``message_indexes``.
    """

    header: bytes
    data: bytes
    message_indexes: bytes
    index_offsets: dict[int, int]
    message_start_time: int
    message_end_time: int
    compression: str
    uncompressed_size: int
    message_counts: dict[int, int]
    uncompressed_crc: int = 0  # 0: not computed (MCAP's "no CRC")

    @property
    def length(self) -> int:
        """Bytes of the Chunk record."""
        return len(self.header) + len(self.data)


class ChunkBuilder:
    """Collects messages into one chunk's records until :meth:`close`.

    Attributes:
        records: the Message records so far (uncompressed).
        start, end: the first and last log time (``start`` is 2**64 while empty).
        count: messages so far.
        opened: ``time.monotonic()`` when the chunk was started.
    """

    __slots__ = ("count", "end", "index", "opened", "records", "start")

    def __init__(self) -> None:
        self.records = bytearray()
        self.index: dict[int, array[int]] = {}
        self.start = _NO_TIME
        self.end = 0
        self.count = 0
        self.opened = time.monotonic()

    def add(
        self, channel_id: int, data: bytes, log_time: int, publish_time: int, sequence: int
    ) -> None:
        """Append one Message record and its index entry."""
        records = self.records
        offset = len(records)
        records += MESSAGE_RECORD_HEADER.pack(
            _MESSAGE,
            _PREFIX_SIZE + len(data),
            channel_id,
            sequence & _SEQUENCE_MASK,
            log_time,
            publish_time,
        )
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
        records: bytes | bytearray,
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

        base = len(self.records)
        self.records += records
        entries = np.empty((len(offsets), 2), np.uint64)
        entries[:, 0] = log_times
        entries[:, 1] = offsets + base
        for channel_id in np.unique(channel_ids).tolist():
            index = self.index.get(channel_id)
            if index is None:
                index = self.index[channel_id] = array("Q")
            index.frombytes(entries[channel_ids == channel_id].tobytes())
        self.start = min(self.start, int(log_times.min()))
        self.end = max(self.end, int(log_times.max()))
        self.count += len(offsets)

    def message_counts(self) -> dict[int, int]:
        """Messages per channel so far."""
        return {channel_id: len(entries) // 2 for channel_id, entries in self.index.items()}

    def close(self, compression: str, compress: Callable[[bytearray], bytes]) -> ClosedChunk:
        """Compress the records and build the Chunk and Message Index records.

        Args:
            compression: the name stored in the chunk (``zstd``, ``lz4`` or ``""``).
            compress: the function compressing the records.
        """
        records = self.records
        data = compress(records)
        header = encode_chunk_header(
            Chunk(
                message_start_time=self.start,
                message_end_time=self.end,
                uncompressed_size=len(records),
                uncompressed_crc=crc32(records),
                compression=compression,
                data=data,
            )
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
            data=data,
            message_indexes=b"".join(index_records),
            index_offsets=index_offsets,
            message_start_time=self.start,
            message_end_time=self.end,
            compression=compression,
            uncompressed_size=len(records),
            message_counts=self.message_counts(),
        )
