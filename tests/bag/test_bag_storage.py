"""The storage back-ends behind bagkit.bag.storage.StorageFile, one bag of both formats."""

from __future__ import annotations

import shutil
from collections.abc import Callable
from pathlib import Path

import pytest
from test_bag_sqlite_hostile import write_db3

from bagkit.bag import BagReader
from bagkit.bag.mcap_file import McapFile
from bagkit.bag.sqlite3_file import Sqlite3File


def test_back_ends_read_nothing_before_open(tmp_path: Path) -> None:
    missing = tmp_path / "missing"
    for storage in (
        McapFile(missing.with_suffix(".mcap")),
        Sqlite3File(missing.with_suffix(".db3")),
    ):
        assert storage.topics == {} and storage.problems == []
        storage.close()  # also before open()


def test_one_bag_of_mcap_and_sqlite3_files(
    tmp_path: Path, write_sample_bag: Callable[..., Path]
) -> None:
    bag_dir = tmp_path / "mixed"
    bag_dir.mkdir()
    (mcap,) = write_sample_bag(n_imu=250, chunk_size=4096).glob("*.mcap")
    shutil.copy(mcap, bag_dir / "a_0.mcap")
    write_db3(bag_dir / "b_0.db3", n=30)
    with BagReader(bag_dir) as bag:
        assert bag.storage == "mcap,sqlite3"
        assert bag.has_summary
        seen: dict[str, list[int]] = {}
        for message in bag.messages():
            seen.setdefault(message.topic, []).append(message.log_time)
        assert set(seen) == {"/imu/data", "/text", "/a", "/b"}
        # From the indexes (Message Index records, the messages table), no message read.
        assert bag.topic_spans() == {t: (min(times), max(times)) for t, times in seen.items()}
        chunks = list(bag.chunks())
        assert len(chunks) > 1  # the MCAP file's, then the SQLite3 file's rows as one chunk
        assert [chunk.file.name for chunk in chunks].count("b_0.db3") == 1
        for topic, times in seen.items():
            in_chunks = [t for c in chunks for t in c.payloads(topic)[0].tolist()]
            assert sorted(in_chunks) == sorted(times)
        db3 = {m.log_time: m.data for m in bag.messages(["/a", "/b"])}
        (rows,) = [c for c in chunks if c.file.name == "b_0.db3"]
        for topic in ("/a", "/b"):
            log_times, starts, lengths = rows.payloads(topic)
            for log_time, start, length in zip(log_times, starts, lengths, strict=True):
                assert rows.records[start : start + length] == db3[log_time]
        assert bag.compression == "zstd" and bag.uncompressed_size > bag.compressed_size > 0


def test_a_back_end_without_chunks_has_its_messages_laid_out_as_chunks(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A back-end whose chunks() yields none (as the Protocol once allowed) still feeds the
    bulk decoders: the reader lays its messages out as chunks."""

    db3 = write_db3(tmp_path / "rows.db3", n=30)
    with BagReader(db3) as bag:
        expected = [(m.topic, m.log_time, m.data) for m in bag.messages()]
    monkeypatch.setattr(
        Sqlite3File, "chunks", lambda self, topics, start_ns=None, end_ns=None: iter(())
    )
    with BagReader(db3) as bag:
        chunks = list(bag.chunks())
    got = [
        (topic, t, c.records[s : s + n])
        for c in chunks
        for topic in c.message_index
        for t, s, n in zip(*(a.tolist() for a in c.payloads(topic)), strict=True)
    ]
    assert sorted(got) == sorted(expected)
    assert len(got) == 30
