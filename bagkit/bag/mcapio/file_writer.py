"""One MCAP file being written: appends that never leave a partial record, and the summary.

Records go to an unbuffered file in one ``writev`` per chunk (its header, its data in pieces,
then its Message Index records), so a killed process leaves whole records behind; a failed
write cuts the file back to its last whole record. The summary (Schema, Channel, Statistics,
Chunk Index and Metadata Index groups, Summary Offsets, Footer with the summary CRC) is encoded
with the ``mcap`` package's record classes.
"""

from __future__ import annotations

import contextlib
import os
import struct
from collections.abc import Iterable
from pathlib import Path
from typing import BinaryIO

from zlib_ng.zlib_ng import crc32

from bagkit.bag.errors import BagWriteError
from bagkit.bag.mcapio.chunk_builder import Buffer, ClosedChunk
from bagkit.bag.mcapio.chunk_indexes import ChunkIndexes
from bagkit.bag.mcapio.records import (
    MAGIC,
    Channel,
    ChunkIndex,
    DataEnd,
    Footer,
    Header,
    Metadata,
    MetadataIndex,
    Opcode,
    Schema,
    Statistics,
    SummaryOffset,
    encode,
)

_SUMMARY_CRC = struct.Struct("<I")
# Buffers per writev call: below every system's IOV_MAX (1024 on Linux).
_MAX_PARTS = 512


class McapFileWriter:
    """Writes one MCAP file: header, schemas and channels, chunks, then the summary.

    Attributes:
        path: the file.
        offset: bytes written so far.
        message_count, start_time, end_time: of the chunks written (``start_time`` None before
            the first).
        channel_counts: messages per channel id.
    """

    def __init__(self, path: Path, handle: BinaryIO) -> None:
        self.path = path
        self._handle = handle
        self.offset = 0
        # Columns, not an object a chunk: a long recording holds one row per chunk written.
        self.chunk_indexes = ChunkIndexes()
        self.metadata_indexes: list[MetadataIndex] = []
        self.channel_counts: dict[int, int] = {}
        self.message_count = 0
        self.start_time: int | None = None
        self.end_time = 0

    @classmethod
    def create(
        cls, path: Path, header: Header, schemas: Iterable[Schema], channels: Iterable[Channel]
    ) -> McapFileWriter:
        """Create ``path`` (it must not exist) and write the header, schemas and channels.

        Raises:
            BagWriteError: the file cannot be created or written.
        """
        try:
            handle = open(path, "xb", buffering=0)  # noqa: SIM115 (closed in close())
        except OSError as exc:
            raise BagWriteError(f"cannot create {path}: {exc.strerror or exc}") from exc
        writer = cls(path, handle)
        writer.append(
            MAGIC
            + encode(header)
            + b"".join(map(encode, schemas))
            + b"".join(map(encode, channels))
        )
        return writer

    def append(self, *parts: Buffer, lost: dict[str, int] | None = None) -> int:
        """Write ``parts`` one after the other at the end of the file; return their offset.

        Raises:
            BagWriteError: the write failed (``lost``: the messages this costs); the file is cut
                back to where it was, so it stays readable.
        """
        offset = self.offset
        views = [memoryview(part).cast("B") for part in parts if len(part)]
        try:
            fd = self._handle.fileno()
            while views:
                written = os.writev(fd, views[:_MAX_PARTS])
                if not written:
                    raise OSError("the write wrote nothing")
                while views and written >= len(views[0]):
                    written -= len(views[0])
                    del views[0]
                if written:
                    views[0] = views[0][written:]
        except OSError as exc:
            with contextlib.suppress(OSError):
                self._handle.truncate(offset)
                self._handle.seek(offset)
            raise BagWriteError(
                f"cannot write {self.path}: {exc.strerror or exc}", lost_by_topic=lost
            ) from exc
        self.offset = offset + sum(len(part) for part in parts)
        return offset

    def write_chunk(self, chunk: ClosedChunk, *, lost: dict[str, int]) -> None:
        """Append a chunk and its Message Index records (``lost``: its messages by topic).

        Raises:
            BagWriteError: as for :meth:`append`.
        """
        index_start = self.offset + chunk.length
        offset = self.append(chunk.header, *chunk.pieces, chunk.message_indexes, lost=lost)
        self.chunk_indexes.append(
            ChunkIndex(
                message_start_time=chunk.message_start_time,
                message_end_time=chunk.message_end_time,
                chunk_start_offset=offset,
                chunk_length=chunk.length,
                message_index_offsets={
                    c: index_start + relative for c, relative in chunk.index_offsets.items()
                },
                message_index_length=len(chunk.message_indexes),
                compression=chunk.compression,
                compressed_size=chunk.compressed_size,
                uncompressed_size=chunk.uncompressed_size,
            )
        )
        for channel_id, count in chunk.message_counts.items():
            self.channel_counts[channel_id] = self.channel_counts.get(channel_id, 0) + count
            self.message_count += count
        if self.start_time is None or chunk.message_start_time < self.start_time:
            self.start_time = chunk.message_start_time
        self.end_time = max(self.end_time, chunk.message_end_time)

    def add_metadata(self, metadata: Metadata) -> None:
        """Append a Metadata record (indexed in the summary)."""
        record = encode(metadata)
        offset = self.append(record)
        self.metadata_indexes.append(
            MetadataIndex(offset=offset, length=len(record), name=metadata.name)
        )

    def finish(self, schemas: list[Schema], channels: list[Channel]) -> None:
        """Write Data End, the summary and the footer.

        Raises:
            BagWriteError: as for :meth:`append`.
        """
        self.append(encode(DataEnd(data_section_crc=0)))  # CRC 0: not computed
        summary_start = self.offset
        groups = [
            (Opcode.SCHEMA, b"".join(map(encode, schemas))),
            (Opcode.CHANNEL, b"".join(map(encode, channels))),
            (Opcode.STATISTICS, encode(self._statistics(len(schemas), channels))),
            (Opcode.CHUNK_INDEX, b"".join(map(encode, self.chunk_indexes))),
            (Opcode.METADATA_INDEX, b"".join(map(encode, self.metadata_indexes))),
        ]
        summary = bytearray()
        offsets = bytearray()
        for opcode, group in groups:
            if group:
                offsets += encode(
                    SummaryOffset(
                        group_opcode=opcode,
                        group_start=summary_start + len(summary),
                        group_length=len(group),
                    )
                )
                summary += group
        summary_offset_start = summary_start + len(summary)
        summary += offsets
        footer = encode(
            Footer(
                summary_start=summary_start,
                summary_offset_start=summary_offset_start,
                summary_crc=0,
            )
        )
        # The summary CRC covers the summary and the footer up to the CRC field, its last field.
        signed = footer[: -_SUMMARY_CRC.size]
        footer = signed + _SUMMARY_CRC.pack(crc32(summary + signed))
        self.append(bytes(summary) + footer + MAGIC)

    def close(self) -> None:
        """Close the file (without a summary unless :meth:`finish` was called)."""
        with contextlib.suppress(OSError):
            self._handle.close()

    def _statistics(self, schema_count: int, channels: list[Channel]) -> Statistics:
        return Statistics(
            message_count=self.message_count,
            schema_count=schema_count,
            channel_count=len(channels),
            attachment_count=0,
            metadata_count=len(self.metadata_indexes),
            chunk_count=len(self.chunk_indexes),
            message_start_time=self.start_time or 0,
            message_end_time=self.end_time,
            channel_message_counts={c.id: self.channel_counts.get(c.id, 0) for c in channels},
        )
