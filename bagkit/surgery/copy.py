"""The streaming copy: messages of several MCAP files, in log-time order, into one OutputBag.

Each input file is a stream of blocks (chunks, runs of loose messages) in start-time order.
The stream whose next message or block comes first goes next. A chunk is copied as it is
stored when every message in it passes the selection, it is in the output's compression, its
channel ids are the output's, and no other message (of any input) falls inside its time span;
otherwise it is opened and its selected Message records join the runs waiting to be written
(:mod:`~bagkit.surgery.runs`). Memory: the chunks opened and not yet written out (those
overlapping in time), not the bag.

Chunks copied as stored have their CRC checked (which means decompressing them) on a pool of
threads, one per core, while the copy goes on: up to :data:`CHECK_WINDOW` of them wait for
their check, in order, before anything else is written.
"""

from __future__ import annotations

import os
from collections import deque
from collections.abc import Iterable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from bagkit.bag.definitions import DEFINITION_ENCODINGS, canonical_type_name
from bagkit.bag.errors import ChunkError
from bagkit.bag.mcapio import (
    Block,
    FileIndex,
    Source,
    extent,
    may_hold,
    read_chunk,
    unreadable_chunk,
)
from bagkit.bag.mcapio.chunk_builder import ClosedChunk
from bagkit.bag.mcapio.raw_chunk import check_raw_chunk, read_raw_chunk, stored_in_log_time_order
from bagkit.bag.mcapio.records import ChunkIndex
from bagkit.bag.messages import TopicInfo
from bagkit.surgery.options import TopicRewrite
from bagkit.surgery.output import OutputBag
from bagkit.surgery.select import PayloadFilter, Selection

if TYPE_CHECKING:
    from bagkit.surgery.runs import Run

_END = 1 << 64
# Chunks read and waiting for their CRC check: enough to keep every core busy.
CHECK_WINDOW = 16


@dataclass
class InputFile:
    """One MCAP file being copied: its index, and where its selected channels go."""

    path: Path
    source: Source
    index: FileIndex
    known: dict[str, TopicInfo] = field(default_factory=dict)  # topics as the bag lists them
    channel_map: dict[int, int] = field(default_factory=dict)  # input id -> output id
    content: dict[int, PayloadFilter] = field(default_factory=dict)  # input id -> --where
    rewrites: dict[int, TopicRewrite] = field(default_factory=dict)  # input id -> migration
    problems: list[str] = field(default_factory=list)


def topics_of(
    index: FileIndex, known: dict[str, TopicInfo]
) -> list[tuple[int, TopicInfo, str | None]]:
    """``(channel id, topic, definition)`` of each channel (QoS completed from ``known``); the
    definition None where the schema holds none (rosbag2's ``unknown`` encoding)."""
    found = []
    for channel in index.channels.values():
        schema = index.schemas.get(channel.schema_id)
        type_name = canonical_type_name(schema.name) if schema else ""
        recorded = known.get(channel.topic)
        qos = channel.metadata.get("offered_qos_profiles", "") or (
            recorded.offered_qos_profiles if recorded else ""
        )
        topic = TopicInfo(
            name=channel.topic,
            type=type_name,
            serialization_format=channel.message_encoding,
            offered_qos_profiles=qos,
            type_description_hash=channel.metadata.get("topic_type_hash", "")
            or (recorded.type_description_hash if recorded else ""),
        )
        definition = None
        if schema is not None and schema.encoding in DEFINITION_ENCODINGS:
            definition = schema.data.decode("utf-8", errors="replace")
        found.append((channel.id, topic, definition))
    return found


class _Stream:
    """The blocks of one input file not yet read (made one at a time, as they are reached)."""

    def __init__(self, file: InputFile, rank: int) -> None:
        self.file = file
        self._blocks = file.index.blocks(with_empty=True)
        self.head: Block | None = next(self._blocks, None)
        self.order = rank << 96  # then block after block, by offset inside it

    def next_block_start(self) -> int:
        """Log time the next block starts at (2**64 when done)."""
        return self.head.message_start_time if self.head is not None else _END

    def pop(self) -> Block:
        """The next block (there is one: ``head``), then the one after it is ``head``."""
        block = self.head
        assert block is not None
        self.head = next(self._blocks, None)
        return block


class _CheckedCopies:
    """Chunks to copy as stored, written in order once their CRC check (on a thread) passed."""

    def __init__(self, out: OutputBag, check_crc: bool) -> None:
        self._out = out
        self._pool = ThreadPoolExecutor(os.cpu_count() or 1) if check_crc else None
        self._waiting: deque[tuple[InputFile, Block, ClosedChunk, Future[None] | None]] = deque()

    def add(self, file: InputFile, block: Block, chunk: ClosedChunk, *, checked: bool) -> None:
        """Queue ``chunk`` for writing; its CRC is checked first unless it was (``checked``)."""
        pool = None if checked else self._pool
        check = pool.submit(check_raw_chunk, chunk) if pool is not None else None
        self._waiting.append((file, block, chunk, check))
        while len(self._waiting) > CHECK_WINDOW:
            self._write_next()

    def flush(self) -> None:
        """Write every chunk waiting (before anything else goes out)."""
        while self._waiting:
            self._write_next()

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(cancel_futures=True)

    def _write_next(self) -> None:
        file, block, chunk, check = self._waiting.popleft()
        try:
            if check is not None:
                check.result()
        except ChunkError as exc:
            _lost(file, block, str(exc))
            return
        self._out.copy_chunk(chunk)


