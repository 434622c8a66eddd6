"""bagkit.bag.mcapio chunk writing and reading: the chunk builder and file writer read back by
the mcap package, bounded decompression, the walk over a chunk's records, payload spans checked
against the mcap reader."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import lz4.frame
import numpy as np
import pytest
import zstandard
from mcap.reader import make_reader
from mcap.records import Channel, Header, Message, Schema

from bagkit.bag import BagReader
from bagkit.bag.bag_files import compressor
from bagkit.bag.errors import ChunkError, CorruptBagError
from bagkit.bag.mcapio.chunk_builder import LARGE_PAYLOAD, SAMPLED_CHUNK, ChunkBuilder
from bagkit.bag.mcapio.chunks import decompress, payload_spans, walk_chunk
from bagkit.bag.mcapio.file_writer import McapFileWriter
from bagkit.bag.mcapio.message_index import ordered_offsets
from bagkit.bag.mcapio.records import (
    MESSAGE_PREFIX,
    RECORD_HEADER,
    Opcode,
    encode,
    message_index_dtype,
)

COMPRESSORS = {name: compressor(name)[1] for name in ("zstd", "lz4", "none")}
COMPRESSORS[""] = COMPRESSORS.pop("none")


def _chunk_records() -> tuple[list[bytes], list[tuple[int, int, int]]]:
    """The records of a chunk as rosbag2 writes it (Schema, Channel, then messages), one by one,
    and for each message (channel id, log time, offset of its record)."""
    parts = [
        encode(Schema(id=1, name="pkg/msg/T", encoding="ros2msg", data=b"int32 x")),
        encode(Channel(id=7, schema_id=1, topic="/t", message_encoding="cdr", metadata={})),
    ]
    placed = []
    for i, (channel_id, log_time) in enumerate([(7, 30), (9, 10), (7, 20)]):
        placed.append((channel_id, log_time, sum(len(p) for p in parts)))
        parts.append(
            encode(
                Message(
                    channel_id=channel_id,
                    sequence=i,
                    log_time=log_time,
                    publish_time=log_time,
                    data=bytes(i * 3),
                )
            )
        )
    return parts, placed


def test_walk_chunk_finds_every_message_and_the_definitions() -> None:
    parts, placed = _chunk_records()
    records = b"".join(parts)
    schemas: dict[int, Schema] = {}
    channels: dict[int, Channel] = {}
    walked = walk_chunk(records, schemas=schemas, channels=channels)
    expected: dict[int, list[tuple[int, int]]] = {}
    for channel_id, log_time, offset in placed:
        expected.setdefault(channel_id, []).append((log_time, offset))
    assert walked.by_channel == expected  # stored order, not time order
    assert walked.counts() == {7: 2, 9: 1}
    index = walked.message_index()
    assert index[7].dtype == message_index_dtype()
    assert index[7].tolist() == expected[7]
    assert [s.name for s in schemas.values()] == ["pkg/msg/T"]
    assert [(c.id, c.topic) for c in channels.values()] == [(7, "/t")]
    assert walk_chunk(records).counts() == {7: 2, 9: 1}  # definitions not asked for


def test_walk_chunk_checks_every_length_before_use() -> None:
    parts, placed = _chunk_records()
    records = b"".join(parts)
    boundaries = {sum(len(p) for p in parts[:n]) for n in range(len(parts))}
    for cut in range(len(records)):  # every prefix ends mid-record, or between two records
        if cut in boundaries:
            walked = walk_chunk(records[:cut]).counts()
            assert sum(walked.values()) == sum(1 for *_, offset in placed if offset < cut)
        else:
            with pytest.raises(CorruptBagError):
                walk_chunk(records[:cut])
    # A Message record too short for its fixed fields, though its own length fits the buffer.
    length = MESSAGE_PREFIX.size - 1
    short = RECORD_HEADER.pack(Opcode.MESSAGE, length) + bytes(length)
    with pytest.raises(CorruptBagError, match="too short"):
        walk_chunk(short)
    # Definitions met before the damage are kept: salvage still learns the channel.
    channels: dict[int, Channel] = {}
    with pytest.raises(CorruptBagError):
        walk_chunk(records[: placed[0][2]] + short, schemas={}, channels=channels)
    assert list(channels) == [7]


@pytest.mark.parametrize("compression", ["zstd", "lz4", ""])
def test_chunks_built_and_written_read_back_with_mcap(tmp_path: Path, compression: str) -> None:
    schema = Schema(id=1, name="pkg/msg/T", encoding="ros2msg", data=b"int32 x")
    channels = [
        Channel(id=c, schema_id=1, topic=f"/t{c}", message_encoding="cdr", metadata={})
        for c in (1, 2)
    ]
    path = tmp_path / "f.mcap"
    writer = McapFileWriter.create(path, Header(profile="ros2", library="t"), [schema], channels)
    expected = []
    for chunk_number in range(3):
        builder = ChunkBuilder()
        for i in range(50):
            channel_id = 1 + i % 2
            log_time = 1 + chunk_number * 1000 + i
            data = bytes([i]) * (i + chunk_number)
            builder.add(channel_id, data, log_time, log_time - 1, 2**32 + i)
            expected.append((f"/t{channel_id}", log_time, log_time - 1, i, data))
        assert builder.message_counts() == {1: 25, 2: 25}
        writer.write_chunk(builder.close(compression, COMPRESSORS[compression]), lost={})
    writer.finish([schema], channels)
    writer.close()
    with open(path, "rb") as f:
        reader = make_reader(f, validate_crcs=True)
        got = [
            (ch.topic, m.log_time, m.publish_time, m.sequence, m.data)
            for _, ch, m in reader.iter_messages(log_time_order=False)
        ]
        summary = reader.get_summary()
    assert got == expected  # sequences are stored modulo 2**32
    assert summary is not None and summary.statistics is not None
    assert summary.statistics.message_count == 150
    assert summary.statistics.channel_message_counts == {1: 75, 2: 75}
    assert len(summary.chunk_indexes) == 3


@pytest.mark.parametrize("compression", ["zstd", "lz4", ""])
def test_large_payloads_are_chunked_by_reference_and_read_back(
    tmp_path: Path, compression: str
) -> None:
    # Small and large (kept by reference) payloads mixed in one chunk, then chunks of noise, a
    # large one (its sample does not compress) and a small one (its data does not): both stored
    # uncompressed whatever the compression asked.
    schema = Schema(id=1, name="pkg/msg/T", encoding="ros2msg", data=b"uint8[] x")
    channels = [Channel(id=1, schema_id=1, topic="/t", message_encoding="cdr", metadata={})]
    path = tmp_path / "f.mcap"
    writer = McapFileWriter.create(path, Header(profile="ros2", library="t"), [schema], channels)
    mixed = [b"s" * 10, b"L" * LARGE_PAYLOAD, b"t" * 20, bytes(range(256)) * 1000, b"u"]
    rng = np.random.default_rng(1)
    noise = [rng.bytes(SAMPLED_CHUNK), rng.bytes(1000)]
    chunks = [mixed, [b"v", noise[0], b"w"], [noise[1]]]
    for number, payloads in enumerate(chunks):
        builder = ChunkBuilder()
        for i, data in enumerate(payloads):
            builder.add(1, data, 100 * number + i, 100 * number + i, i)
        assert builder.size == sum(31 + len(data) for data in payloads)
        writer.write_chunk(builder.close(compression, COMPRESSORS[compression]), lost={})
    writer.finish([schema], channels)
    writer.close()
    expected = [data for payloads in chunks for data in payloads]
    with open(path, "rb") as f:
        reader = make_reader(f, validate_crcs=True)
        got = [m.data for _, _, m in reader.iter_messages(log_time_order=False)]
        summary = reader.get_summary()
    assert got == expected
    assert summary is not None
    assert [c.compression for c in summary.chunk_indexes] == [compression, "", ""]
    with BagReader(path) as bag:
        assert [m.data for m in bag.messages()] == expected
        assert bag.problems == []


def test_decompression_never_exceeds_the_declared_size() -> None:
    records = b"\x05" * 100_000
    bomb = zstandard.ZstdCompressor(write_content_size=False).compress(records)
    assert decompress("zstd", bomb, len(records), 1 << 20) == records
    with pytest.raises(ChunkError, match="does not decompress"):
        decompress("zstd", bomb, 1000, 1 << 20)
    sized = zstandard.ZstdCompressor().compress(records)
    with pytest.raises(ChunkError, match="zstd frame holds 100000 bytes, the chunk declares 99"):
        decompress("zstd", sized, 99, 1 << 20)
    framed = lz4.frame.compress(records)
    assert decompress("lz4", framed, len(records), 1 << 20) == records
    with pytest.raises(ChunkError, match="declared 1000 bytes"):
        decompress("lz4", framed, 1000, 1 << 20)
    with pytest.raises(ChunkError, match="over the maximum chunk size of 65536"):
        decompress("zstd", bomb, len(records), 1 << 16)
    with pytest.raises(ChunkError, match="declares 0 bytes"):
        decompress("zstd", bomb, 0, 1 << 20)
    with pytest.raises(ChunkError, match="unsupported chunk compression 'brotli'"):
        decompress("brotli", bomb, 10, 1 << 20)
    with pytest.raises(ChunkError, match="does not decompress"):
        decompress("lz4", b"not lz4 at all", 10, 1 << 20)


@pytest.mark.parametrize("compression", ["zstd", "lz4", "none"])
def test_payload_spans_are_the_payloads_mcap_reads(
    write_sample_bag: Callable[..., Path], compression: str
) -> None:
    bag_path = write_sample_bag(compression=compression, chunk_size=20_000)
    with open(bag_path / "sample_0.mcap", "rb") as f:
        oracle: dict[str, list[tuple[int, bytes]]] = {}
        for _, channel, message in make_reader(f).iter_messages(log_time_order=False):
            oracle.setdefault(channel.topic, []).append((message.log_time, message.data))
    with BagReader(bag_path) as bag:
        found: dict[str, list[tuple[int, bytes]]] = {}
        chunks = 0
        for chunk in bag.chunks():
            chunks += 1
            for topic in chunk.message_index:
                log_times, starts, lengths = chunk.payloads(topic)
                assert log_times.dtype == starts.dtype == lengths.dtype == np.int64
                found.setdefault(topic, []).extend(
                    (t, chunk.records[s : s + n])
                    for t, s, n in zip(
                        log_times.tolist(), starts.tolist(), lengths.tolist(), strict=True
                    )
                )
        assert bag.problems == []
    assert chunks > 3
    assert found == oracle


def test_spans_outside_the_chunk_are_dropped_and_counted(
    write_sample_bag: Callable[..., Path],
) -> None:
    with BagReader(write_sample_bag(n_imu=20)) as bag:
        chunk = next(bag.chunks(["/imu/data"]))
        index = chunk.message_index["/imu/data"]
        good = payload_spans(chunk.records, index)
        assert good[3] == 0 and len(good[1]) == 20
        broken = index.copy()
        broken["offset"][3] = len(chunk.records) + 5  # past the end
        broken["offset"][4] = 2**64 - 1
        broken["offset"][5] = index["offset"][5] + 1  # not at a record start
        broken["offset"][6] = len(chunk.records) - 10  # header would run past the end
        log_times, starts, lengths, dropped = payload_spans(chunk.records, broken)
        assert dropped == 4
        keep = np.ones(20, dtype=bool)
        keep[3:7] = False
        assert starts.tolist() == good[1][keep].tolist()
        assert lengths.tolist() == good[2][keep].tolist()
        assert log_times.tolist() == good[0][keep].tolist()
        chunk.message_index["/imu/data"] = broken
        assert len(chunk.payloads("/imu/data")[1]) == 16
        assert any("4 messages of /imu/data indexed outside" in p for p in bag.problems)
    empty = payload_spans(b"", np.zeros(2, dtype=message_index_dtype()))
    assert empty[3] == 2 and len(empty[1]) == 0


@pytest.mark.parametrize(
    ("channels", "lower", "upper"),
    [
        (1, 0, 1 << 64),  # one channel in order: the bisection path
        (1, 30, 70),
        (3, 0, 1 << 64),  # interleaved channels: the sort
        (3, 25, 61),
        (3, 200, 300),  # nothing in range
    ],
)
@pytest.mark.parametrize("shuffled", [False, True])
def test_ordered_offsets_are_numpys_lexsort_of_the_entries(
    channels: int, lower: int, upper: int, shuffled: bool
) -> None:
    # Entries with repeated log times, as several channels of one chunk hold them; shuffled,
    # a channel's entries are not in log-time order (a recorder writing in batches).
    rng = np.random.default_rng(channels + lower)
    parts = []
    for channel in range(channels):
        times = np.sort(rng.integers(0, 100, 40))
        offsets = np.arange(40) * 16 * channels + channel * 16
        entries = np.zeros(40, dtype=message_index_dtype())
        entries["log_time"], entries["offset"] = times, offsets
        parts.append(rng.permutation(entries) if shuffled else entries)
    both = np.concatenate(parts)
    inside = both[(both["log_time"] >= lower) & (both["log_time"] < upper)]
    expected = inside["offset"][np.lexsort((inside["offset"], inside["log_time"]))].tolist()
    got = ordered_offsets([p.tobytes() for p in parts], lower, upper)
    assert got == expected
