"""The last message of each channel before a time, found from the chunks' indexes.

Blocks are visited from the latest bound down (a chunk's end time, capped at the time asked):
a channel is settled once the next block's bound is earlier than the message already found
for it, so only the Message Index records of the chunks near the time are read, never the
bag from its start. Ties in log time go to the message stored last (the last one a log-time
ordered read yields).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from bagkit.bag.mcapio.chunks import Block, extent

if TYPE_CHECKING:
    import numpy as np

_MAX_TIME = (1 << 64) - 1
BlockIndex = Callable[[Block, set[int]], "dict[int, np.ndarray] | None"]
"""The ``message_index_dtype`` entries of the given channels in a block (None: unreadable)."""


@dataclass(frozen=True, slots=True)
class Latest:
    """Where the last message of a channel before the time is: its block, its record offset."""

    log_time: int
    block: Block
    offset: int

    def key(self) -> tuple[int, int, int]:
        """Log time, then storage order (the block's file offset, the record's in the block)."""
        return self.log_time, extent(self.block)[0], self.offset


def latest_before(
    blocks: Iterable[Block],
    channels: set[int],
    before_ns: int,
    block_index: BlockIndex,
) -> dict[int, Latest]:
    """The last message with ``log_time < before_ns`` of each of ``channels`` that has one.

    Args:
        blocks: the file's chunks and runs of loose messages (with their time bounds).
        channels: the channel ids wanted.
        before_ns: the time (exclusive).
        block_index: reads a block's message index for some channels (Message Index records
            where the chunk has them, else the chunk itself).
    """
    candidates = sorted(
        (b for b in blocks if b.message_start_time < before_ns),
        key=lambda b: min(b.message_end_time, before_ns - 1),
        reverse=True,
    )
    found: dict[int, Latest] = {}
    for block in candidates:
        bound = min(block.message_end_time, before_ns - 1)
        # A channel whose message found is later than this bound is settled (equal: a tie
        # stored later may still be here).
        open_channels = {c for c in channels if c not in found or found[c].log_time <= bound}
        if not open_channels:
            break
        entries = block_index(block, open_channels)
        for channel, index in (entries or {}).items():
            if channel not in open_channels:
                continue
            best = _last_entry(index, before_ns)
            if best is None:
                continue
            latest = Latest(best[0], block, best[1])
            if channel not in found or latest.key() > found[channel].key():
                found[channel] = latest
    return found


def _last_entry(index: np.ndarray, before_ns: int) -> tuple[int, int] | None:
    """(log time, offset) of the last entry before ``before_ns`` (ties: largest offset)."""
    import numpy as np

    if not len(index) or before_ns <= 0:
        return None
    times = index["log_time"]
    earlier = np.flatnonzero(times < np.uint64(min(before_ns, _MAX_TIME)))
    if not len(earlier):
        return None
    last_time = times[earlier].max()
    at_last = earlier[times[earlier] == last_time]
    offset = index["offset"][at_last].max()
    return int(last_time), int(offset)