@dataclass(frozen=True)
class CopyOptions:
    """How chunks are read and when they may be copied as stored.

    Attributes:
        check_crc: check each chunk's CRC (a damaged chunk's messages are lost, reported).
        stored_order: True: a chunk whose messages are stored out of log-time order (as
            recorders writing per-topic batches store them) is opened and its messages written
            in order, so the output is stored in log-time order (``merge``); False: it is
            copied as stored (readers order by index; ``filter``, ``recover``).
    """

    check_crc: bool = True
    stored_order: bool = False


def copy_files(
    files: list[InputFile], out: OutputBag, selection: Selection, options: CopyOptions
) -> None:
    """Copy the selected messages of ``files`` into ``out`` in log-time order (ties: file order).

    Opened messages wait in one heap until no block still to be read may hold an earlier one.
    Problems (chunks that cannot be read) are appended to each file's ``problems``.
    """
    check_crc = options.check_crc
    streams = [_Stream(f, rank) for rank, f in enumerate(files)]
    pending: list[Run] = []
    copies = _CheckedCopies(out, check_crc)
    try:
        while True:
            waiting = [s for s in streams if s.head is not None]
            if not waiting:
                copies.flush()
                _emit(pending, _END, 0, out)
                return
            stream = min(waiting, key=_Stream.next_block_start)
            if pending:
                copies.flush()
            # Messages before the block (equal times: those of earlier blocks or inputs) go first.
            _emit(pending, stream.next_block_start(), stream.order, out)
            block = stream.pop()
            bound = min(s.next_block_start() for s in streams)
            if pending:
                bound = min(bound, *(run.head() for run in pending))
            if block.message_end_time < bound and _may_copy(stream.file, block, selection, out):
                _copy(stream, block, selection, copies, pending, options)
            else:
                _open(stream, block, selection, check_crc, pending)
    finally:
        copies.close()


def _copy(  # noqa: PLR0917 (the loop's state, passed as it is)
    stream: _Stream,
    block: Block,
    selection: Selection,
    copies: _CheckedCopies,
    pending: list[Run],
    options: CopyOptions,
) -> None:
    """Copy a chunk as it is stored (or open it when its records show it cannot be)."""
    assert isinstance(block, ChunkIndex)
    # A chunk without Message Index records is decompressed to find its messages: its CRC is
    # checked then, not decompressed a second time on the pool.
    inline = options.check_crc and not block.message_index_offsets
    try:
        chunk = read_raw_chunk(stream.file.source, block, check_crc=inline)
    except ChunkError as exc:
        _lost(stream.file, block, str(exc))
        return
    in_order = not options.stored_order or stored_in_log_time_order(chunk)
    if in_order and _identity(stream.file, chunk.message_counts):
        copies.add(stream.file, block, chunk, checked=inline)
    else:  # stored out of order, or an index-less chunk holding channels not copied as is
        _open(stream, block, selection, options.check_crc, pending)


def _may_copy(file: InputFile, block: Block, selection: Selection, out: OutputBag) -> bool:
    """Whether ``block`` can go out as it is stored, as far as its index tells.

    A chunk without Message Index records may: its channels are known once it is read.
    """
    if not isinstance(block, ChunkIndex) or block.compression != out.compression:
        return False
    if not selection.covers(block.message_start_time, block.message_end_time):
        return False
    if not out.takes_whole(block.message_start_time, block.message_end_time, block.chunk_length):
        return False
    return _identity(file, block.message_index_offsets)


def _identity(file: InputFile, channel_ids: Iterable[int]) -> bool:
    """Whether every one of ``channel_ids`` is selected whole (no content filter) and keeps
    its id in the output."""
    mapping, content, rewrites = file.channel_map, file.content, file.rewrites
    return all(mapping.get(c) == c and c not in content and c not in rewrites for c in channel_ids)


def _open(
    stream: _Stream, block: Block, selection: Selection, check_crc: bool, pending: list[Run]
) -> None:
    """Read a block and add its selected messages to the pending ones."""
    file = stream.file
    mapping = file.channel_map
    if not may_hold(block, mapping.keys()):
        return  # nothing selected in it: not even read
    if not selection.window.overlaps(block.message_start_time, block.message_end_time):
        return  # wholly outside the window: not read, nor lost if it cannot be
    try:
        contents = read_chunk(file.source, block, check_crc=check_crc)
    except ChunkError as exc:
        _lost(file, block, str(exc))
        return
    from bagkit.surgery.runs import open_run  # numpy: not imported while chunks are copied

    run, bad = open_run(
        contents.records,
        contents.message_index,
        mapping,
        selection,
        stream.order,
        file.content,
        file.rewrites,
    )
    stream.order += 1 << 64
    if run is not None:
        pending.append(run)
    if bad:
        file.problems.append(
            f"{file.path.name}: chunk at byte {extent(block)[0]}: {bad} message index entries "
            "point at no message: those messages are lost"
        )


def _emit(pending: list[Run], before_time: int, before_rank: int, out: OutputBag) -> None:
    """Write the pending messages before ``(before_time, before_rank)``, if any."""
    if pending:
        from bagkit.surgery.runs import emit

        emit(pending, before_time, before_rank, out)


def _lost(file: InputFile, block: Block, what: str) -> None:
    file.problems.append(unreadable_chunk(file.path.name, file.source, block, what))
