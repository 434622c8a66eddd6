"""``doctor`` on one MCAP file: walk every record and hold the summary and indexes against it.

What the file really holds comes from the walk (every chunk decompressed and CRC-checked);
the summary (Statistics, Chunk Indexes, Schemas, Channels), the Message Index records, the
footer's summary CRC and the Data End's data CRC are then compared with it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from zlib_ng.zlib_ng import crc32

from bagkit.bag.errors import CorruptBagError
from bagkit.bag.mcapio.chunks import DEFAULT_MAX_CHUNK_SIZE, decompress, walk_chunk
from bagkit.bag.mcapio.data_section import DataSection
from bagkit.bag.mcapio.records import (
    FOOTER_RECORD_SIZE,
    MAGIC,
    MAX_SECTION_SIZE,
    MESSAGE_PREFIX,
    RECORD_HEADER,
    Channel,
    ChunkIndex,
    Opcode,
    Schema,
    parse_channel,
    parse_chunk,
    parse_footer,
    parse_message_index,
    parse_schema,
)
from bagkit.bag.mcapio.source import Source
from bagkit.bag.mcapio.summary import (
    FileIndex,
    closed_without_summary,
    read_header,
    read_summary,
)
from bagkit.words import counted

# Called with (channel id, log time, payload) for every message when decoding is checked.
MessageCheck = Callable[[int, int, memoryview], None]
_CRC_BLOCK = 16 << 20


@dataclass
class _Chunk:
    offset: int
    length: int
    start: int
    end: int
    compression: str
    compressed_size: int
    uncompressed_size: int
    entries: dict[int, np.ndarray]  # found by walking its records
    indexed: dict[int, int] = field(default_factory=dict)  # channel -> Message Index offset


@dataclass
class FileFacts:
    """What the walk found in one file, and the problems (one line each)."""

    schemas: dict[int, Schema] = field(default_factory=dict)
    channels: dict[int, Channel] = field(default_factory=dict)
    counts: dict[int, int] = field(default_factory=dict)
    start: int | None = None
    end: int = 0
    problems: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)  # valid MCAP, worth knowing

    @property
    def message_count(self) -> int:
        """Messages found."""
        return sum(self.counts.values())


class FileCheck:
    """One walk over one file (state shared by the record handlers)."""

    def __init__(self, source: Source, check_message: MessageCheck | None = None) -> None:
        self.source = source
        self.check_message = check_message
        self.facts = FileFacts()
        self.chunks: list[_Chunk] = []
        self.last_time = 0  # of the message stored last
        self.out_of_order = 0
        self.data_end: tuple[int, int] | None = None  # (offset, data section CRC)
        self.damaged: set[int] = set()  # offsets of chunks that are reported already

    def run(self) -> FileFacts:
        """Walk the file and compare; return the facts and problems."""
        name = self.source.name
        header = read_header(self.source)
        try:
            summary = read_summary(self.source, header)
        except CorruptBagError as exc:
            self._problem(f"summary unreadable ({exc})")
            summary = None
        self._walk()
        if self.out_of_order:
            # Valid MCAP (readers order by index), as recorders writing per-topic batches do.
            self.facts.notes.append(
                f"{counted(self.out_of_order, 'message')} stored out of log-time order"
            )
        if summary is None and closed_without_summary(self.source):
            self.facts.notes.append(
                "no summary section (its writer wrote none): readers scan the whole file; "
                "`bagkit recover` adds one"
            )
        elif summary is None:
            self._problem("no usable summary (not closed cleanly: `bagkit recover` rewrites it)")
        else:
            self.facts.problems.extend(p.removeprefix(f"{name}: ") for p in summary.problems)
            self._compare_summary(summary)
            self._check_summary_crc()
        self._check_data_crc()
        return self.facts

    def _problem(self, text: str) -> None:
        self.facts.problems.append(text)

    # -- the walk -------------------------------------------------------------------------

    def _walk(self) -> None:
        records = DataSection(self.source)
        for pos, opcode, length in records:
            if opcode == Opcode.DATA_END:
                crc = self.source.read(pos + RECORD_HEADER.size, 4) if length >= 4 else b""
                self.data_end = (pos, int.from_bytes(crc, "little"))
                return
            if opcode == Opcode.FOOTER:
                return
            try:
                self._record(pos, opcode, length)
            except CorruptBagError as exc:
                self._problem(f"record at byte {pos} unreadable ({exc})")
                self.damaged.add(pos)
        cut_at, cut_length = records.cut_at, records.cut_length
        if cut_at is not None and cut_length is None:
            left = self.source.size - cut_at
            self._problem(f"truncated at byte {cut_at}: {left} bytes are no whole record")
        elif cut_at is not None:
            self._problem(f"truncated at byte {cut_at}: a record of {cut_length} bytes is cut")

    def _record(self, pos: int, opcode: int, length: int) -> None:
        if opcode == Opcode.MESSAGE:
            self._loose_message(pos, length)
            return
        if opcode in (Opcode.CHUNK, Opcode.MESSAGE_INDEX, Opcode.SCHEMA, Opcode.CHANNEL):
            if length > 2 * DEFAULT_MAX_CHUNK_SIZE:
                raise CorruptBagError(f"{length} bytes, over the maximum size")
            content = memoryview(self.source.read(pos + RECORD_HEADER.size, length))
        else:
            return  # metadata, attachments: nothing to hold an index against
        if opcode == Opcode.CHUNK:
            self._chunk(pos, length, content)
        elif opcode == Opcode.MESSAGE_INDEX:
            channel_id, entries = parse_message_index(content)
            self._message_index(pos, channel_id, entries)
        elif opcode == Opcode.SCHEMA:
            schema = parse_schema(content)
            self.facts.schemas[schema.id] = schema
        else:
            channel = parse_channel(content)
            self.facts.channels[channel.id] = channel

    def _chunk(self, pos: int, length: int, content: memoryview) -> None:
        chunk = parse_chunk(content)
        where = f"chunk at byte {pos}"
        records = decompress(
            chunk.compression, chunk.data, chunk.uncompressed_size, DEFAULT_MAX_CHUNK_SIZE
        )
        if chunk.uncompressed_crc and crc32(records) != chunk.uncompressed_crc:
            self._problem(f"{where}: CRC mismatch (the chunk is damaged)")
            self.damaged.add(pos)
            return
        # Schema and Channel records are kept too: rosbag2 writes them inside chunks.
        facts = self.facts
        walked = walk_chunk(records, schemas=facts.schemas, channels=facts.channels)
        entries = walked.message_index()
        self.chunks.append(
            _Chunk(
                pos,
                RECORD_HEADER.size + length,
                chunk.message_start_time,
                chunk.message_end_time,
                chunk.compression,
                len(chunk.data),
                chunk.uncompressed_size,
                entries,
            )
        )
        times = np.concatenate([e["log_time"] for e in entries.values()]) if entries else None
        if times is None:
            return
        start, end = int(times.min()), int(times.max())
        if (start, end) != (chunk.message_start_time, chunk.message_end_time):
            self._problem(
                f"{where}: declares messages from {chunk.message_start_time} to "
                f"{chunk.message_end_time}, holds {start} to {end}"
            )
        self._count(entries, records)

    def _count(self, entries: dict[int, np.ndarray], records: bytes) -> None:
        facts = self.facts
        for channel_id, found in entries.items():
            facts.counts[channel_id] = facts.counts.get(channel_id, 0) + len(found)
        merged = np.sort(np.concatenate(list(entries.values())), order="offset")
        times = merged["log_time"].astype(np.int64)
        facts.start = (
            int(times.min()) if facts.start is None else min(facts.start, int(times.min()))
        )
        facts.end = max(facts.end, int(times.max()))
        previous = np.concatenate([[self.last_time], times[:-1]])
        self.out_of_order += int((times < previous).sum())
        self.last_time = int(times[-1])
        if self.check_message is not None:
            view = memoryview(records)
            for log_time, offset in merged.tolist():
                channel_id = int.from_bytes(view[offset + 9 : offset + 11], "little")
                length = int.from_bytes(view[offset + 1 : offset + 9], "little")
                payload = view[
                    offset + RECORD_HEADER.size + MESSAGE_PREFIX.size : offset
                    + RECORD_HEADER.size
                    + length
                ]
                self.check_message(channel_id, log_time, payload)

    def _loose_message(self, pos: int, length: int) -> None:
        """A message outside chunks (an unchunked file): counted, its decoding checked."""
        if length < MESSAGE_PREFIX.size or length > 2 * DEFAULT_MAX_CHUNK_SIZE:
            raise CorruptBagError(f"a message record of {length} bytes")
        record = memoryview(self.source.read(pos + RECORD_HEADER.size, length))
        channel_id, _, log_time, _ = MESSAGE_PREFIX.unpack_from(record)
        facts = self.facts
        facts.counts[channel_id] = facts.counts.get(channel_id, 0) + 1
        facts.start = log_time if facts.start is None else min(facts.start, log_time)
        facts.end = max(facts.end, log_time)
        self.out_of_order += log_time < self.last_time
        self.last_time = log_time
        if self.check_message is not None:
            self.check_message(channel_id, log_time, record[MESSAGE_PREFIX.size :])

    def _message_index(self, pos: int, channel_id: int, entries: np.ndarray) -> None:
        if not self.chunks:
            self._problem(f"message index at byte {pos} follows no chunk")
            return
        chunk = self.chunks[-1]
        chunk.indexed[channel_id] = pos
        found = chunk.entries.get(channel_id)
        stored = np.sort(entries, order="offset")
        if (
            found is None
            or len(found) != len(stored)
            or not np.array_equal(np.sort(found, order="offset"), stored)
        ):
            self._problem(
                f"message index at byte {pos} (channel {channel_id}) disagrees with the "
                f"chunk at byte {chunk.offset}: {counted(len(stored), 'entry', 'entries')}, the "
                "chunk holds "
                f"{counted(0 if found is None else len(found), 'message')} of that channel"
            )

    # -- comparisons ----------------------------------------------------------------------

    def _compare_summary(self, summary: FileIndex) -> None:
        """Compare what the summary holds; Statistics and chunk indexes are optional records."""
        facts = self.facts
        if (
            summary.complete
            and summary.channel_message_counts != {c: n for c, n in facts.counts.items()}
            and ({c: n for c, n in summary.channel_message_counts.items() if n} != facts.counts)
        ):
            self._problem(
                f"statistics count {counted(summary.message_count, 'message')} "
                f"({_counts(summary.channel_message_counts)}), the chunks hold "
                f"{facts.message_count} ({_counts(facts.counts)})"
            )
        # Channels without messages may be in the summary only; one with messages must be there.
        for channel_id in sorted(facts.counts.keys() - summary.channels.keys()):
            self._problem(f"channel {channel_id} holds messages but is missing from the summary")
        by_offset = {c.chunk_start_offset: c for c in summary.chunk_indexes}
        for chunk in self.chunks:
            index = by_offset.pop(chunk.offset, None)
            if index is None and summary.chunk_indexes:
                self._problem(f"chunk at byte {chunk.offset} has no chunk index")
            elif index is not None and not _agrees(index, chunk):
                self._problem(
                    f"the chunk index of the chunk at byte {chunk.offset} disagrees with it"
                )
        for offset in sorted(by_offset.keys() - self.damaged):
            self._problem(f"a chunk index points at byte {offset}, where no intact chunk is")

    def _check_summary_crc(self) -> None:
        source = self.source
        footer_offset = source.size - FOOTER_RECORD_SIZE - len(MAGIC)
        footer = parse_footer(
            source.read(footer_offset + RECORD_HEADER.size, FOOTER_RECORD_SIZE - RECORD_HEADER.size)
        )
        if not footer.summary_crc or footer.summary_start > footer_offset:
            return
        length = footer_offset + FOOTER_RECORD_SIZE - 4 - footer.summary_start
        if length > MAX_SECTION_SIZE:
            return
        if crc32(source.read(footer.summary_start, length)) != footer.summary_crc:
            self._problem("summary CRC mismatch (the summary is damaged)")

    def _check_data_crc(self) -> None:
        if self.data_end is None or not self.data_end[1]:
            return
        end, expected = self.data_end
        crc = 0
        for offset in range(0, end, _CRC_BLOCK):
            crc = crc32(self.source.read(offset, min(_CRC_BLOCK, end - offset)), crc)
        if crc != expected:
            self._problem("data section CRC mismatch (the data section is damaged)")


def _agrees(index: ChunkIndex, chunk: _Chunk) -> bool:
    return (
        index.chunk_length == chunk.length
        and index.message_start_time == chunk.start
        and index.message_end_time == chunk.end
        and index.compression == chunk.compression
        and index.compressed_size == chunk.compressed_size
        and index.uncompressed_size == chunk.uncompressed_size
        and (not index.message_index_offsets or index.message_index_offsets == chunk.indexed)
    )


def _counts(counts: dict[int, int]) -> str:
    return ", ".join(f"channel {c}: {n}" for c, n in sorted(counts.items())) or "none"
