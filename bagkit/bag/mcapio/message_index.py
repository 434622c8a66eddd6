"""The Message Index records after a chunk: as bytes, as numpy arrays, times, message sizes.

``bagkit info`` reads them as bytes (:func:`message_index_times`, :func:`channel_spans`,
:func:`ordered_offsets` for the events of services) and starts without numpy
(benchmarks/README.md, start-up), as does the player sizing its shared-memory segment before
its participant exists (:func:`largest_messages`); numpy is imported by :func:`index_arrays`
only.
"""

from __future__ import annotations

import itertools
import operator
import sys
from array import array
from bisect import bisect_left
from collections.abc import Callable, Hashable, Iterable, Mapping
from typing import TYPE_CHECKING, TypeVar

from bagkit.bag.errors import CorruptBagError
from bagkit.bag.mcapio.chunk_indexes import ChunkIndexes
from bagkit.bag.mcapio.records import (
    MAX_SECTION_SIZE,
    MESSAGE_RECORD_HEADER,
    ChunkIndex,
    Opcode,
    iter_records,
    message_index_dtype,
    message_index_entries,
)
from bagkit.bag.mcapio.source import Source

if TYPE_CHECKING:
    import numpy as np

_OFFSET = operator.itemgetter(1)
Span = tuple[int, int]
"""(first, last) log time in nanoseconds."""
_Key = TypeVar("_Key", bound=Hashable)


def widen(spans: dict[_Key, Span], key: _Key, first: int, last: int) -> None:
    """Widen ``spans[key]`` to take in ``first`` and ``last`` (set it when absent)."""
    old = spans.get(key)
    spans[key] = (first, last) if old is None else (min(old[0], first), max(old[1], last))


def message_index_bytes(source: Source, chunk_index: ChunkIndex) -> dict[int, memoryview]:
    """The entries of a chunk's Message Index records, by channel, as stored (16 bytes each).

    Raises:
        CorruptBagError: the records are not where the chunk index says.
    """
    offsets = chunk_index.message_index_offsets
    if not offsets:
        return {}
    first = min(offsets.values())
    if chunk_index.message_index_length > MAX_SECTION_SIZE:
        raise CorruptBagError(f"message indexes of {chunk_index.message_index_length} bytes")
    block = source.read(first, chunk_index.message_index_length)
    found: dict[int, memoryview] = {}
    for offset, opcode, content in iter_records(block):
        if opcode == Opcode.MESSAGE_INDEX:
            channel_id, entries = message_index_entries(content)
            if offsets.get(channel_id) == first + offset:
                found[channel_id] = entries
    if found.keys() != offsets.keys():
        raise CorruptBagError("message indexes are not where the chunk index says")
    return found


def read_message_indexes(source: Source, chunk_index: ChunkIndex) -> dict[int, np.ndarray]:
    """The Message Index records of a chunk, by channel, as ``message_index_dtype`` arrays.

    Raises:
        CorruptBagError: the records are not where the chunk index says.
    """
    return index_arrays(message_index_bytes(source, chunk_index))


def index_arrays(entries: Mapping[int, bytes | memoryview]) -> dict[int, np.ndarray]:
    """Message Index entries by channel as ``message_index_dtype`` arrays (views of them)."""
    import numpy as np

    dtype = message_index_dtype()
    return {channel_id: np.frombuffer(found, dtype=dtype) for channel_id, found in entries.items()}


def _words(entries: bytes | memoryview) -> array[int]:
    """Message Index entries as (log_time, offset, log_time, offset, ...) integers."""
    words = array("Q")
    words.frombytes(entries)
    if sys.byteorder == "big":  # MCAP is little-endian
        words.byteswap()
    return words


def ordered_offsets(entries: list[bytes | memoryview], lower: int, upper: int) -> list[int]:
    """The offsets of the entries with ``lower <= log_time < upper``, in log-time order (ties
    in storage order): the message-by-message path's order, without numpy."""
    if len(entries) == 1:
        words = _words(entries[0])
        times, offsets = words[0::2], words[1::2]
        # One channel written in order (the usual case): its entries are already in that
        # order, and its time range is cut by bisection.
        if _ascending(times, operator.le) and _ascending(offsets, operator.lt):
            return offsets[bisect_left(times, lower) : bisect_left(times, upper)].tolist()
    keyed: list[tuple[int, int]] = []
    for found in entries:
        words = _words(found)
        keyed.extend(zip(words[0::2], words[1::2], strict=True))
    keyed.sort()  # runs already in order (each channel's, mostly) merge in linear time
    if keyed and (keyed[0][0] < lower or keyed[-1][0] >= upper):
        keyed = keyed[bisect_left(keyed, (lower,)) : bisect_left(keyed, (upper,))]
    return list(map(_OFFSET, keyed))


