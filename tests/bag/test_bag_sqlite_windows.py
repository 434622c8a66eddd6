"""The SQLite3 back-end's bulk read (bagkit.bag.sqlite3_windows): rows in windows of row ids,
payloads decompressed in runs. Small bags written by rosbags' rosbag2 writer, windows made
tiny; chunks compared with the row-by-row path (bag.messages(), same order) and with rosbags'
reader (same values)."""

from __future__ import annotations

import sqlite3
import sys
import threading
from collections.abc import Iterator
from contextlib import closing
from pathlib import Path

import numpy as np
import pytest
import zstandard
from rosbags.rosbag2 import Reader, Writer
from rosbags.rosbag2.enums import CompressionFormat, CompressionMode, StoragePlugin
from rosbags.typesys import Stores, get_typestore

from bagkit.bag import BagReader, BagWriter, TopicInfo, sqlite3_windows
from bagkit.bag.mcapio import payload_spans
from bagkit.bag.sqlite3_file import Sqlite3File
from bagkit.bag.zstd_frames import declared_sizes
from bagkit.errors import BagkitError
from bagkit.prefetch import prefetch
from bagkit.words import counted

STORE = get_typestore(Stores.ROS2_JAZZY)
STRING = "std_msgs/msg/String"
T0 = 1_700_000_000_000_000_000
Row = tuple[str, int, bytes]


def _text(text: str) -> bytes:
    return bytes(STORE.serialize_cdr(STORE.types[STRING](data=text), STRING))


def _write(path: Path, rows: list[tuple[str, int, bytes]], *, zstd: bool = False) -> Path:
    """A rosbags-written sqlite3 bag of ``rows`` (topic, time, payload) in that row order;
    topics /a, /b, /c and /empty (no message)."""
    writer = Writer(path, version=9, storage_plugin=StoragePlugin.SQLITE3)
    if zstd:
        writer.set_compression(CompressionMode.MESSAGE, CompressionFormat.ZSTD)
    with writer:
        connections = {
            topic: writer.add_connection(topic, STRING, typestore=STORE)
            for topic in ("/a", "/b", "/c", "/empty")
        }
        for topic, time, payload in rows:
            writer.write(connections[topic], time, payload)
    return path


def _interleaved(n: int, seed: int = 0) -> list[Row]:
    """``n`` messages over /a, /b, /c in an irregular mix, payloads of varied lengths."""
    rng = np.random.default_rng(seed)
    topics = rng.choice(["/a", "/b", "/c"], size=n, p=[0.6, 0.3, 0.1])
    return [
        (str(topic), T0 + i * 1000, _text(f"{i}" * int(rng.integers(1, 12))))
        for i, topic in enumerate(topics)
    ]


def _from_chunks(
    bag: BagReader,
    topics: list[str] | None = None,
    start_ns: int | None = None,
    end_ns: int | None = None,
) -> list[Row]:
    """The messages of ``bag.chunks()`` in the order their records are laid out."""
    found: list[Row] = []
    for chunk in bag.chunks(topics, start_ns, end_ns):
        records = []
        for topic in chunk.message_index:
            times, starts, lengths = chunk.payloads(topic)
            # The spans kept from the layout are those read back from its records.
            *read_back, dropped = payload_spans(chunk.records, chunk.message_index[topic])
            assert dropped == 0
            for kept, read in zip((times, starts, lengths), read_back, strict=True):
                assert kept.dtype == np.int64
                assert np.array_equal(kept, read)
            # Statistics read the payloads where they were before the layout: the same bytes.
            buffer, view_times, view_starts, view_lengths = chunk.payload_view(topic)
            assert np.array_equal(view_times, times) and np.array_equal(view_lengths, lengths)
            assert [buffer[s : s + n] for s, n in zip(view_starts, view_lengths, strict=True)] == [
                chunk.records[s : s + n] for s, n in zip(starts, lengths, strict=True)
            ]
            for time, start, length in zip(
                times.tolist(), starts.tolist(), lengths.tolist(), strict=True
            ):
                records.append((start, topic, time, chunk.records[start : start + length]))
        found += [(topic, time, data) for _, topic, time, data in sorted(records)]
    return found


