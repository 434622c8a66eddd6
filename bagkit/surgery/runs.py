"""Opened chunks waiting to be written: their selected Message records as sorted numpy runs.

Messages are never handled one object at a time: a chunk's selected records are located,
checked and sorted with numpy, and the records due are copied whole (header, times, sequence
and payload as stored) into the output's chunk, the channel id rewritten in place.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Literal

import numpy as np

from bagkit.bag.mcapio.records import MESSAGE_PREFIX, MESSAGE_RECORD_HEADER, RECORD_HEADER, Opcode
from bagkit.decode.bulk import gather, read_at
from bagkit.surgery.options import TopicRewrite
from bagkit.surgery.output import OutputBag
from bagkit.surgery.select import PayloadFilter, Selection

_LOG_TIME_AT = RECORD_HEADER.size + 2 + 4  # channel id (u16), sequence (u32), then log time
_CHANNEL_AT = RECORD_HEADER.size
_MAX_TIME = (1 << 64) - 1
_MESSAGE = int(Opcode.MESSAGE)  # an enum member read per chunk costs a lookup in enum code


@dataclass
class Run:
    """The selected messages of one opened chunk, in (log time, offset) order.

    ``rank`` orders runs whose messages have equal log times (input, then block in the file).
    """

    records: bytes | memoryview  # memoryview: records rebuilt here (writable)
    times: np.ndarray  # uint64
    starts: np.ndarray  # int64, Message record starts in ``records``
    ends: np.ndarray  # int64
    channels: np.ndarray  # uint16, output channel ids
    rank: int
    cursor: int = 0

    def head(self) -> int:
        """Log time of the next message."""
        return int(self.times[self.cursor])

    @property
    def done(self) -> bool:
        """All written."""
        return self.cursor >= len(self.times)


def open_run(  # noqa: PLR0917 (the opened chunk and how it is selected)
    records: bytes,
    message_index: dict[int, np.ndarray],
    mapping: dict[int, int],
    selection: Selection,
    rank: int,
    content: Mapping[int, PayloadFilter] | None = None,
    rewrites: Mapping[int, TopicRewrite] | None = None,
) -> tuple[Run | None, int]:
    """The selected, whole Message records of a chunk as a run, and how many entries pointed at
    no whole Message record. ``content``: filters of input channels (``--where``);
    ``rewrites``: input channels whose payloads are rewritten (``migrate``)."""
    parts = [(c, e) for c, e in message_index.items() if c in mapping and len(e)]
    if not parts:
        return None, 0
    offsets = np.concatenate([e["offset"] for _, e in parts]).astype(np.int64)
    inputs = np.concatenate([np.full(len(e), c, np.uint16) for c, e in parts])
    channels = np.concatenate([np.full(len(e), mapping[c], np.uint16) for c, e in parts])
    size = len(records)
    valid = offsets <= size - MESSAGE_RECORD_HEADER.size
    buf = np.frombuffer(records, np.uint8)
    if size >= MESSAGE_RECORD_HEADER.size:
        safe = np.where(valid, offsets, 0)
        lengths = read_at(buf, safe + 1, "<u8").astype(np.int64)
        lengths = np.where(lengths < 0, size, lengths)  # lengths past 2**63: never whole
        times = read_at(buf, safe + _LOG_TIME_AT, "<u8")
        ends = safe + RECORD_HEADER.size + np.minimum(lengths, size)
        valid &= (buf[safe] == _MESSAGE) & (lengths >= MESSAGE_PREFIX.size) & (ends <= size)
    else:
        times = ends = np.zeros(len(offsets), np.int64)
    bad = int(len(offsets) - valid.sum())
    keep = valid.copy()
    window = selection.window
    if window.start_ns is not None:
        keep &= times >= np.uint64(max(window.start_ns, 0))
    if window.end_ns is not None:
        keep &= times < np.uint64(min(max(window.end_ns, 0), _MAX_TIME))
    for channel, payload_filter in (content or {}).items():
        rows = np.flatnonzero(keep & (inputs == channel))
        if len(rows):
            starts = offsets[rows] + MESSAGE_RECORD_HEADER.size
            keep[rows] = payload_filter.mask_records(
                records, starts, ends[rows] - starts, times[rows].astype(np.int64)
            )
    order = np.flatnonzero(keep)
    order = order[np.lexsort((offsets[order], times[order]))]
    if not len(order):
        return None, bad
    starts, stops = offsets[order], ends[order]
    kept: bytes | memoryview = records
    kept_inputs = inputs[order]
    if rewrites and any((kept_inputs == c).any() for c, _ in parts if c in rewrites):
        kept, starts, stops = _rewritten(buf, starts, stops, kept_inputs, rewrites)
    run = Run(kept, times[order].astype(np.uint64), starts, stops, channels[order], rank)
    return run, bad


def _rewritten(
    buf: np.ndarray,
    starts: np.ndarray,
    ends: np.ndarray,
    inputs: np.ndarray,
    rewrites: Mapping[int, TopicRewrite],
) -> tuple[memoryview, np.ndarray, np.ndarray]:
    """The run's Message records with the payloads of ``rewrites``' channels rewritten, as one
    new buffer with its record starts and ends.

    Each group of rewritten payloads of one size comes as the rows of a 2-D array with room
    for the record's header before the payload: the opcode and the new length are set, the
    stored channel, sequence and times copied, for all rows at once. The records not rewritten
    follow the groups, as they are stored.
    """
    size = MESSAGE_RECORD_HEADER.size
    new_starts, new_ends = np.empty_like(starts), np.empty_like(ends)
    rewritten = np.zeros(len(starts), bool)
    blocks: list[np.ndarray] = []
    at = 0
    for channel, rewrite in rewrites.items():
        rows = np.flatnonzero(inputs == channel)
        if not len(rows):
            continue
        payload_at = starts[rows] + size
        for indexes, block in rewrite.payloads(buf, payload_at, ends[rows] - payload_at, size):
            which = rows[indexes]
            count, width = block.shape
            block[:, : RECORD_HEADER.size] = np.frombuffer(
                RECORD_HEADER.pack(_MESSAGE, width - RECORD_HEADER.size), np.uint8
            )
            prefix = np.dtype((np.void, size - RECORD_HEADER.size))
            block[:, RECORD_HEADER.size : size].view(prefix)[:, 0] = gather(
                buf, starts[which] + RECORD_HEADER.size, prefix
            )
            new_starts[which] = at + np.arange(count, dtype=np.int64) * width
            new_ends[which] = new_starts[which] + width
            rewritten[which] = True
            blocks.append(block.reshape(-1))
            at += block.size
    if not rewritten.all():
        blocks.append(buf)
        new_starts[~rewritten] = starts[~rewritten] + at
        new_ends[~rewritten] = ends[~rewritten] + at
    joined = blocks[0] if len(blocks) == 1 else np.concatenate(blocks)
    return joined.data, new_starts, new_ends


def emit(runs: list[Run], before_time: int, before_rank: int, out: OutputBag) -> None:
    """Write the messages of ``runs`` that come before ``(before_time, before_rank)``."""
    runs.sort(key=lambda r: r.rank)
    key = np.uint64(min(before_time, _MAX_TIME))
    taken = []
    for run in runs:
        side: Literal["left", "right"] = (
            "right" if run.rank < before_rank or before_time > _MAX_TIME else "left"
        )
        stop = run.cursor + int(np.searchsorted(run.times[run.cursor :], key, side=side))
        if stop > run.cursor:
            taken.append((run, run.cursor, stop))
            run.cursor = stop
    runs[:] = [r for r in runs if not r.done]
    if not taken:
        return
    if len(taken) == 1:
        run, a, b = taken[0]
        starts, ends = run.starts[a:b], run.ends[a:b]
        if (starts[1:] == ends[:-1]).all():  # back to back: one slice
            first = int(starts[0])
            data = memoryview(run.records)[first : int(ends[-1])]
            writable = data if not data.readonly else bytearray(data)  # each record goes once
            _write(out, writable, starts - first, ends - starts, run.times[a:b], run.channels[a:b])
            return
        pieces = [run.records[s:e] for s, e in zip(starts.tolist(), ends.tolist(), strict=True)]
        _write_pieces(out, pieces, run.times[a:b], run.channels[a:b])
        return
    times = np.concatenate([r.times[a:b] for r, a, b in taken])
    which = np.concatenate([np.full(b - a, i, np.int64) for i, (_, a, b) in enumerate(taken)])
    order = np.lexsort((which, times))  # stable: within a run, its own order
    starts = np.concatenate([r.starts[a:b] for r, a, b in taken])[order].tolist()
    ends = np.concatenate([r.ends[a:b] for r, a, b in taken])[order].tolist()
    buffers = [r.records for r, _, _ in taken]
    pieces = [buffers[w][s:e] for w, s, e in zip(which[order].tolist(), starts, ends, strict=True)]
    channels = np.concatenate([r.channels[a:b] for r, a, b in taken])[order]
    _write_pieces(out, pieces, times[order], channels)


def _write_pieces(
    out: OutputBag, pieces: list[bytes | memoryview], times: np.ndarray, channels: np.ndarray
) -> None:
    lengths = np.fromiter(map(len, pieces), np.int64, len(pieces))
    offsets = np.zeros(len(pieces), np.int64)
    np.cumsum(lengths[:-1], out=offsets[1:])
    _write(out, bytearray(b"".join(pieces)), offsets, lengths, times, channels)


def _write(  # noqa: PLR0917 (the records and what each needs)
    out: OutputBag,
    data: bytearray | memoryview,
    offsets: np.ndarray,
    lengths: np.ndarray,
    times: np.ndarray,
    channels: np.ndarray,
) -> None:
    """Write the Message records ``data`` holds at ``offsets``, their channel ids set first."""
    view = np.frombuffer(data, np.uint8)
    view[offsets + _CHANNEL_AT] = (channels & 0xFF).astype(np.uint8)
    view[offsets + _CHANNEL_AT + 1] = (channels >> 8).astype(np.uint8)
    out.write_records(data, offsets, lengths, channels, times)
