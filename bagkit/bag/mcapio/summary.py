"""What an MCAP file holds (:class:`FileIndex`), from its summary section, checked against the file.

Every offset and length of the summary is checked before it is used: a summary that does not
fit the file is not used (the file is scanned instead, :mod:`bagkit.bag.mcapio.salvage`), and a
chunk or metadata index pointing outside the data section, or overlapping another chunk, is
dropped with a problem. Parsing is bagkit's own because it checks lengths (see
:mod:`bagkit.bag.mcapio.records`), at the ``mcap`` package's ``get_summary`` speed ("info" of
``python -m benchmarks info``, figures in benchmarks/README.md, "bagkit.bag.mcapio").
"""

from __future__ import annotations

import heapq
from array import array
from collections.abc import Iterator
from dataclasses import dataclass, field

from bagkit.bag.errors import CorruptBagError, NotABagError
from bagkit.bag.mcapio.chunk_indexes import ChunkIndexes
from bagkit.bag.mcapio.chunks import Block, MessageRun, extent
from bagkit.bag.mcapio.message_index import message_index_bytes
from bagkit.bag.mcapio.records import (
    FOOTER_RECORD_SIZE,
    MAGIC,
    MAX_SECTION_SIZE,
    MESSAGE_INDEX_ENTRY_SIZE,
    RECORD_HEADER,
    Channel,
    Footer,
    Header,
    Metadata,
    MetadataIndex,
    Opcode,
    Schema,
    Statistics,
    iter_records,
    parse_channel,
    parse_footer,
    parse_header,
    parse_metadata_index,
    parse_schema,
    parse_statistics,
)
from bagkit.bag.mcapio.source import Source


@dataclass(slots=True)
class FileIndex:
    """What one MCAP file holds, from its summary or, when it has none, from a salvage scan.

    Attributes:
        summary: True when the file was closed cleanly: it has a summary section, or its
            Footer says it has none (:func:`closed_without_summary`, a writer's choice).
        complete: True when the summary indexes every message (counts from its Statistics
            record or from the Message Index records of its chunk indexes); a file whose summary
            does not is scanned (:mod:`bagkit.bag.mcapio.salvage`), ``summary`` still True.
        chunk_indexes: the chunks' indexes, sorted by start time then file offset when the
            index comes from :func:`~bagkit.bag.mcapio.salvage.read_file_index`.
        message_runs: runs of loose messages (a scan's), in file order.
        channel_message_counts: messages per channel id.
        metadata: the Metadata records a salvage scan met.
        metadata_indexes: a summary's Metadata Index entries that point inside the data
            section; the records are read only when asked for (from storage each is one more
            range request): metadata.yaml is what describes a bag.
        problems: what could not be read (empty for intact files).
        header: None when it was not read: a file in storage whose summary was enough
            (:func:`~bagkit.bag.mcapio.salvage.read_file_index`, ``header_first``).
    """

    header: Header | None
    schemas: dict[int, Schema] = field(default_factory=dict)
    channels: dict[int, Channel] = field(default_factory=dict)
    chunk_indexes: ChunkIndexes = field(default_factory=ChunkIndexes)
    message_runs: list[MessageRun] = field(default_factory=list)
    channel_message_counts: dict[int, int] = field(default_factory=dict)
    message_start_time: int = 0
    message_end_time: int = 0
    metadata: list[Metadata] = field(default_factory=list)
    metadata_indexes: list[MetadataIndex] = field(default_factory=list)
    summary: bool = False
    complete: bool = False
    problems: list[str] = field(default_factory=list)

    @property
    def message_count(self) -> int:
        """Messages in the file."""
        return sum(self.channel_message_counts.values())

    def blocks(self, *, with_empty: bool = False) -> Iterator[Block]:
        """The chunks (with messages, or all with ``with_empty``) and runs of loose messages,
        by start time then file offset; each chunk made a ``ChunkIndex`` when it is reached.

        Needs ``chunk_indexes`` in that order (as :func:`read_file_index` leaves them).
        """
        chunks = self.chunk_indexes
        starts, ends = chunks.start_times, chunks.end_times
        rows = range(len(chunks))
        in_order = (chunks[r] for r in rows if with_empty or starts[r] <= ends[r])
        runs = sorted(self.message_runs, key=_start_and_offset)
        return heapq.merge(in_order, runs, key=_start_and_offset)

    def blocks_in_file_order(self) -> Iterator[Block]:
        """The blocks with messages in file order, each chunk made a ``ChunkIndex`` when
        reached (a bag's worth of them is not held while it is read)."""
        chunks = self.chunk_indexes
        starts, ends = chunks.start_times, chunks.end_times
        rows = chunks.rows_by(chunks.chunk_offsets)
        with_messages = (chunks[row] for row in rows if starts[row] <= ends[row])
        return heapq.merge(with_messages, sorted(self.message_runs, key=extent), key=extent)


