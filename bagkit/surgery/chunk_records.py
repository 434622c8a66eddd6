"""One bag of any storage into MCAP by its chunks: the Message records that the back-ends hand
out (MCAP chunks, SQLite3 rows and ROS 1 messages laid out as such) written as they are.

No message object is made: each chunk's kept records are copied into one buffer, their channel
ids set to the output's in place, and appended to the output's chunks at once. The selection
is the message copy's (topics, time window, ``--where``); the latched state before a window is
written by the caller.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable

import numpy as np

from bagkit.bag import BagReader
from bagkit.bag.mcapio.chunks import payload_spans
from bagkit.bag.mcapio.records import MESSAGE_RECORD_HEADER
from bagkit.bag.storage import BagChunk
from bagkit.prefetch import prefetch
from bagkit.surgery.output import OutputBag
from bagkit.surgery.select import Selection

# Progress callback: (messages done, messages in all)
Progress = Callable[[int, int], None]
# A Message record's channel id: the u16 after its opcode (1 byte) and length (8 bytes).
_CHANNEL_AT = 9


def copy_chunk_records(
    reader: BagReader,
    selected: set[str],
    selection: Selection,
    out: OutputBag,
    progress: tuple[Progress | None, int],
) -> list[str]:
    """Write the selected messages of ``reader`` into ``out`` chunk by chunk, in chunk order
    (a SQLite3 file's: log-time order). Returns the problems found (index entries pointing
    outside their chunk)."""
    ids = {name: out.topic_id(name) for name in selected}
    report, total = progress
    done = unindexed = 0
    # The next chunk is read (SQLite3 steps, decompression: the GIL released) while one is
    # written; closing(): the reading thread stops before the reader is closed, also on error.
    window = selection.window
    read = reader.chunks(selected, window.start_ns, window.end_ns)
    with contextlib.closing(prefetch(read)) as chunks:
        for chunk in chunks:
            written, dropped = _write_chunk(chunk, ids, selection, out)
            done += written
            unindexed += dropped
            if report is not None:
                report(done, total)
    if unindexed:
        return [f"{reader.path.name}: {unindexed} index entries point outside their chunk: lost"]
    return []


def _write_chunk(
    chunk: BagChunk, ids: dict[str, int], selection: Selection, out: OutputBag
) -> tuple[int, int]:
    """Append the kept records of ``chunk``; (records written, index entries dropped)."""
    header = MESSAGE_RECORD_HEADER.size
    window = selection.window
    found: list[tuple[np.ndarray, ...]] = []
    dropped = 0
    for topic, entries in chunk.message_index.items():
        if topic not in ids:
            continue
        log_times, starts, lengths, lost = payload_spans(chunk.records, entries)
        dropped += lost
        keep = np.ones(len(starts), bool)
        if window.start_ns is not None:
            keep &= log_times >= window.start_ns
        if window.end_ns is not None:
            keep &= log_times < window.end_ns
        matcher = selection.content.get(topic)
        if matcher is not None:
            keep[keep] = matcher.mask_records(
                chunk.records, starts[keep], lengths[keep], log_times[keep]
            )
        channels = np.full(int(keep.sum()), ids[topic], np.uint16)
        found.append((starts[keep] - header, lengths[keep] + header, log_times[keep], channels))
    if not found:
        return 0, dropped
    offsets, sizes, times, channels = (np.concatenate(c) for c in zip(*found, strict=True))
    if not len(offsets):
        return 0, dropped
    order = np.argsort(offsets, kind="stable")
    offsets, sizes, times, channels = offsets[order], sizes[order], times[order], channels[order]
    data = _records(chunk.records, offsets, sizes)
    offsets = np.zeros(len(sizes), np.int64)
    np.cumsum(sizes[:-1], out=offsets[1:])
    fields = np.frombuffer(data, np.uint8)
    fields[offsets + _CHANNEL_AT] = channels & 0xFF
    fields[offsets + _CHANNEL_AT + 1] = channels >> 8
    out.write_records(data, offsets, sizes, channels, times.view(np.uint64))
    return len(offsets), dropped


def _records(records: bytes, offsets: np.ndarray, sizes: np.ndarray) -> bytearray:
    """The records at ``offsets`` (ascending) back to back, in a buffer of their own."""
    if offsets[0] == 0 and (offsets[1:] == (offsets + sizes)[:-1]).all():
        return bytearray(memoryview(records)[: int(offsets[-1] + sizes[-1])])
    view = memoryview(records)
    return bytearray(
        b"".join(view[o : o + n] for o, n in zip(offsets.tolist(), sizes.tolist(), strict=True))
    )
