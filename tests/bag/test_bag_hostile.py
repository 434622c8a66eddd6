"""Hostile MCAP files, crafted from a small valid bag by patching fields: each is a clean
BagkitError or a problem that costs the damaged part only; the intact messages are still read."""

from __future__ import annotations

import struct
from collections.abc import Callable
from pathlib import Path

import pytest
from hostile_files import Layout, chunk_messages

from bagkit.bag import BagReader, CorruptBagError
from bagkit.stats import summarize
from bagkit.words import counted

CHUNK_FIELDS = 9  # a chunk record's content starts after its opcode and length
UNCOMPRESSED_SIZE = CHUNK_FIELDS + 16
CRC = CHUNK_FIELDS + 24
COMPRESSION = CHUNK_FIELDS + 28 + 4  # after the compression name's u32 length


@pytest.fixture
def layout(write_sample_bag: Callable[..., Path]) -> Layout:
    """A 330-message bag of several zstd chunks, as one file (copied out of its directory)."""
    bag = write_sample_bag(chunk_size=20_000)
    found = Layout.of(bag / "sample_0.mcap")
    assert len(found.chunks) >= 4
    found.path = bag.parent / "hostile.mcap"
    return found


def _read_all(path: Path, **options: object) -> tuple[int, list[str]]:
    with BagReader(path, **options) as bag:  # type: ignore[arg-type]
        return sum(1 for _ in bag.messages()), bag.problems


def _total(layout: Layout) -> int:
    assert layout.summary.statistics is not None
    return int(layout.summary.statistics.message_count)


@pytest.mark.parametrize("length", [2**62, 2**64 - 1])
def test_a_header_length_past_the_file_is_a_corrupt_bag_error(layout: Layout, length: int) -> None:
    layout.put(9, "<Q", length)
    with pytest.raises(CorruptBagError, match=f"header record's length \\({length}\\) runs past"):
        BagReader(layout.save()).open()


@pytest.mark.parametrize("summary_start", [2**63, 10**9, 3])
def test_a_summary_start_outside_the_file_falls_back_to_salvage(
    layout: Layout, summary_start: int
) -> None:
    layout.put(layout.footer_content, "<Q", summary_start)
    count, problems = _read_all(layout.save())
    assert count == _total(layout)
    assert problems == [
        f"hostile.mcap: summary unreadable (the footer's summary start ({summary_start}) is "
        "outside the file); the file was scanned instead"
    ]


def test_a_huge_metadata_index_length_loses_the_metadata_only(layout: Layout) -> None:
    (entry,) = layout.summary.metadata_indexes
    layout.put(layout.record_in_summary(entry) + 8, "<Q", 2**63)
    count, problems = _read_all(layout.save())
    assert count == _total(layout)
    assert len(problems) == 1
    assert "metadata 'rosbag2' unreadable" in problems[0]


@pytest.mark.parametrize("size", [2**63, 2**64 - 1, 2**62, (256 << 20) + 1])
def test_a_chunk_declaring_a_huge_size_loses_that_chunk(layout: Layout, size: int) -> None:
    chunk = layout.chunks[1]
    layout.put(chunk.chunk_start_offset + UNCOMPRESSED_SIZE, "<Q", size)
    lost = chunk_messages(layout, chunk)
    path = layout.save()
    count, problems = _read_all(path)
    assert count == _total(layout) - lost
    assert problems == [
        f"hostile.mcap: chunk at byte {chunk.chunk_start_offset} ({chunk.chunk_length} bytes) "
        f"unreadable: declares {size} bytes uncompressed, over the maximum chunk size of "
        f"{256 << 20}; {counted(lost, 'message')} lost"
    ]
    summary = summarize([path])
    assert sum(t.count for t in summary.topics) == _total(layout) - lost
    assert list(summary.problems) == problems


def test_a_non_utf8_compression_name_loses_that_chunk(layout: Layout) -> None:
    chunk = layout.chunks[2]
    layout.data[chunk.chunk_start_offset + COMPRESSION] = 0xFF
    lost = chunk_messages(layout, chunk)
    count, problems = _read_all(layout.save())
    assert count == _total(layout) - lost
    assert len(problems) == 1
    assert "a string is not UTF-8" in problems[0]
    assert f"; {counted(lost, 'message')} lost" in problems[0]


def test_a_non_utf8_name_in_a_chunk_index_falls_back_to_salvage(layout: Layout) -> None:
    chunk = layout.chunks[0]
    at = layout.record_in_summary(chunk)
    name_at = layout.data.find(b"zstd", at)
    layout.data[name_at] = 0xC3  # an incomplete two-byte sequence
    count, problems = _read_all(layout.save())
    assert count == _total(layout)
    assert len(problems) == 1
    assert "summary unreadable (a string is not UTF-8" in problems[0]


def test_message_index_offsets_past_the_chunk_lose_those_messages(layout: Layout) -> None:
    chunk = layout.chunks[0]
    index_at = min(chunk.message_index_offsets.values())
    first_entry = index_at + 9 + 2 + 4
    layout.put(first_entry + 8, "<Q", 2**40)  # the first message's offset
    layout.put(first_entry + 16 + 8, "<Q", 2**64 - 1)  # the second's
    path = layout.save()
    count, problems = _read_all(path)
    assert count == _total(layout) - 2
    assert problems == [
        f"hostile.mcap: chunk at byte {chunk.chunk_start_offset}: 2 message index entries "
        "point at no message: those messages are lost"
    ]
    summary = summarize([path])
    assert summary.problems[0].startswith("hostile.mcap: 2 messages of ")
    assert "indexed outside their chunk" in summary.problems[0]


