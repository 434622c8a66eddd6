"""bagkit.bag.mcapio.salvage on crafted cuts and damaged records: the messages counted are those
of the chunks the mcap package's stream reader can read whole."""

from __future__ import annotations

import io
import struct
from collections.abc import Callable
from pathlib import Path

import pytest
from mcap.exceptions import McapError
from mcap.records import Message
from mcap.stream_reader import StreamReader

from bagkit.bag.errors import CorruptBagError
from bagkit.bag.mcapio import Source, read_file_index
from bagkit.bag.mcapio.data_section import DataSection
from bagkit.bag.mcapio.records import Opcode

RECORD = struct.Struct("<BQ")


def _intact(data: bytes) -> int:
    """Messages the mcap stream reader yields before it fails (whole chunks only)."""
    count = 0
    try:
        for record in StreamReader(io.BytesIO(data)).records:
            count += isinstance(record, Message)
    except (McapError, EOFError, ValueError, struct.error):
        pass
    return count


def _record_starts(data: bytes) -> list[tuple[int, int]]:
    """(offset, opcode) of each record of the data section."""
    starts = []
    pos = 8
    while pos < len(data):
        opcode, length = RECORD.unpack_from(data, pos)
        starts.append((pos, opcode))
        if opcode == Opcode.DATA_END:
            break
        pos += RECORD.size + length
    return starts


@pytest.fixture
def mcap_bytes(write_sample_bag: Callable[..., Path]) -> bytes:
    bag = write_sample_bag(n_imu=120, chunk_size=4_000)
    return (bag / "sample_0.mcap").read_bytes()


def test_cuts_at_and_around_every_record_keep_the_whole_chunks(mcap_bytes: bytes) -> None:
    starts = _record_starts(mcap_bytes)
    assert sum(op == Opcode.CHUNK for _, op in starts) >= 5
    after_header = starts[1][0]
    cuts = sorted({s + d for s, _ in starts[1:] for d in (0, 1, 9, 30)} - {len(mcap_bytes)})
    with pytest.raises(CorruptBagError, match=r"header record.s length \(24\) runs past the end"):
        read_file_index(Source(io.BytesIO(mcap_bytes[: after_header - 1]), "cut.mcap"))
    for cut in cuts:
        data = mcap_bytes[:cut]
        index = read_file_index(Source(io.BytesIO(data), "cut.mcap"))
        assert index.message_count == _intact(data), cut
        assert not index.summary
        data_end = starts[-1][0] + RECORD.size + 4  # the data section ends with Data End
        cut_in_a_record = cut not in {s for s, _ in starts} and cut < data_end
        # Cut in Data End, or in rosbag2's Metadata past its name (both written after the last
        # message, as the file closes): nothing that held a message was lost.
        torn = max(s for s, _ in starts if s <= cut)
        torn_op = mcap_bytes[torn]
        name_end = torn + RECORD.size + 4 + len(b"rosbag2")
        after_messages = torn_op == Opcode.DATA_END or (
            torn_op == Opcode.METADATA
            and cut >= name_end
            and mcap_bytes[torn + RECORD.size + 4 : name_end] == b"rosbag2"
        )
        truncated = [p for p in index.problems if "truncated at byte" in p]
        assert bool(truncated) == (cut_in_a_record and not after_messages), (cut, index.problems)


def test_a_damaged_record_is_skipped_and_the_rest_counted(mcap_bytes: bytes) -> None:
    starts = _record_starts(mcap_bytes)
    data = bytearray(mcap_bytes[: starts[-1][0]])  # up to Data End: no summary
    total = _intact(bytes(data))
    # A Metadata record between the chunks gets a name that is not UTF-8.
    metadata_at = next(s for s, op in starts if op == Opcode.METADATA)
    data[metadata_at + RECORD.size + 4] = 0xFF
    index = read_file_index(Source(io.BytesIO(bytes(data)), "damaged.mcap"))
    assert index.message_count == total
    assert index.metadata == []
    assert index.problems == [
        f"damaged.mcap: unreadable record at byte {metadata_at} (a string is not UTF-8 "
        "(invalid start byte)), skipped"
    ]


def test_an_unindexed_last_chunk_that_fails_its_crc_is_reported(mcap_bytes: bytes) -> None:
    starts = _record_starts(mcap_bytes)
    chunks = [s for s, op in starts if op == Opcode.CHUNK]
    end = next(s for s, _ in starts if s > chunks[-1])  # the last chunk, without its indexes
    data = bytearray(mcap_bytes[:end])
    crc_at = chunks[-1] + RECORD.size + 24
    struct.pack_into("<I", data, crc_at, struct.unpack_from("<I", data, crc_at)[0] ^ 1)
    index = read_file_index(Source(io.BytesIO(bytes(data)), "c.mcap"))
    assert index.message_count == _intact(mcap_bytes[: chunks[-1]])
    assert len(index.problems) == 1
    assert f"chunk at byte {chunks[-1]}" in index.problems[0]
    assert "CRC mismatch" in index.problems[0]
    unchecked = read_file_index(Source(io.BytesIO(bytes(data)), "c.mcap"), check_crc=False)
    assert unchecked.message_count == _intact(mcap_bytes[:end])
    assert unchecked.problems == []


def test_the_data_section_walk_stops_where_the_file_is_cut(mcap_bytes: bytes) -> None:
    starts = _record_starts(mcap_bytes)
    whole = DataSection(Source(io.BytesIO(mcap_bytes), "whole.mcap"))
    walked = []
    for offset, opcode, _ in whole:
        walked.append((offset, opcode))
        if opcode == Opcode.DATA_END:
            break
    assert walked == starts  # from the Header to the Data End, yielded too
    assert whole.cut_at is None
    chunk_at = next(s for s, op in starts if op == Opcode.CHUNK)
    (length,) = struct.unpack_from("<Q", mcap_bytes, chunk_at + 1)
    for cut, cut_length in ((chunk_at + 4, None), (chunk_at + RECORD.size + 1, length)):
        records = DataSection(Source(io.BytesIO(mcap_bytes[:cut]), "cut.mcap"))
        assert [offset for offset, _, _ in records] == [s for s, _ in starts if s < chunk_at]
        assert (records.cut_at, records.cut_length) == (chunk_at, cut_length)