def _start_and_offset(block: Block) -> tuple[int, int]:
    return block.message_start_time, extent(block)[0]


def read_header(source: Source) -> Header:
    """Check the leading magic and read the Header record.

    Raises:
        NotABagError: the file does not start with the MCAP magic.
        CorruptBagError: the header record is unreadable.
    """
    start = source.read(0, min(source.size, len(MAGIC) + RECORD_HEADER.size))
    if not start.startswith(MAGIC):
        raise NotABagError("not an MCAP file (bad magic)")
    if len(start) < len(MAGIC) + RECORD_HEADER.size:
        raise CorruptBagError("MCAP file ends inside its header")
    opcode, length = RECORD_HEADER.unpack_from(start, len(MAGIC))
    if opcode != Opcode.HEADER:
        raise CorruptBagError("MCAP file does not start with a Header record")
    if length > MAX_SECTION_SIZE or not source.holds(len(start), length):
        raise CorruptBagError(
            f"the header record's length ({length}) runs past the end of the file"
        )
    return parse_header(source.read(len(start), length))


def _footer(source: Source) -> tuple[Footer, int] | None:
    """The Footer record and its offset; None when the file does not end in one and the
    closing magic (it was not closed)."""
    footer_offset = source.size - FOOTER_RECORD_SIZE - len(MAGIC)
    if footer_offset < 2 * len(MAGIC):
        return None
    end = source.read(footer_offset, FOOTER_RECORD_SIZE + len(MAGIC))
    if end[-len(MAGIC) :] != MAGIC or end[0] != Opcode.FOOTER:
        return None
    return parse_footer(end[RECORD_HEADER.size : FOOTER_RECORD_SIZE]), footer_offset


def closed_without_summary(source: Source) -> bool:
    """True for a file closed with no summary section (its Footer's ``summary_start`` is 0):
    valid MCAP, the summary is optional (mcap's writer with every summary record off)."""
    found = _footer(source)
    return found is not None and found[0].summary_start == 0


def _summary_bounds(source: Source) -> tuple[int, int] | None:
    """(summary start, footer offset), or None when the file has no summary (not closed,
    or closed without one).

    Raises:
        CorruptBagError: the footer points outside the file.
    """
    found = _footer(source)
    if found is None or found[0].summary_start == 0:
        return None
    footer, footer_offset = found
    if not len(MAGIC) < footer.summary_start <= footer_offset:
        raise CorruptBagError(
            f"the footer's summary start ({footer.summary_start}) is outside the file"
        )
    return footer.summary_start, footer_offset


