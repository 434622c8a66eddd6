"""Bulk CDR decoding of many messages of one type at once with numpy structured dtypes.

Messages are grouped by the values of their length prefixes (string lengths such as
``header.frame_id``, sequence counts), which fixes every other field's offset; each group is
then read with one structured dtype and handed out as columns, one array per leaf field
(:meth:`BulkGroup.columns`). Messages that do not fit (big-endian or XCDR2 encapsulation,
unexpected sizes, a length prefix larger than the payload, a span outside the buffer, too many
distinct layouts) are handed back for the general decoder, so bulk decoding never guesses.

Statistics accumulate moments from the columns; a table builder writes each group's columns
at its ``indexes`` and fills the leftover rows from the general decoder.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from bagkit.decode.layout import CDR_LE, CdrLayout, NeedLength, ResolvedLayout

# CDR writers pad a payload to a multiple of 4 bytes at most; rosbags accepts the same.
MAX_TRAILING_PADDING = 3
# Beyond this many distinct prefix values in one batch, per-message decoding is as fast.
MAX_GROUPS = 256


@dataclass(frozen=True, slots=True)
class BulkGroup:
    """Messages sharing one layout: ``values[i]`` is the message at ``indexes[i]`` of the batch."""

    layout: ResolvedLayout
    indexes: np.ndarray
    values: np.ndarray

    def columns(self, paths: Iterable[str]) -> dict[str, np.ndarray]:
        """Leaf path -> values of this group's messages (views of the buffer, in ``indexes``
        order); see :meth:`ResolvedLayout.columns`."""
        return self.layout.columns(self.values, paths)


def read_at(buf: np.ndarray, positions: np.ndarray, dtype: str) -> np.ndarray:
    """The number of ``dtype`` (``"<u4"``, ``"<u8"``) at each of ``positions`` in the contiguous
    byte array ``buf``: one gather through a view of a number at every byte (unaligned), not
    a window of bytes gathered per position (benchmarks/README.md, migrate, sixth pass).
    Positions evenly spaced inside ``buf`` (a chunk of records or payloads of one size) are
    copied through one strided view instead (eleventh pass)."""
    kind = np.dtype(dtype)
    n = len(positions)
    if n > 2:
        first, step = int(positions[0]), int(positions[1] - positions[0])
        last = first + (n - 1) * step
        if (
            step > 0
            and first >= 0
            and last + kind.itemsize <= len(buf)
            and int(positions[-1]) == last
            and (np.diff(positions) == step).all()
        ):
            return np.ndarray((n,), kind, buf, first, (step,)).copy()
    count = max(len(buf) - kind.itemsize + 1, 0)
    return np.ndarray((count,), kind, buf, 0, (1,))[positions]


def read_u32(buf: np.ndarray, positions: np.ndarray) -> np.ndarray:
    """Little-endian ``uint32`` at each of ``positions`` in the byte array ``buf``."""
    return read_at(buf, positions, "<u4")


def gather(buf: np.ndarray, starts: np.ndarray, dtype: np.dtype) -> np.ndarray:
    """One record of ``dtype`` at each of ``starts`` in ``buf`` (zero-copy when evenly spaced)."""
    size = dtype.itemsize
    n = len(starts)
    if n > 1:
        steps = np.diff(starts)
        if steps[0] >= size and (steps == steps[0]).all():
            return np.ndarray(
                (n,), dtype=dtype, buffer=buf, offset=int(starts[0]), strides=(int(steps[0]),)
            )
    return sliding_window_view(buf, size)[starts].view(dtype).ravel()


def spans_inside(size: int, starts: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """Which spans ``[start, start + length)`` lie inside a buffer of ``size`` bytes."""
    return (starts >= 0) & (lengths >= 0) & (starts <= size - lengths)


def decode_bulk(
    buf: np.ndarray, starts: np.ndarray, lengths: np.ndarray, layout: CdrLayout
) -> tuple[list[BulkGroup], np.ndarray]:
    """Decode the payloads ``buf[starts[i] : starts[i] + lengths[i]]`` of one message type.

    Args:
        buf: the bytes holding the payloads (a decompressed chunk), as ``uint8``.
        starts: payload offsets in ``buf`` (int64).
        lengths: payload sizes (int64).
        layout: the type's CDR layout.

    Returns:
        The decoded groups, and the indexes (ascending) of the messages left for the general
        decoder, which include every span that is not inside ``buf``.
    """
    indexes = np.arange(len(starts))
    plain = spans_inside(len(buf), starts, lengths) & (lengths >= 4)
    head = starts[plain]
    plain[plain] = read_at(buf, head, "<u2") == int.from_bytes(CDR_LE, "little")
    leftover = [indexes[~plain]]
    groups: list[BulkGroup] = []
    pending: list[tuple[np.ndarray, tuple[int, ...]]] = [(indexes[plain], ())]
    while pending:
        members, prefixes = pending.pop()
        if not len(members):
            continue
        step = layout.resolve(prefixes)
        if isinstance(step, NeedLength):
            members, values = _read_prefixes(buf, starts, lengths, members, step, leftover=leftover)
            if not len(values):
                continue
            low = int(values.min())
            if low == values.max():  # the usual case: one frame_id, one layout
                pending.append((members, (*prefixes, low)))
                continue
            distinct = np.unique(values)
            if len(distinct) + len(groups) + len(pending) > MAX_GROUPS:
                leftover.append(members)
                continue
            for value in distinct:
                pending.append((members[values == value], (*prefixes, int(value))))
            continue
        size = step.dtype.itemsize
        member_lengths = lengths[members]
        fits = (member_lengths >= size) & (member_lengths <= size + MAX_TRAILING_PADDING)
        leftover.append(members[~fits])
        members = members[fits]
        if len(members):
            groups.append(BulkGroup(step, members, gather(buf, starts[members], step.dtype)))
    return groups, np.sort(np.concatenate(leftover))


def _read_prefixes(
    buf: np.ndarray,
    starts: np.ndarray,
    lengths: np.ndarray,
    members: np.ndarray,
    step: NeedLength,
    *,
    leftover: list[np.ndarray],
) -> tuple[np.ndarray, np.ndarray]:
    """The members whose prefix at ``step`` fits in their payload, and those prefixes.

    The others go to ``leftover``: a prefix is only trusted once the rest of the payload can
    hold what it counts, so no layout (nor dtype) is ever built from an impossible length.
    """
    room = lengths[members] - (step.offset + 4)
    fits = room >= 0
    leftover.append(members[~fits])
    members, room = members[fits], room[fits]
    values = read_u32(buf, starts[members] + step.offset)
    fits = values.astype(np.int64) * step.element_size <= room
    leftover.append(members[~fits])
    return members[fits], values[fits]
