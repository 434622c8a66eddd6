"""bagkit.bag.mcapio.chunk_indexes: rows as the mcap package encodes them, order, bounds, size;
FileIndex.blocks over them."""

from __future__ import annotations

import random
import struct
import tracemalloc

import pytest

from bagkit.bag.errors import CorruptBagError
from bagkit.bag.mcapio.chunk_indexes import ChunkIndexes
from bagkit.bag.mcapio.chunks import MessageRun
from bagkit.bag.mcapio.records import RECORD_HEADER, ChunkIndex, Header, encode
from bagkit.bag.mcapio.summary import FileIndex


def _chunk_indexes(count: int, seed: int = 1) -> list[ChunkIndex]:
    rng = random.Random(seed)
    found = []
    for _ in range(count):
        start = rng.randrange(2**64)
        channels = rng.sample(range(2**16), rng.randrange(4))
        found.append(
            ChunkIndex(
                message_start_time=start,
                message_end_time=rng.randrange(2**64),
                chunk_start_offset=rng.randrange(2**64),
                chunk_length=rng.randrange(2**64),
                message_index_offsets={c: rng.randrange(2**64) for c in channels},
                message_index_length=rng.randrange(2**64),
                compression=rng.choice(["", "zstd", "lz4", "\u00e9"]),
                compressed_size=rng.randrange(2**64),
                uncompressed_size=rng.randrange(2**64),
            )
        )
    return found


def _table(chunks: list[ChunkIndex]) -> ChunkIndexes:
    table = ChunkIndexes()
    for chunk in chunks:
        table.append_record(encode(chunk)[RECORD_HEADER.size :])
    return table


def test_rows_are_the_records_parsed() -> None:
    chunks = _chunk_indexes(50)
    table = _table(chunks)
    assert len(table) == len(chunks)
    assert list(table) == chunks
    assert table[-1] == chunks[-1]
    assert table[3:6] == chunks[3:6]
    with pytest.raises(IndexError):
        table[len(chunks)]
    for row, chunk in enumerate(chunks):
        assert list(table.channels(row)) == list(chunk.message_index_offsets)
        assert table.indexed(row) == bool(chunk.message_index_offsets)


def test_appended_rows_equal_parsed_ones() -> None:
    chunks = _chunk_indexes(20, seed=2)
    appended = ChunkIndexes()
    for chunk in chunks:
        appended.append(chunk)
    assert list(appended) == list(_table(chunks))


def test_rows_by_and_take_sort_and_leave_out() -> None:
    chunks = _chunk_indexes(40, seed=3)
    # A tie: offset decides.
    chunks[5] = chunks[5]._replace(message_start_time=chunks[9].message_start_time)
    table = _table(chunks)
    rows = table.rows_by(table.start_times, table.chunk_offsets)
    expected = sorted(chunks, key=lambda c: (c.message_start_time, c.chunk_start_offset))
    assert list(table.take(rows)) == expected
    assert list(table.take(rows[::2])) == expected[::2]
    by_offset = table.rows_by(table.chunk_offsets)
    assert [table[r] for r in by_offset] == sorted(chunks, key=lambda c: c.chunk_start_offset)


def test_a_record_cut_anywhere_is_a_corrupt_bag_error() -> None:
    (chunk,) = _chunk_indexes(1, seed=4)
    chunk = chunk._replace(message_index_offsets={1: 10, 2: 20}, compression="zstd")
    content = encode(chunk)[RECORD_HEADER.size :]
    for cut in range(len(content)):
        table = ChunkIndexes()
        with pytest.raises(CorruptBagError):
            table.append_record(content[:cut])
        assert not table  # nothing half-added


def test_hostile_lengths_are_corrupt_bag_errors() -> None:
    (chunk,) = _chunk_indexes(1, seed=5)
    chunk = chunk._replace(message_index_offsets={7: 70}, compression="lz4")
    content = bytearray(encode(chunk)[RECORD_HEADER.size :])
    map_at, name_at = 32, 32 + 4 + 10 + 8
    for at, value, match in [
        (map_at, 2**32 - 1, "runs past the end"),
        (map_at, 9, "not whole entries"),
        (name_at, 2**32 - 1, "runs past the end"),
    ]:
        hostile = bytearray(content)
        struct.pack_into("<I", hostile, at, value)
        with pytest.raises(CorruptBagError, match=match):
            ChunkIndexes().append_record(hostile)
    hostile = bytearray(content)
    hostile[name_at + 4 : name_at + 7] = b"\xff\xfe\xfd"
    with pytest.raises(CorruptBagError, match="not UTF-8"):
        ChunkIndexes().append_record(hostile)


def test_a_chunk_costs_columns_not_an_object() -> None:
    """About 64 bytes a row and 10 a channel (a ChunkIndex object with its dict: ~680)."""
    chunks = _chunk_indexes(10_000, seed=6)
    records = [encode(chunk)[RECORD_HEADER.size :] for chunk in chunks]
    channels = sum(len(chunk.message_index_offsets) for chunk in chunks)
    tracemalloc.start()
    try:
        before = tracemalloc.get_traced_memory()[0]
        table = ChunkIndexes()
        for content in records:
            table.append_record(content)
        held = tracemalloc.get_traced_memory()[0] - before
    finally:
        tracemalloc.stop()
    assert len(table) == len(chunks)
    # 8 columns of 8 bytes, a 4-byte compression id, a u16 and a u64 per channel; arrays grow
    # by up to an eighth more than they hold.
    exact = len(chunks) * (8 * 8 + 4) + channels * 10
    assert held < 1.25 * exact + 4096


def test_file_index_blocks_merge_chunks_and_runs_by_start_then_offset() -> None:
    chunks = _chunk_indexes(30, seed=7)
    for n, chunk in enumerate(chunks):  # small times, so that runs fall among them
        start = n % 7 * 10 + 1
        chunks[n] = chunk._replace(
            message_start_time=start,
            message_end_time=start + (5 if n % 5 else -1),  # some empty
            message_index_offsets={} if n % 5 == 0 else chunk.message_index_offsets,
        )
    in_order = sorted(chunks, key=lambda c: (c.message_start_time, c.chunk_start_offset))
    runs = [MessageRun(offset, 10, start, start + 3) for offset, start in [(90, 25), (5, 0)]]
    index = FileIndex(header=Header(profile="ros2", library="test"))
    index.chunk_indexes = _table(in_order)
    index.message_runs = runs

    def key(block: ChunkIndex | MessageRun) -> tuple[int, int]:
        offset = block.offset if isinstance(block, MessageRun) else block.chunk_start_offset
        return block.message_start_time, offset

    everything = sorted([*in_order, *runs], key=key)
    assert list(index.blocks(with_empty=True)) == everything
    with_messages = [b for b in everything if b.message_start_time <= b.message_end_time]
    assert len(with_messages) < len(everything)
    assert list(index.blocks()) == with_messages