def test_swapped_chunk_indexes_still_read_every_message(layout: Layout) -> None:
    first, second = layout.chunks[0], layout.chunks[1]
    with BagReader(layout.path.parent / "sample") as bag:
        expected = sorted((m.log_time, m.topic, m.data) for m in bag.messages())
    a, b = layout.record_in_summary(first), layout.record_in_summary(second)
    # chunk_start_offset and chunk_length follow the two times
    layout.put(a + 16, "<QQ", second.chunk_start_offset, second.chunk_length)
    layout.put(b + 16, "<QQ", first.chunk_start_offset, first.chunk_length)
    path = layout.save()
    with BagReader(path) as bag:
        got = sorted((m.log_time, m.topic, m.data) for m in bag.messages())
        assert bag.problems == []
    assert got == expected
    summary = summarize([path])
    assert sum(t.count for t in summary.topics) == len(expected)
    assert list(summary.problems) == []


def test_overlapping_chunk_indexes_are_dropped(layout: Layout) -> None:
    first, second = layout.chunks[0], layout.chunks[1]
    layout.put(layout.record_in_summary(second) + 16, "<Q", first.chunk_start_offset)
    count, problems = _read_all(layout.save())
    assert count == _total(layout) - chunk_messages(layout, second)
    assert problems == [
        f"hostile.mcap: the index of a chunk at byte {first.chunk_start_offset} "
        f"({second.chunk_length} bytes) overlaps the chunk before it: that chunk is not read"
    ]


def test_a_flipped_byte_inside_a_chunk_fails_its_crc(
    write_sample_bag: Callable[..., Path],
) -> None:
    bag = write_sample_bag(chunk_size=20_000, compression="none")
    layout = Layout.of(bag / "sample_0.mcap")
    chunk = layout.chunks[1]
    layout.data[chunk.chunk_start_offset + chunk.chunk_length - 3] ^= 0x01  # in a payload
    layout.save()
    lost = chunk_messages(layout, chunk)
    count, problems = _read_all(bag)
    assert count == _total(layout) - lost
    assert problems == [
        f"sample_0.mcap: chunk at byte {chunk.chunk_start_offset} ({chunk.chunk_length} bytes) "
        f"unreadable: CRC mismatch (the chunk is damaged); {counted(lost, 'message')} lost"
    ]
    count, problems = _read_all(bag, check_crc=False)
    assert (count, problems) == (_total(layout), [])


def test_a_crc_field_of_zero_means_not_computed(write_sample_bag: Callable[..., Path]) -> None:
    bag = write_sample_bag(chunk_size=20_000, compression="none")
    layout = Layout.of(bag / "sample_0.mcap")
    for chunk in layout.chunks:
        layout.put(chunk.chunk_start_offset + CRC, "<I", 0)
    layout.save()
    assert _read_all(bag) == (_total(layout), [])


def test_a_truncated_record_length_inside_a_chunk_loses_that_chunk(
    write_sample_bag: Callable[..., Path],
) -> None:
    bag = write_sample_bag(chunk_size=20_000, compression="none")
    layout = Layout.of(bag / "sample_0.mcap")
    chunk = layout.chunks[0]
    records_at = chunk.chunk_start_offset + COMPRESSION + 4 + 8  # "" name, then records length
    layout.put(records_at + 1, "<Q", 2**62)  # the first message record's length
    struct.pack_into("<I", layout.data, chunk.chunk_start_offset + CRC, 0)  # no CRC to catch it
    layout.save()
    count, problems = _read_all(bag)
    assert count == _total(layout) - 1
    assert problems == [
        f"sample_0.mcap: chunk at byte {chunk.chunk_start_offset}: 1 message index entries "
        "point at no message: those messages are lost"
    ]


def test_overlapping_chunks_are_merged_within_a_memory_budget(tmp_path: Path) -> None:
    from bag_samples import STRING, string_cdr

    from bagkit.bag import BagWriter, TopicInfo

    times = [(i * 7919) % 1000 for i in range(1000)]  # every chunk spans almost all of them
    with BagWriter(tmp_path / "overlap", chunk_size=2_000, compression="none") as bag:
        bag.add_topic(TopicInfo("/t", STRING))
        for i, t in enumerate(times):
            bag.write("/t", string_cdr(f"m{i}"), log_time=1 + t)
    with BagReader(tmp_path / "overlap") as reader:
        got = [m.log_time for m in reader.messages()]
        assert got == sorted(1 + t for t in times)
        assert reader.problems == []
    with BagReader(tmp_path / "overlap", max_chunk_size=4_000) as reader:
        got = [m.log_time for m in reader.messages()]
        assert sorted(got) == sorted(1 + t for t in times)
        assert got != sorted(got)
        assert len(reader.problems) == 1
        assert "chunks overlapping in time beyond 4 chunks' worth of memory" in reader.problems[0]