def _ascending(values: array[int], order: Callable[[int, int], bool]) -> bool:
    """Whether ``order(a, b)`` holds for each value and the next."""
    return all(map(order, values, itertools.islice(values, 1, None)))


def largest_messages(
    source: Source, chunk_index: ChunkIndex, channels: Iterable[int]
) -> dict[int, int]:
    """Payload bytes of the largest message of each of ``channels`` in a chunk, from its Message
    Index records alone (no decompression, no numpy).

    A Message record runs to the next record any channel's index names, the last one to the
    chunk's end; a Schema or Channel record stored between two messages counts with the
    message before it, so a size may be over, never under.

    Raises:
        CorruptBagError: the records are not where the chunk index says, or name offsets
            past the chunk's end.
    """
    wanted = set(channels)
    starts: dict[int, array[int]] = {}
    offsets: set[int] = set()
    for channel_id, entries in message_index_bytes(source, chunk_index).items():
        channel_offsets = _words(entries)[1::2]
        offsets.update(channel_offsets)
        if channel_id in wanted and len(channel_offsets):
            starts[channel_id] = channel_offsets
    size = chunk_index.uncompressed_size
    bounds = sorted(offsets)
    if bounds and bounds[-1] + MESSAGE_RECORD_HEADER.size > size:
        raise CorruptBagError("a message index names an offset past its chunk's end")
    bounds.append(size)
    record_end = dict(itertools.pairwise(bounds))
    return {
        channel: max(record_end[start] - start for start in found) - MESSAGE_RECORD_HEADER.size
        for channel, found in starts.items()
    }


def message_index_times(
    source: Source, chunk_index: ChunkIndex, channels: Iterable[int]
) -> dict[int, Span]:
    """(first, last) log time of each of ``channels`` with entries in a chunk's Message Index
    records, read without numpy.

    Raises:
        CorruptBagError: the records are not where the chunk index says.
    """
    wanted = set(channels)
    spans: dict[int, Span] = {}
    for channel_id, entries in message_index_bytes(source, chunk_index).items():
        if channel_id not in wanted or not len(entries):
            continue
        log_times = _words(entries)[0::2]
        spans[channel_id] = (min(log_times), max(log_times))
    return spans


def channel_log_times(
    source: Source, chunks: ChunkIndexes, channels: set[int]
) -> np.ndarray | None:
    """The log times (int64, in no order) of ``channels``' messages from the chunks' Message
    Index records, no chunk decompressed; None when a chunk has none or they are damaged."""
    import numpy as np

    parts: list[np.ndarray] = []
    for row in range(len(chunks)):
        if chunks.start_times[row] > chunks.end_times[row]:
            continue  # no messages
        if not chunks.indexed(row):
            return None  # salvaged: only its records tell
        if channels.isdisjoint(chunks.channels(row)):
            continue
        try:
            indexes = read_message_indexes(source, chunks[row])
        except CorruptBagError:
            return None
        parts.extend(indexes[c]["log_time"] for c in channels if c in indexes)
    return np.concatenate(parts).astype(np.int64) if parts else np.zeros(0, np.int64)


def channel_spans(source: Source, chunks: ChunkIndexes) -> dict[int, Span]:
    """(first, last) log time of each channel, from the Message Index records of the chunks.

    Only the chunks that can hold a channel's first or last message are read: the index of a
    chunk starting after the earliest time found (or ending before the latest) cannot. A chunk
    whose Message Index records are not where its index says is passed over.
    """
    starts, ends = chunks.start_times, chunks.end_times
    indexed = [row for row in range(len(chunks)) if chunks.indexed(row)]
    found: dict[int, Span] = {}
    by_start = sorted(indexed, key=starts.__getitem__)
    by_end = sorted(indexed, key=ends.__getitem__, reverse=True)  # stable, as by -end
    for rows, earliest in ((by_start, True), (by_end, False)):
        seen: set[int] = set()
        for row in rows:
            # Chunks are visited in bound order: once a channel's time is beyond the next
            # chunk's bound, no later chunk can hold an earlier (later) message of it.
            start, end = starts[row], ends[row]
            wanted = [
                c
                for c in chunks.channels(row)
                if c not in seen
                or (start < found[c][0] if earliest else False)
                or (end > found[c][1] if not earliest else False)
            ]
            if not wanted:
                continue
            try:
                spans = message_index_times(source, chunks[row], wanted)
            except CorruptBagError:
                spans = {}
            for channel, (first, last) in spans.items():
                widen(found, channel, first, last)
            seen.update(c for c in wanted if c in found)
    return found
