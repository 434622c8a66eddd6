"""bagkit.bag.mcapio.records: parse(encode(record)) round trips, the mcap package as oracle (its
reader reads what is encoded, as its own records with the same fields), and lengths that do not
fit their record."""

from __future__ import annotations

import io
import re
import struct

import numpy as np
import pytest
from mcap import records as mcap_records
from mcap.stream_reader import StreamReader

from bagkit.bag.errors import CorruptBagError
from bagkit.bag.mcapio import records
from bagkit.bag.mcapio.chunk_indexes import ChunkIndexes
from bagkit.bag.mcapio.records import (
    MAGIC,
    RECORD_HEADER,
    Channel,
    ChunkIndex,
    Footer,
    Header,
    Metadata,
    MetadataIndex,
    Schema,
    Statistics,
    encode,
    iter_records,
)

SAMPLES = [
    (Header(profile="ros2", library="bagkit test"), records.parse_header),
    (Footer(summary_start=123, summary_offset_start=456, summary_crc=789), records.parse_footer),
    (
        Schema(id=3, name="pkg/msg/T", encoding="ros2msg", data=b"int32 x\n\xff"),
        records.parse_schema,
    ),
    (
        Channel(
            id=7,
            schema_id=3,
            topic="/t\u00e9",
            message_encoding="cdr",
            metadata={"offered_qos_profiles": "- depth: 10", "k": ""},
        ),
        records.parse_channel,
    ),
    (
        ChunkIndex(
            message_start_time=1,
            message_end_time=2**64 - 1,
            chunk_start_offset=8,
            chunk_length=1000,
            message_index_offsets={1: 1008, 65535: 1040},
            message_index_length=64,
            compression="zstd",
            compressed_size=900,
            uncompressed_size=4000,
        ),
        lambda content: _one_row(content)[0],
    ),
    (
        Statistics(
            message_count=5,
            schema_count=1,
            channel_count=2,
            attachment_count=0,
            metadata_count=1,
            chunk_count=1,
            message_start_time=10,
            message_end_time=20,
            channel_message_counts={1: 3, 2: 2},
        ),
        records.parse_statistics,
    ),
    (Metadata(name="rosbag2", metadata={"serialized_metadata": "a: 1"}), records.parse_metadata),
    (MetadataIndex(offset=99, length=40, name="rosbag2"), records.parse_metadata_index),
]


def _one_row(content: bytes) -> ChunkIndexes:
    """A Chunk Index record's content parsed as the one row of a table."""
    table = ChunkIndexes()
    table.append_record(content)
    return table


@pytest.mark.parametrize(("record", "parse"), SAMPLES, ids=lambda x: type(x).__name__)
def test_parse_inverts_encode(record: object, parse: object) -> None:
    data = encode(record)  # type: ignore[arg-type]
    opcode, length = RECORD_HEADER.unpack_from(data)
    assert opcode == records.Opcode[re.sub(r"(?<!^)(?=[A-Z])", "_", type(record).__name__).upper()]
    assert length == len(data) - RECORD_HEADER.size
    assert parse(data[RECORD_HEADER.size :]) == record  # type: ignore[operator]


# The stream reader yields a Footer only at the end of a file: the others, after a Header.
@pytest.mark.parametrize(
    ("record", "parse"),
    [s for s in SAMPLES if not isinstance(s[0], Footer)],
    ids=lambda x: type(x).__name__,
)
def test_the_mcap_reader_reads_what_is_encoded(record: object, parse: object) -> None:
    stream = MAGIC + encode(Header(profile="ros2", library="x")) + encode(record)  # type: ignore[arg-type]
    read = StreamReader(io.BytesIO(stream), skip_magic=False).records
    assert next(read) == mcap_records.Header(profile="ros2", library="x")
    as_read = next(read)
    assert type(as_read).__name__ == type(record).__name__
    assert vars(as_read) == record._asdict()  # type: ignore[attr-defined]


@pytest.mark.parametrize(("record", "parse"), SAMPLES, ids=lambda x: type(x).__name__)
def test_a_record_cut_short_is_a_corrupt_bag_error(record: object, parse: object) -> None:
    content = encode(record)[RECORD_HEADER.size :]  # type: ignore[arg-type]
    for cut in sorted({0, 1, len(content) // 2, len(content) - 1}):
        with pytest.raises(CorruptBagError):
            parse(content[:cut])  # type: ignore[operator]


def test_string_lengths_are_checked_against_the_record() -> None:
    huge = struct.pack("<I", 2**32 - 1) + b"ros2" + struct.pack("<I", 0)
    with pytest.raises(CorruptBagError, match="runs past the end of its 12-byte record"):
        records.parse_header(huge)


def test_a_string_that_is_not_utf8_is_a_corrupt_bag_error() -> None:
    content = struct.pack("<I", 2) + b"\xff\xfe" + struct.pack("<I", 0)
    with pytest.raises(CorruptBagError, match="not UTF-8"):
        records.parse_header(content)


def test_a_map_of_partial_entries_is_a_corrupt_bag_error() -> None:
    content = encode(SAMPLES[5][0])[RECORD_HEADER.size :]  # type: ignore[arg-type]
    fixed = struct.calcsize("<QHIIIIQQ")
    broken = content[:fixed] + struct.pack("<I", 9) + content[fixed + 4 : fixed + 13]
    with pytest.raises(CorruptBagError, match="not whole entries"):
        records.parse_statistics(broken)


def test_message_index_round_trip() -> None:
    entries = np.array([(5, 0), (6, 40)], dtype=records.message_index_dtype())
    data = records.encode_message_index(4, entries.tobytes())
    channel_id, parsed = records.parse_message_index(data[RECORD_HEADER.size :])
    assert channel_id == 4
    assert parsed.tolist() == entries.tolist()
    partial = struct.pack("<HI", 4, 17) + entries.tobytes() + b"x"
    with pytest.raises(CorruptBagError, match="not whole entries"):
        records.parse_message_index(partial)


def test_iter_records_walks_and_rejects_an_overrun() -> None:
    block = encode(SAMPLES[2][0]) + encode(SAMPLES[6][0])  # type: ignore[arg-type]
    walked = list(iter_records(block))
    assert [opcode for _, opcode, _ in walked] == [records.Opcode.SCHEMA, records.Opcode.METADATA]
    assert walked[1][0] == len(encode(SAMPLES[2][0]))  # type: ignore[arg-type]
    overrun = block[:-1]
    with pytest.raises(CorruptBagError, match="runs past the end"):
        list(iter_records(overrun))
    huge = RECORD_HEADER.pack(records.Opcode.SCHEMA, 2**64 - 1) + b"x"
    with pytest.raises(CorruptBagError, match="runs past the end"):
        list(iter_records(huge))
