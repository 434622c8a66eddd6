"""An MCAP file's messages as :class:`BagMessage` objects in log-time order, for
:class:`~bagkit.bag.mcap_file.McapFile`: each chunk's through its message index, one at a
time as they are taken, and chunks that overlap in time merged within a memory budget."""

from __future__ import annotations

import heapq
import operator
from collections.abc import Callable, Iterable, Iterator

from bagkit.bag.mcapio import Block, ChunkContents, extent
from bagkit.bag.mcapio.message_index import ordered_offsets
from bagkit.bag.mcapio.records import MESSAGE_RECORD_HEADER, RECORD_HEADER, ChunkIndex, Opcode
from bagkit.bag.messages import BagMessage, make_message

_LOG_TIME = operator.attrgetter("log_time")
_OFFSET = operator.itemgetter(0)
# Overlapping chunks are merged in log-time order while they need at most this many times
# max_chunk_size of memory (uncompressed); beyond, order is given up rather than memory.
MERGE_BUDGET_CHUNKS = 4


def in_log_time_order(
    blocks: Iterable[Block],
    messages_of: Callable[[Block], Iterator[BagMessage]],
    max_chunk_size: int,
    on_out_of_order: Callable[[], None],
) -> Iterator[BagMessage]:
    """The messages of ``blocks`` (sorted by start time; ``messages_of`` gives each one's in
    log-time order), merged where blocks overlap; ``on_out_of_order`` is called where an
    overlap goes beyond the budget and order is given up."""
    # A block that starts before the ones already taken end overlaps them: such a group is
    # merged (all its chunks in memory at once), up to MERGE_BUDGET_CHUNKS chunks' worth;
    # groups simply follow one another.
    budget = MERGE_BUDGET_CHUNKS * max_chunk_size
    group: list[tuple[int, Iterator[BagMessage]]] = []
    group_end = group_bytes = 0
    for block in blocks:
        size = block.uncompressed_size if isinstance(block, ChunkIndex) else block.length
        size = min(size, max_chunk_size)  # larger ones are not read
        overlaps = bool(group) and block.message_start_time < group_end
        if group and (not overlaps or group_bytes + size > budget):
            if overlaps:
                on_out_of_order()
            yield from _merged(group)
            group, group_bytes = [], 0
        group_end = max(group_end, block.message_end_time) if group else block.message_end_time
        group_bytes += size
        group.append((extent(block)[0], messages_of(block)))
    yield from _merged(group)


def _merged(blocks: list[tuple[int, Iterator[BagMessage]]]) -> Iterator[BagMessage]:
    """Merge the log-time ordered messages of overlapping ``(file offset, messages)`` blocks.

    Equal log times come in storage order: heapq.merge takes them from the earlier iterable.
    """
    if len(blocks) == 1:
        return blocks[0][1]
    return heapq.merge(*(messages for _, messages in sorted(blocks, key=_OFFSET)), key=_LOG_TIME)


def chunk_messages(
    read: Callable[[], ChunkContents | None],
    wanted: set[int],
    window: tuple[int, int],
    channel_topics: dict[int, str],
    on_lost: Callable[[int], None],
) -> Iterator[BagMessage]:
    """The messages of the chunk ``read`` gives (None: none; read when the first message is
    taken) on the ``wanted`` channels logged in ``window`` (``[lower, upper)``) in log-time
    order, built one at a time as they are taken; ``on_lost`` gets the count of index entries
    that point at no message, at the end.

    Only the message index is ordered up front (without numpy: ``bagkit info`` reads the
    events of services this way): a replay that takes the next message when it is due is
    not held up for the whole chunk's worth of objects.
    """
    chunk = read()
    if chunk is None:
        return
    parts = [entries for channel, entries in chunk.entries.items() if channel in wanted]
    if not parts:
        return
    offsets = ordered_offsets(parts, *window)
    records = chunk.records
    size = len(records)
    unpack = MESSAGE_RECORD_HEADER.unpack_from
    lost = 0
    last_header = size - MESSAGE_RECORD_HEADER.size
    for offset in offsets:
        if offset > last_header:
            lost += 1
            continue
        opcode, length, channel_id, sequence, log_time, publish_time = unpack(records, offset)
        end = offset + RECORD_HEADER.size + length
        if opcode != Opcode.MESSAGE or end > size or channel_id not in channel_topics:
            lost += 1
            continue
        yield make_message(
            channel_topics[channel_id],
            records[offset + MESSAGE_RECORD_HEADER.size : end],
            log_time,
            publish_time,
            sequence,
        )
    if lost:
        on_lost(lost)


def message_at(
    chunk: ChunkContents, offset: int, channel_topics: dict[int, str]
) -> BagMessage | None:
    """The Message record at ``offset`` in ``chunk``'s records, None when there is none."""
    records = chunk.records
    if offset + MESSAGE_RECORD_HEADER.size > len(records):
        return None
    opcode, length, channel_id, sequence, log_time, publish_time = (
        MESSAGE_RECORD_HEADER.unpack_from(records, offset)
    )
    end = offset + RECORD_HEADER.size + length
    topic = channel_topics.get(channel_id)
    if opcode != Opcode.MESSAGE or end > len(records) or topic is None:
        return None
    data = records[offset + MESSAGE_RECORD_HEADER.size : end]
    return make_message(topic, data, log_time, publish_time, sequence)
