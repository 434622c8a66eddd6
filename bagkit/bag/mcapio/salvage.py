"""Salvage: read what a file without a usable summary holds (a killed recorder, a cut copy).

The data section is walked record by record. A chunk followed by its Message Index records is
counted from them without being decompressed; the last chunk before a cut, and chunks without
indexes, are decompressed and CRC-checked. bagkit's own scan: the ``mcap`` package's stream
reader stops at the first bad record and decompresses every chunk to count its messages; kept
for "info on the large bag cut at 90% (salvage scan)" of ``python -m benchmarks info`` (figures
in benchmarks/README.md, "bagkit.bag.mcapio").
"""

from __future__ import annotations

import struct
from array import array
from itertools import chain

from bagkit.bag.errors import CorruptBagError
from bagkit.bag.mcapio.chunks import (
    DEFAULT_MAX_CHUNK_SIZE,
    MessageRun,
    read_block_records,
    walk_chunk,
)
from bagkit.bag.mcapio.data_section import DataSection
from bagkit.bag.mcapio.records import (
    CHUNK_PREFIX,
    MAX_SECTION_SIZE,
    MESSAGE_INDEX_ENTRY_SIZE,
    MESSAGE_PREFIX,
    RECORD_HEADER,
    ROSBAG2_METADATA,
    ChunkIndex,
    Cursor,
    Header,
    Opcode,
    message_index_entries,
    parse_channel,
    parse_metadata,
    parse_schema,
)
from bagkit.bag.mcapio.source import Source
from bagkit.bag.mcapio.summary import (
    FileIndex,
    closed_without_summary,
    read_header,
    read_summary,
)

# Loose messages are grouped into runs of at most this many bytes, read like chunks.
MAX_RUN_BYTES = 1 << 20
# Enough of a Chunk record to hold its fixed fields and a compression name.
_CHUNK_HEAD_BYTES = CHUNK_PREFIX.size + 4 + 256 + 8


def read_file_index(
    source: Source,
    *,
    check_crc: bool = True,
    max_chunk_size: int = DEFAULT_MAX_CHUNK_SIZE,
    header_first: bool = True,
) -> FileIndex:
    """What an MCAP file holds: from its summary, or by salvage when it has no usable one.

    ``check_crc`` and ``max_chunk_size`` apply to the chunks a scan opens (see
    :func:`~bagkit.bag.mcapio.chunks.read_chunk`). ``header_first=False`` reads the leading
    magic and the Header record only when the summary is not enough (a file in storage, where
    they are a range request of their own; its footer and closing magic are checked
    instead): ``header`` is then None.

    Raises:
        NotABagError: not an MCAP file.
        CorruptBagError: the header is unreadable.
    """
    header = read_header(source) if header_first else None
    problem = None
    try:
        index = read_summary(source, header)
    except CorruptBagError as exc:
        index = None
        problem = f"{source.name}: summary unreadable ({exc}); the file was scanned instead"
    if index is None or not index.complete:
        header = header or read_header(source)  # a scan starts after it
        summary = index  # one that does not index every message: scanned, and kept for topics
        index = _Scanner(source, header, check_crc, max_chunk_size).scan()
        index.summary = summary is not None or closed_without_summary(source)
        if summary is not None:
            for schema_id, schema in summary.schemas.items():
                index.schemas.setdefault(schema_id, schema)
            for channel_id, channel in summary.channels.items():
                index.channels.setdefault(channel_id, channel)
        if problem:
            index.problems.insert(0, problem)
    chunks = index.chunk_indexes
    rows = chunks.rows_by(chunks.start_times, chunks.chunk_offsets)
    if rows != array("Q", range(len(chunks))):
        index.chunk_indexes = chunks.take(rows)
    return index


def _chunk_index_from_record(source: Source, pos: int, length: int) -> ChunkIndex:
    """A Chunk record's fixed fields (not its data) as a ChunkIndex without message indexes."""
    cur = Cursor(source.read(pos + RECORD_HEADER.size, min(length, _CHUNK_HEAD_BYTES)))
    start, end, uncompressed_size, _ = cur.unpack(CHUNK_PREFIX)
    compression = cur.string()
    compressed_size = cur.u64()
    if compressed_size > length - cur.pos:
        raise CorruptBagError(f"chunk data of {compressed_size} bytes overruns its record")
    return ChunkIndex(
        message_start_time=start,
        message_end_time=end,
        chunk_start_offset=pos,
        chunk_length=RECORD_HEADER.size + length,
        message_index_offsets={},
        message_index_length=0,
        compression=compression,
        compressed_size=compressed_size,
        uncompressed_size=uncompressed_size,
    )


