"""Compression bombs: a chunk that expands to 1.25 GiB is refused without the memory, whatever it
declares, and the intact chunk beside it is read. Memory is checked in a subprocess whose address
space is limited to 1 GiB (RLIMIT_AS): an unbounded decompression could not fit."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import lz4.frame
import pytest
import zstandard
from bag_samples import STRING, string_cdr

from bagkit.bag import BagReader, TopicInfo
from bagkit.bag.bag_files import compressor
from bagkit.bag.bag_topics import BagTopics
from bagkit.bag.mcapio.chunk_builder import ChunkBuilder, ClosedChunk
from bagkit.bag.mcapio.file_writer import McapFileWriter
from bagkit.bag.mcapio.records import Chunk, Header, encode_chunk_header

BOMB_SIZE = 1280 << 20  # 1.25 GiB of zeros
PIECE = b"\0" * (1 << 20)
INTACT = 10


def _zstd_bomb() -> bytes:
    compressor = zstandard.ZstdCompressor(level=1).compressobj()  # no content size
    parts = [compressor.compress(PIECE) for _ in range(BOMB_SIZE // len(PIECE))]
    return b"".join(parts) + compressor.flush()


def _lz4_bomb() -> bytes:
    compressor = lz4.frame.LZ4FrameCompressor()
    parts = [compressor.begin()]
    parts += [compressor.compress(PIECE) for _ in range(BOMB_SIZE // len(PIECE))]
    return b"".join(parts) + compressor.flush()


def _bomb_bag(path: Path, compression: str, data: bytes, declared: int) -> Path:
    """A .mcap file with an intact chunk of INTACT messages, then the bomb chunk."""
    topics = BagTopics()
    schema, channel = topics.add(TopicInfo("/text", STRING), None)
    writer = McapFileWriter.create(
        path,
        Header(profile="ros2", library="t"),
        [schema],
        [channel],  # type: ignore[list-item]
    )
    intact = ChunkBuilder()
    for i in range(INTACT):
        intact.add(1, string_cdr(f"m{i}"), 1000 + i, 1000 + i, i)
    writer.write_chunk(intact.close("", compressor("none")[1]), lost={})
    header = encode_chunk_header(
        Chunk(
            message_start_time=2000,
            message_end_time=2000,
            uncompressed_size=declared,
            uncompressed_crc=0,
            compression=compression,
            data=data,
        )
    )
    writer.write_chunk(
        ClosedChunk(header, (data,), b"", {}, 2000, 2000, compression, declared, {}), lost={}
    )
    writer.finish([schema], [channel])  # type: ignore[list-item]
    writer.close()
    return path


@pytest.fixture(scope="module")
def bombs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("bombs")
    zstd, lz4_data = _zstd_bomb(), _lz4_bomb()
    assert len(zstd) < 200_000 and len(lz4_data) < 6_000_000
    return {
        "zstd-honest": _bomb_bag(root / "zstd-honest.mcap", "zstd", zstd, BOMB_SIZE),
        "zstd-lying": _bomb_bag(root / "zstd-lying.mcap", "zstd", zstd, 1 << 20),
        "lz4-honest": _bomb_bag(root / "lz4-honest.mcap", "lz4", lz4_data, BOMB_SIZE),
        "lz4-lying": _bomb_bag(root / "lz4-lying.mcap", "lz4", lz4_data, 1 << 20),
    }


CHILD = textwrap.dedent(
    """
    import json, resource, sys
    resource.setrlimit(resource.RLIMIT_AS, (1 << 30, 1 << 30))
    from bagkit.bag import BagReader
    from bagkit.stats import summarize
    with BagReader(sys.argv[1]) as bag:
        messages = sum(1 for _ in bag.messages())
        problems = bag.problems
    summary = summarize([sys.argv[1]])
    print(json.dumps({
        "messages": messages,
        "problems": problems,
        "summarized": sum(t.count for t in summary.topics),
        "summary_problems": list(summary.problems),
        # The peak of this process's own memory: ru_maxrss keeps the parent's resident size
        # across fork and exec, so a test process grown large would count in it.
        "peak_rss_kib": next(
            int(line.split()[1]) for line in open("/proc/self/status") if line.startswith("VmHWM:")
        ),
    }))
    """
)


@pytest.mark.parametrize("name", ["zstd-honest", "zstd-lying", "lz4-honest", "lz4-lying"])
def test_a_bomb_costs_its_chunk_not_the_memory(bombs: dict[str, Path], name: str) -> None:
    run = subprocess.run(
        [sys.executable, "-c", CHILD, str(bombs[name])],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert run.returncode == 0, run.stderr
    result = json.loads(run.stdout)
    assert result["messages"] == result["summarized"] == INTACT
    assert len(result["problems"]) == 1
    assert result["summary_problems"] == result["problems"]
    if name.endswith("honest"):
        assert f"declares {BOMB_SIZE} bytes uncompressed, over the maximum" in result["problems"][0]
    else:
        assert "does not decompress" in result["problems"][0]
    assert result["peak_rss_kib"] < 300 * 1024


def test_a_larger_maximum_reads_a_large_chunk(tmp_path: Path) -> None:
    builder = ChunkBuilder()
    for i in range(2100):
        builder.add(1, string_cdr("x" * 1000), 2000, 2000, i)
    records = bytes(builder.records)
    assert len(records) > 2 << 20
    data = zstandard.ZstdCompressor().compress(records)
    path = _bomb_bag(tmp_path / "big.mcap", "zstd", data, len(records))
    with BagReader(path, max_chunk_size=1 << 20) as bag:
        assert sum(1 for _ in bag.messages()) == INTACT
        assert "over the maximum chunk size of 1048576" in bag.problems[0]
    with BagReader(path, max_chunk_size=4 << 20) as bag:
        assert sum(1 for _ in bag.messages()) == INTACT + 2100
        assert bag.problems == []