def read_summary(source: Source, header: Header | None) -> FileIndex | None:
    """Build the index from the summary section; None when the file has none (not closed).

    Statistics, chunk indexes and message indexes are optional records: without Statistics
    (some rosbags versions, mcap's writer with ``use_statistics=False``), counts come from the
    Message Index records; a summary that cannot count every message (chunks without message
    indexes, no chunk indexes, messages outside chunks) is returned with ``complete`` False.

    Raises:
        CorruptBagError: the summary section is damaged.
    """
    bounds = _summary_bounds(source)
    if bounds is None:
        return None
    summary_start, footer_offset = bounds
    if footer_offset - summary_start > MAX_SECTION_SIZE:
        raise CorruptBagError(f"a summary section of {footer_offset - summary_start} bytes")
    index = FileIndex(header=header, summary=True)
    statistics: Statistics | None = None
    metadata_indexes: list[MetadataIndex] = []
    for _, opcode, content in iter_records(
        source.read(summary_start, footer_offset - summary_start)
    ):
        if opcode == Opcode.SCHEMA:
            schema = parse_schema(content)
            index.schemas[schema.id] = schema
        elif opcode == Opcode.CHANNEL:
            channel = parse_channel(content)
            index.channels[channel.id] = channel
        elif opcode == Opcode.CHUNK_INDEX:
            index.chunk_indexes.append_record(content)
        elif opcode == Opcode.STATISTICS:
            statistics = parse_statistics(content)
        elif opcode == Opcode.METADATA_INDEX:
            metadata_indexes.append(parse_metadata_index(content))
    index.metadata_indexes = [
        entry
        for entry in metadata_indexes
        if _check_metadata_index(index, source, entry, summary_start)
    ]
    if statistics is not None and statistics.message_count and not index.chunk_indexes:
        return index  # messages outside chunks, or no chunk indexes: the data must be read
    _keep_valid_chunk_indexes(index, source, summary_start)
    if statistics is not None:
        index.channel_message_counts = dict(statistics.channel_message_counts)
    else:
        counts = _indexed_counts(source, index.chunk_indexes)
        if counts is None:
            return index
        index.channel_message_counts = counts
    index.complete = True
    # Chunk indexes before Statistics: the Go writer's statistics skip log_time 0.
    chunks = index.chunk_indexes
    rows = range(len(chunks))
    first = min((chunks.start_times[r] for r in rows if not chunks.empty(r)), default=None)
    if first is not None:
        index.message_start_time = first
        index.message_end_time = max(chunks.end_times[r] for r in rows if not chunks.empty(r))
    elif statistics is not None and statistics.message_count:
        index.message_start_time = statistics.message_start_time
        index.message_end_time = statistics.message_end_time
    return index


def _indexed_counts(source: Source, chunks: ChunkIndexes) -> dict[int, int] | None:
    """Messages per channel from the Message Index records of the chunks; None when a chunk
    with messages has none (or there are no chunk indexes: loose messages are possible).

    Raises:
        CorruptBagError: message indexes are not where a chunk index says.
    """
    if not chunks:
        return None
    counts: dict[int, int] = {}
    for row in range(len(chunks)):
        if chunks.empty(row):
            continue
        if not chunks.indexed(row):
            return None
        for channel_id, entries in message_index_bytes(source, chunks[row]).items():
            found = len(entries) // MESSAGE_INDEX_ENTRY_SIZE
            counts[channel_id] = counts.get(channel_id, 0) + found
    return counts


def _keep_valid_chunk_indexes(index: FileIndex, source: Source, data_end: int) -> None:
    """Drop (as problems) chunk indexes outside the data section or overlapping another."""
    chunks = index.chunk_indexes
    kept = array("Q")
    covered = 0  # end of the last kept chunk, in file order
    for row in chunks.rows_by(chunks.chunk_offsets):
        start, length = chunks.chunk_offsets[row], chunks.chunk_lengths[row]
        if start < len(MAGIC) or length < RECORD_HEADER.size or length > data_end - start:
            what = "points outside the data section"
        elif start < covered:
            what = "overlaps the chunk before it"
        elif chunks.start_times[row] > chunks.end_times[row] and not chunks.empty(row):
            what = "ends before it starts"
        else:
            kept.append(row)
            covered = start + length
            continue
        index.problems.append(
            f"{source.name}: the index of a chunk at byte {start} ({length} bytes) {what}: "
            "that chunk is not read"
        )
    if kept != array("Q", range(len(chunks))):
        index.chunk_indexes = chunks.take(kept)


def _check_metadata_index(
    index: FileIndex, source: Source, entry: MetadataIndex, data_end: int
) -> bool:
    """True when ``entry`` points inside the data section, else a problem and False."""
    if RECORD_HEADER.size <= entry.length <= min(MAX_SECTION_SIZE, data_end - entry.offset):
        return True
    index.problems.append(
        f"{source.name}: metadata {entry.name!r} unreadable ({entry.length} bytes at byte "
        f"{entry.offset} are outside the data)"
    )
    return False