class _Scanner:
    """One salvage scan of one file (state shared by the record handlers)."""

    def __init__(self, source: Source, header: Header, check_crc: bool, max_size: int) -> None:
        self.source = source
        self.check_crc = check_crc
        self.max_size = max_size
        self.index = FileIndex(header=header, summary=False)
        self.pending: ChunkIndex | None = None  # the last chunk, not yet counted
        self.pending_counts: dict[int, int] = {}  # from the Message Index records after it
        self.run: list[int] | None = None  # loose messages: start, end, first and last time

    def scan(self) -> FileIndex:
        """Walk the data section; return what it holds."""
        records = DataSection(self.source)
        closed = False  # Data End or Footer reached: the last chunk's indexes are complete
        for pos, opcode, length in records:
            if opcode in (Opcode.DATA_END, Opcode.FOOTER):
                closed = True
                break
            try:
                self._record(pos, opcode, length)
            except CorruptBagError as exc:
                self.index.problems.append(
                    f"{self.source.name}: unreadable record at byte {pos} ({exc}), skipped"
                )
        # After a cut, the last chunk's indexes may be incomplete: count it from its records.
        self._settle(trust_indexes=closed)
        self._end_run()
        if records.cut_at is not None and not self._cut_after_messages(records):
            self.index.problems.append(
                f"{self.source.name}: truncated at byte {records.cut_at}: "
                f"{self.source.size - records.cut_at} bytes could not be read"
            )
        self._find_channels_in_chunks()
        self._set_times()
        return self.index

    def _cut_after_messages(self, records: DataSection) -> bool:
        """Whether the file is cut in a record written after its last message: Data End, or
        rosbag2's Metadata record (written as the file is closed). What is lost then held no
        message, and a topic none of whose messages were read had none."""
        if records.cut_opcode == Opcode.DATA_END:
            return True
        if records.cut_opcode != Opcode.METADATA or records.cut_at is None:
            return False
        name = ROSBAG2_METADATA.encode()
        head = struct.pack("<I", len(name)) + name
        start = records.cut_at + RECORD_HEADER.size
        # A name cut short is no name: what the record was is not known.
        return start + len(head) <= self.source.size and self.source.read(start, len(head)) == head

    def _record(self, pos: int, opcode: int, length: int) -> None:
        if opcode == Opcode.MESSAGE_INDEX:
            if self.pending is not None:
                channel_id, entries = message_index_entries(self._content(pos, length))
                self.pending.message_index_offsets[channel_id] = pos
                self.pending = self.pending._replace(
                    message_index_length=self.pending.message_index_length
                    + RECORD_HEADER.size
                    + length
                )
                self.pending_counts[channel_id] = len(entries) // MESSAGE_INDEX_ENTRY_SIZE
            return
        self._settle(trust_indexes=True)
        if opcode == Opcode.CHUNK:
            self.pending = _chunk_index_from_record(self.source, pos, length)
            self.pending_counts = {}
        elif opcode == Opcode.SCHEMA:
            schema = parse_schema(self._content(pos, length))
            self.index.schemas[schema.id] = schema
        elif opcode == Opcode.CHANNEL:
            channel = parse_channel(self._content(pos, length))
            self.index.channels[channel.id] = channel
        elif opcode == Opcode.METADATA:
            self.index.metadata.append(parse_metadata(self._content(pos, length)))
        elif opcode == Opcode.MESSAGE:
            self._add_message(pos, length)

    def _content(self, pos: int, length: int) -> bytes:
        if length > MAX_SECTION_SIZE:
            raise CorruptBagError(f"a record of {length} bytes")
        return self.source.read(pos + RECORD_HEADER.size, length)

    def _add_message(self, pos: int, length: int) -> None:
        """Count a loose message and add it to the current run (or start a new run)."""
        if length < MESSAGE_PREFIX.size:
            raise CorruptBagError("message record too short")
        prefix = self.source.read(pos + RECORD_HEADER.size, MESSAGE_PREFIX.size)
        channel_id, _, log_time, _ = MESSAGE_PREFIX.unpack(prefix)
        counts = self.index.channel_message_counts
        counts[channel_id] = counts.get(channel_id, 0) + 1
        record_end = pos + RECORD_HEADER.size + length
        run = self.run
        if run is not None and run[1] == pos and run[1] - run[0] < MAX_RUN_BYTES:
            run[1:] = [record_end, min(run[2], log_time), max(run[3], log_time)]
        else:
            self._end_run()
            self.run = [pos, record_end, log_time, log_time]

    def _end_run(self) -> None:
        if self.run is not None:
            start, end, first, last = self.run
            self.index.message_runs.append(MessageRun(start, end - start, first, last))
            self.run = None

    def _settle(self, *, trust_indexes: bool) -> None:
        """Count the pending chunk: from its indexes, or by opening it."""
        chunk_index, self.pending = self.pending, None
        if chunk_index is None:
            return
        if trust_indexes and self.pending_counts:
            counts = dict(self.pending_counts)
        else:
            chunk_index = chunk_index._replace(message_index_offsets={}, message_index_length=0)
            try:
                counts = self._open_chunk(chunk_index)
            except CorruptBagError as exc:
                self.index.problems.append(
                    f"{self.source.name}: chunk at byte {chunk_index.chunk_start_offset} "
                    f"({chunk_index.chunk_length} bytes) unreadable ({exc}), skipped"
                )
                return
        if not counts:
            return
        for channel_id, count in counts.items():
            total = self.index.channel_message_counts.get(channel_id, 0) + count
            self.index.channel_message_counts[channel_id] = total
        self.index.chunk_indexes.append(chunk_index)

    def _open_chunk(self, chunk_index: ChunkIndex) -> dict[int, int]:
        """Decompress and check a chunk, keep schemas/channels found in it; count messages."""
        records = read_block_records(
            self.source, chunk_index, check_crc=self.check_crc, max_size=self.max_size
        )
        index = self.index
        return walk_chunk(records, schemas=index.schemas, channels=index.channels).counts()

    def _find_channels_in_chunks(self) -> None:
        """Writers that put Schema/Channel records inside chunks: find the ones still missing."""
        for chunk_index in self.index.chunk_indexes:
            if self.index.channel_message_counts.keys() <= self.index.channels.keys():
                return
            try:
                self._open_chunk(chunk_index)
            except CorruptBagError:
                continue  # its messages are reported when they are read

    def _set_times(self) -> None:
        chunks, runs = self.index.chunk_indexes, self.index.message_runs
        if chunks or runs:
            self.index.message_start_time = min(
                chain(chunks.start_times, (run.message_start_time for run in runs))
            )
            self.index.message_end_time = max(
                chain(chunks.end_times, (run.message_end_time for run in runs))
            )
