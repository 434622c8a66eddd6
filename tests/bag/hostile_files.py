"""Helpers of the hostile-input tests: where the records of a (valid) MCAP file are, per the
mcap package, and byte patches of them."""

from __future__ import annotations

import struct
from dataclasses import dataclass
from pathlib import Path

from mcap.reader import make_reader
from mcap.records import ChunkIndex, MetadataIndex
from mcap.summary import Summary

from bagkit.bag.mcapio.records import RECORD_HEADER, encode

MAGIC_SIZE = 8
FOOTER_CONTENT = struct.Struct("<QQI")


@dataclass
class Layout:
    """A valid MCAP file and where its records are."""

    path: Path
    data: bytearray
    summary: Summary

    @classmethod
    def of(cls, path: Path) -> Layout:
        with open(path, "rb") as f:
            summary = make_reader(f).get_summary()
        assert summary is not None
        return cls(path, bytearray(path.read_bytes()), summary)

    @property
    def chunks(self) -> list[ChunkIndex]:
        return sorted(self.summary.chunk_indexes, key=lambda c: c.chunk_start_offset)

    @property
    def footer_content(self) -> int:
        """Offset of the footer record's content."""
        return len(self.data) - MAGIC_SIZE - FOOTER_CONTENT.size

    def record_in_summary(self, record: ChunkIndex | MetadataIndex) -> int:
        """Offset of ``record``'s content inside the summary section."""
        encoded = encode(record)
        start = self.summary_start()
        position = self.data.find(encoded, start)
        assert position >= start, "record not found in the summary"
        return position + RECORD_HEADER.size

    def summary_start(self) -> int:
        return int(FOOTER_CONTENT.unpack_from(self.data, self.footer_content)[0])

    def put(self, offset: int, fmt: str, *values: int) -> None:
        struct.pack_into(fmt, self.data, offset, *values)

    def save(self, path: Path | None = None) -> Path:
        target = path or self.path
        target.write_bytes(self.data)
        return target


def chunk_messages(layout: Layout, chunk: ChunkIndex) -> int:
    """Messages in ``chunk``, counted from its Message Index records by the mcap package."""
    count = 0
    for offset in chunk.message_index_offsets.values():
        (entries_size,) = struct.unpack_from("<I", layout.data, offset + RECORD_HEADER.size + 2)
        count += entries_size // 16
    return count