def _rosbags(path: Path, topics: list[str] | None = None) -> dict[str, list[tuple[int, bytes]]]:
    """Per topic, rosbags' messages ordered by time (ties: by payload)."""
    found: dict[str, list[tuple[int, bytes]]] = {}
    with Reader(path) as reader:
        for connection, time, data in reader.messages():
            if topics is None or connection.topic in topics:
                found.setdefault(connection.topic, []).append((time, bytes(data)))
    return {topic: sorted(messages) for topic, messages in found.items()}


def _per_topic(rows: list[Row]) -> dict[str, list[tuple[int, bytes]]]:
    found: dict[str, list[tuple[int, bytes]]] = {}
    for topic, time, data in rows:
        found.setdefault(topic, []).append((time, data))
    return {topic: sorted(messages) for topic, messages in found.items()}


@pytest.fixture
def tiny_windows(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(sqlite3_windows, "ROWS_PER_WINDOW", 7)


@pytest.fixture
def by_rows(monkeypatch: pytest.MonkeyPatch) -> list[int | None]:
    """The row ids from which ``chunks`` went on by rows (the bulk read stopped)."""
    calls: list[int | None] = []
    original = Sqlite3File._row_chunks

    def spy(self: Sqlite3File, *args: object) -> Iterator[object]:
        calls.append(args[2])  # type: ignore[arg-type]
        return original(self, *args)  # type: ignore[arg-type]

    monkeypatch.setattr(Sqlite3File, "_row_chunks", spy)
    return calls


def _check(path: Path, topics: list[str] | None = None) -> list[str]:
    """Chunks equal the row path's messages in order and rosbags' in values; the problems."""
    with BagReader(path) as bag:
        chunked = _from_chunks(bag, topics)
        assert chunked == [(m.topic, m.log_time, bytes(m.data)) for m in bag.messages(topics)]
        problems = list(bag.problems)
    assert _per_topic(chunked) == _rosbags(path, topics)
    return problems


@pytest.mark.usefixtures("tiny_windows")
@pytest.mark.parametrize("zstd", [False, True], ids=["plain", "zstd"])
@pytest.mark.parametrize("topics", [None, ["/a"], ["/b", "/c"], ["/empty"]])
def test_windows_match_the_rows_and_rosbags(
    tmp_path: Path, by_rows: list[int | None], zstd: bool, topics: list[str] | None
) -> None:
    path = _write(tmp_path / "bag", _interleaved(101), zstd=zstd)
    assert _check(path, topics) == []
    assert by_rows == []  # in order: the bulk read alone


@pytest.mark.usefixtures("tiny_windows")
@pytest.mark.parametrize("topics", [None, ["/b", "/c"]])
def test_a_time_window_reads_what_the_same_bag_as_mcap_holds(
    tmp_path: Path, by_rows: list[int | None], topics: list[str] | None
) -> None:
    """Chunks of a time window hold the rows of ``[start, end)`` only (the window is in the
    query: rows outside it were all read), the messages that the MCAP chunks of the same bag
    hold in that window (McapFile's chunks may hold more: the caller keeps its window)."""
    rows = _interleaved(240)
    db3 = _write(tmp_path / "db3", rows)
    with BagWriter(tmp_path / "mcap", chunk_size=256) as writer:
        for topic in ("/a", "/b", "/c", "/empty"):
            writer.add_topic(TopicInfo(topic, STRING))
        for topic, time, payload in rows:
            writer.write(topic, payload, log_time=time)
    times = [time for _, time, _ in rows]
    windows = [
        (times[40], times[90]),
        (None, times[10]),
        (times[200], None),
        (times[7] + 1, times[30]),
    ]
    for start, end in windows:
        low, high = start if start is not None else times[0], end if end is not None else 1 << 62
        with BagReader(db3) as bag:
            from_db3 = _from_chunks(bag, topics, start, end)
            assert from_db3 == [
                (m.topic, m.log_time, bytes(m.data)) for m in bag.messages(topics, start, end)
            ]
        assert all(low <= time < high for _, time, _ in from_db3), (start, end)
        with BagReader(tmp_path / "mcap") as bag:
            from_mcap = [m for m in _from_chunks(bag, topics, start, end) if low <= m[1] < high]
        assert from_db3 == from_mcap, (start, end)
        assert from_db3
    assert by_rows == []  # in order: the bulk read alone


@pytest.mark.usefixtures("tiny_windows")
def test_ties_and_older_rows_after_newer_ones(tmp_path: Path, by_rows: list[int | None]) -> None:
    # Equal times keep their row order; every 10th message is written 3 us early, older than
    # the two written before it: some window boundary falls between them.
    rows = [
        (topic, time - (3000 if i % 10 == 9 else 0), data)
        for i, (topic, time, data) in enumerate(_interleaved(80, seed=1))
    ]
    rows += [("/a", T0 + 10**9, _text(f"tie {i}")) for i in range(12)]
    path = _write(tmp_path / "bag", rows)
    assert _check(path) == []
    assert len(by_rows) == 1  # from that window on, by rows


def test_disorder_inside_a_window_is_sorted_there(
    tmp_path: Path, by_rows: list[int | None]
) -> None:
    rows = _interleaved(127, seed=2)
    shuffled = np.random.default_rng(2).permutation(len(rows))
    path = _write(tmp_path / "bag", [rows[i] for i in shuffled])
    assert _check(path) == []
    assert by_rows == []  # a small file: one window


@pytest.mark.usefixtures("tiny_windows")
def test_values_that_do_not_add_up_go_by_rows(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, by_rows: list[int | None]
) -> None:
    path = _write(tmp_path / "bag", _interleaved(50))
    original = sqlite3_windows.RowWindows.__init__

    def short_payloads(self: sqlite3_windows.RowWindows, *args: object, **kwargs: object) -> None:
        original(self, *args, **kwargs)  # type: ignore[arg-type]
        # A payload a byte short of its length: the lengths' sum is not the payloads' size.
        self._query = self._query.replace(
            "group_concat(data, '')",
            "group_concat(CASE WHEN rowid = 23 THEN substr(data, 2) ELSE data END, '')",
        )

    monkeypatch.setattr(sqlite3_windows.RowWindows, "__init__", short_payloads)
    assert _check(path) == []
    assert len(by_rows) == 1 and by_rows[0] is not None and 1 < by_rows[0] <= 23


@pytest.mark.usefixtures("tiny_windows")
def test_a_bad_zstd_frame_in_the_middle(tmp_path: Path) -> None:
    rows = _interleaved(70)
    clean = _write(tmp_path / "clean", rows, zstd=True)
    path = _write(tmp_path / "bag", rows, zstd=True)
    (db3,) = path.glob("*.db3")
    db = sqlite3.connect(db3)
    topic_of = dict(
        db.execute("SELECT messages.id, name FROM messages JOIN topics ON topic_id = topics.id")
    )
    declared_too_much = bytearray(zstandard.ZstdCompressor().compress(b"x")[:4])
    declared_too_much += bytes([0xC0]) + (1 << 40).to_bytes(8, "little") + bytes(8)
    damaged = {
        30: b"\x28\xb5\x2f\xfd junk",  # not a frame
        31: bytes(declared_too_much),  # declares 1 TiB
    }
    unsized = zstandard.ZstdCompressor(write_content_size=False).compress(rows[40][2])
    for rowid, data in [*damaged.items(), (41, unsized)]:  # row 41: rows[40], no size
        db.execute("UPDATE messages SET data = ? WHERE id = ?", (data, rowid))
    db.commit()
    db.close()
    with BagReader(path) as bag:
        chunked = _from_chunks(bag)
        problems = list(bag.problems)
    expected = _per_topic(
        [(topic, time, data) for i, (topic, time, data) in enumerate(rows) if i + 1 not in damaged]
    )
    assert _per_topic(chunked) == expected
    with_bad = {topic_of[rowid] for rowid in damaged}
    assert len(problems) == len(with_bad)
    assert all("did not decompress" in p and p.endswith(": lost") for p in problems)
    assert sum(int(p.split(": ", 1)[1].split()[0]) for p in problems) == 2
    with BagReader(clean) as bag:  # the same bag undamaged: as rosbags reads it
        assert _per_topic(_from_chunks(bag)) == _rosbags(clean)


@pytest.mark.skipif(sys.version_info < (3, 11), reason="Connection.setlimit: Python 3.11+")
def test_a_window_over_the_byte_limit_is_halved(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, by_rows: list[int | None]
) -> None:
    monkeypatch.setattr(sqlite3_windows, "MAX_WINDOW_BYTES", 50_000)
    # Small rows first (the windows grow), then rows of 60 kB: a window of several is refused
    # by SQLite and halved down to one row, read alone (over the limit by itself).
    rows = [("/a", T0 + i, _text("s" * 10)) for i in range(40)]
    rows += [("/b", T0 + 40 + i, _text(str(i) * 60_000)) for i in range(5)]
    path = _write(tmp_path / "bag", rows)
    with BagReader(path) as bag:
        chunks = list(bag.chunks())
    large = [chunk for chunk in chunks if "/b" in chunk.message_index]
    assert [len(chunk.message_index["/b"]) for chunk in large] == [1] * 5
    assert all(len(chunk.records) < 50_000 for chunk in chunks if chunk not in large)
    assert _check(path) == [] and by_rows == []


def test_declared_sizes_agree_with_zstandard() -> None:
    rng = np.random.default_rng(3)
    frames = [
        zstandard.ZstdCompressor(level=level, **options).compress(bytes(size))
        for level in (1, 19)
        for size in (0, 1, 255, 256, 257, 65_791, 65_792, 1 << 20)
        for options in ({}, {"write_checksum": True}, {"write_dict_id": True})
    ]
    frames += [zstandard.ZstdCompressor(write_content_size=False).compress(b"abc"), b"", b"\0"]
    frames += [b"\x28\xb5\x2f\xfd" + rng.bytes(int(rng.integers(0, 20))) for _ in range(3000)]
    lengths = np.array([len(f) for f in frames], np.int64)
    got = declared_sizes(
        np.frombuffer(b"".join(frames), np.uint8), np.cumsum(lengths) - lengths, lengths
    )
    for frame, size in zip(frames, got.tolist(), strict=True):
        try:
            expected = zstandard.frame_content_size(frame)
        except zstandard.ZstdError:
            expected = -1
        assert size == (expected if expected < 1 << 63 else -1), frame.hex()


@pytest.mark.usefixtures("tiny_windows")
def test_a_damaged_page_mid_read_through_the_read_ahead(tmp_path: Path) -> None:
    """One topic, payloads in chains of overflow pages (touched only when the rows are read,
    after the count at open): each page in turn filled with garbage, the chunks read as
    ``stats`` reads them (``prefetch`` over ``chunks()``, which reads windows ahead in a thread
    of its own). Open fails cleanly, or the chunks are the undamaged bag's first messages and
    one problem says where the read stopped, or (garbage that SQLite cannot see) every message
    is read; no read-ahead thread outlives the read."""
    rows = [("/a", T0 + i * 1000, _text(f"{i}".ljust(10_000, "x"))) for i in range(40)]
    writer = Writer(tmp_path / "clean", version=9, storage_plugin=StoragePlugin.SQLITE3)
    with writer:
        connection = writer.add_connection("/a", STRING, typestore=STORE)
        for _, time, payload in rows:
            writer.write(connection, time, payload)
    (db3,) = (tmp_path / "clean").glob("*.db3")
    pristine = db3.read_bytes()
    page_size = 4096
    outcomes = {"open": 0, "stopped": 0, "whole": 0}
    for page in range(1, len(pristine) // page_size):
        damaged = bytearray(pristine)
        # The whole page: an overflow page's link to the next one too.
        damaged[page * page_size : (page + 1) * page_size] = b"\xa5" * page_size
        bag = tmp_path / f"page{page}.db3"
        bag.write_bytes(damaged)
        try:
            with BagReader(bag) as reader:
                with closing(prefetch(reader.chunks())) as ahead:
                    found = [
                        (topic, time, chunk.records[start : start + length])
                        for chunk in ahead
                        for topic in chunk.message_index
                        for time, start, length in zip(
                            *(a.tolist() for a in chunk.payloads(topic)), strict=True
                        )
                    ]
                problems = list(reader.problems)
        except BagkitError:
            outcomes["open"] += 1
            continue
        assert not [t for t in threading.enumerate() if t.name.startswith("bagkit-")]
        # Garbage in an overflow page's content is no damage SQLite can see: times only.
        assert [(topic, time) for topic, time, _ in found] == [
            (topic, time) for topic, time, _ in rows[: len(found)]
        ]
        stopped = [p for p in problems if "unreadable after" in p]
        outcomes["stopped" if stopped else "whole"] += 1
        if stopped:
            assert stopped == [
                f"page{page}.db3: unreadable after {counted(len(found), 'message')} "
                "(database disk image is malformed)"
            ]
    assert outcomes["open"] > 0 and outcomes["stopped"] > 0, outcomes
