"""rosbag2's zstd compression, file and message modes, written by rosbags' rosbag2 writer and
read back against rosbags' reader; with and without metadata.yaml; hostile compressed files."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import zstandard
from bagkit_runs import bagkit_in_process, bagkit_subprocess
from rosbags.rosbag2 import Reader, Writer
from rosbags.rosbag2.enums import CompressionFormat, CompressionMode, StoragePlugin
from rosbags.typesys import Stores, get_typestore

from bagkit.bag import BagReader, CorruptBagError
from bagkit.bag.compression import decompressed_copy

BAGKIT = str(Path(sys.executable).with_name("bagkit"))
STORE = get_typestore(Stores.ROS2_JAZZY)
T0 = 1_700_000_000_000_000_000
MODES = {"file": CompressionMode.FILE, "message": CompressionMode.MESSAGE}
STORAGES = {"sqlite3": StoragePlugin.SQLITE3, "mcap": StoragePlugin.MCAP}


def _imu(i: int) -> bytes:
    t = STORE.types
    rng = np.random.default_rng(i)
    msg = t["sensor_msgs/msg/Imu"](
        header=t["std_msgs/msg/Header"](
            stamp=t["builtin_interfaces/msg/Time"](sec=i, nanosec=7), frame_id="imu"
        ),
        orientation=t["geometry_msgs/msg/Quaternion"](*rng.normal(size=4)),
        orientation_covariance=rng.normal(size=9),
        angular_velocity=t["geometry_msgs/msg/Vector3"](*rng.normal(size=3)),
        angular_velocity_covariance=rng.normal(size=9),
        linear_acceleration=t["geometry_msgs/msg/Vector3"](*rng.normal(size=3)),
        linear_acceleration_covariance=rng.normal(size=9),
    )
    return bytes(STORE.serialize_cdr(msg, "sensor_msgs/msg/Imu"))


def write_compressed(path: Path, storage: str, mode: str, n: int = 120) -> Path:
    """A rosbags-written bag of ``n`` Imu and ``n // 10`` String messages, zstd in ``mode``."""
    writer = Writer(path, version=9, storage_plugin=STORAGES[storage])
    writer.set_compression(MODES[mode], CompressionFormat.ZSTD)
    with writer:
        imu = writer.add_connection("/imu", "sensor_msgs/msg/Imu", typestore=STORE)
        text = writer.add_connection("/text", "std_msgs/msg/String", typestore=STORE)
        string = STORE.types["std_msgs/msg/String"]
        for i in range(n):
            writer.write(imu, T0 + i * 10_000_000, _imu(i))
            if i % 10 == 0:
                data = STORE.serialize_cdr(string(data=f"message {i}"), "std_msgs/msg/String")
                writer.write(text, T0 + i * 10_000_000 + 1, bytes(data))
    return path


def _rosbags_messages(path: Path) -> list[tuple[str, int, bytes]]:
    with Reader(path) as reader:
        return [(c.topic, t, bytes(d)) for c, t, d in reader.messages()]


@pytest.mark.parametrize("storage", STORAGES)
@pytest.mark.parametrize("mode", MODES)
@pytest.mark.parametrize("with_metadata", [True, False])
def test_compressed_bags_read_as_rosbags_reads_them(
    tmp_path: Path, storage: str, mode: str, with_metadata: bool
) -> None:
    bag_dir = write_compressed(tmp_path / "bag", storage, mode)
    expected = _rosbags_messages(bag_dir)
    (stored,) = [p for p in bag_dir.iterdir() if p.name != "metadata.yaml"]
    assert stored.name.endswith(".zstd") == (mode == "file")
    if not with_metadata:
        (bag_dir / "metadata.yaml").unlink()
    with BagReader(bag_dir) as bag:
        assert bag.topic_counts == {"/imu": 120, "/text": 12}
        got = [(m.topic, m.log_time, m.data) for m in bag.messages()]
        last = bag.last_messages(["/imu"], T0 + 10**12)
        chunks = list(bag.chunks(["/imu"]))
        assert bag.problems == []
        assert "zstd" in bag.compression
        if mode == "file":  # the file's bytes, as stored and decompressed
            assert bag.compressed_size == stored.stat().st_size < bag.uncompressed_size
        opened = [getattr(s, "inner", s).path for s in bag._storage]
    assert got == expected
    assert last["/imu"].data == [d for t, _, d in expected if t == "/imu"][-1]
    in_chunks = [
        c.records[s : s + n] for c in chunks for s, n in zip(*c.payloads("/imu")[1:], strict=True)
    ]
    assert in_chunks == [d for t, _, d in expected if t == "/imu"]
    # The decompressed copy of a compressed file is removed on close.
    assert all(p.exists() == (p == stored) for p in opened)


@pytest.mark.parametrize("mode", MODES)
def test_stats_of_a_compressed_sqlite3_bag_equals_its_plain_twin(tmp_path: Path, mode: str) -> None:
    compressed = write_compressed(tmp_path / "zstd", "sqlite3", mode)
    plain = tmp_path / "plain"
    writer = Writer(plain, version=9)
    with writer, Reader(compressed) as reader:
        ids = {
            c.id: writer.add_connection(c.topic, c.msgtype, typestore=STORE)
            for c in reader.connections
        }
        for connection, timestamp, data in reader.messages():
            writer.write(ids[connection.id], timestamp, data)
    outputs = []
    for bag in (compressed, plain):
        proc = subprocess.run(
            [BAGKIT, "stats", "summary", str(bag), "--format", "json"],
            capture_output=True,
            text=True,
            timeout=60,
            check=False,
        )
        assert proc.returncode == 0 and proc.stderr == "", proc.stderr
        outputs.append(proc.stdout.replace(str(bag), "BAG"))
    assert outputs[0] == outputs[1]


def _run(*args: str | Path) -> subprocess.CompletedProcess[str]:
    """``bagkit ARGS`` in this process (tests/bagkit_runs.py)."""
    return bagkit_in_process(list(args))


def _one_error_line(proc: subprocess.CompletedProcess[str], *words: str) -> None:
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:"), proc.stderr
    assert all(w in lines[0] for w in words), lines[0]


def test_a_zstd_file_that_does_not_decompress(tmp_path: Path) -> None:
    bag_dir = write_compressed(tmp_path / "bag", "sqlite3", "file")
    (stored,) = bag_dir.glob("*.zstd")
    data = stored.read_bytes()
    stored.write_bytes(data[: len(data) // 2])  # truncated stream
    # A real process: the one error line and exit status are what a shell gets.
    _one_error_line(bagkit_subprocess(["info", bag_dir], Path.cwd()), "zstd")
    stored.write_bytes(data[:8] + bytes(len(data) - 8))  # a valid header, then zeros
    _one_error_line(_run("info", bag_dir), stored.name)
    stored.write_bytes(b"garbage" + data)  # no zstd frame at its start: not "not a bag file"
    _one_error_line(_run("info", bag_dir), stored.name, "not a zstd stream")


def test_a_zstd_bomb_is_bounded(tmp_path: Path) -> None:
    bag_dir = write_compressed(tmp_path / "bag", "sqlite3", "file")
    (stored,) = bag_dir.glob("*.zstd")
    # 64 MiB of zeros in a few kB, without a declared size: stopped at the bound while
    # streaming; with its size declared (1 TiB, more than any disk here): refused at once.
    stored.write_bytes(zstandard.ZstdCompressor(write_content_size=False).compress(bytes(64 << 20)))
    with pytest.raises(CorruptBagError, match="more than the 1048576 bytes"):
        decompressed_copy(stored, limit=1 << 20)
    header = bytearray(zstandard.ZstdCompressor().compress(bytes(1 << 20))[:4])
    header += bytes([0xC0, 0x00]) + (1 << 40).to_bytes(8, "little")  # 8-byte FCS, window
    stored.write_bytes(bytes(header) + bytes(64))
    _one_error_line(_run("info", bag_dir), "decompresses to 1099511627776 bytes")


def test_message_payloads_that_do_not_decompress_are_counted(tmp_path: Path) -> None:
    import sqlite3

    bag_dir = write_compressed(tmp_path / "bag", "sqlite3", "message")
    (db3,) = bag_dir.glob("*.db3")
    db = sqlite3.connect(db3)
    db.execute("UPDATE messages SET data = ? WHERE rowid IN (3, 5)", (b"\x28\xb5\x2f\xfd junk",))
    db.commit()
    db.close()
    proc = _run("stats", "summary", bag_dir, "--format", "json")
    assert proc.returncode == 0, proc.stderr
    assert "did not decompress" in proc.stderr and "Traceback" not in proc.stderr
    with BagReader(bag_dir) as bag:
        assert len(list(bag.messages())) == 132 - 2
        assert any("2 messages of" in p for p in bag.problems)


def test_a_truncated_db3(tmp_path: Path) -> None:
    bag_dir = write_compressed(tmp_path / "bag", "sqlite3", "message", n=2000)
    (db3,) = bag_dir.glob("*.db3")
    db3.write_bytes(db3.read_bytes()[: db3.stat().st_size // 2])
    proc = _run("stats", "summary", bag_dir)
    assert "Traceback" not in proc.stderr
    assert proc.returncode in (0, 2)
    assert proc.stderr.strip().splitlines()[0].startswith(("error:", "warning:"))


def _garbage_bag(path: Path, good: bool) -> Path:
    string = STORE.types["std_msgs/msg/String"]
    with Writer(path, version=9) as writer:
        text = writer.add_connection("/text", "std_msgs/msg/String", typestore=STORE)
        for i in range(5):  # a string length past the payload's end
            writer.write(text, T0 + i, b"\x00\x01\x00\x00\xff\xff\x00\x00")
        if good:
            data = STORE.serialize_cdr(string(data="ok"), "std_msgs/msg/String")
            writer.write(text, T0 + 9, bytes(data))
    return path


def test_echo_fails_when_no_message_of_the_topic_decodes(tmp_path: Path) -> None:
    proc = _run("echo", _garbage_bag(tmp_path / "some", good=True), "/text", "--format", "json")
    assert proc.returncode == 0 and proc.stdout.count("\n") == 1
    assert proc.stderr.count("\n") == 1 and "5 messages of /text did not decode" in proc.stderr
    proc = _run("echo", _garbage_bag(tmp_path / "none", good=False), "/text")
    _one_error_line(proc, "none of the 5 messages of /text decode")
    assert proc.stdout == ""


def test_db3_chunks_of_large_messages_stay_bounded(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from bagkit.bag import sqlite3_windows

    monkeypatch.setattr(sqlite3_windows, "WINDOW_BYTES", 40_000)
    monkeypatch.setattr(sqlite3_windows, "MAX_WINDOW_BYTES", 100_000)
    path = tmp_path / "large"
    payloads = [b"\x00\x01\x00\x00" + bytes([i]) * 20_000 for i in range(30)]
    with Writer(path, version=9) as writer:
        blob = writer.add_connection("/blob", "std_msgs/msg/String", typestore=STORE)
        for i, payload in enumerate(payloads):
            writer.write(blob, T0 + i, payload)
    with BagReader(path) as bag:
        chunks = list(bag.chunks())
    assert len(chunks) >= 5
    assert all(len(c.records) <= 100_000 + 2 * 20_100 for c in chunks)
    got = [
        c.records[s : s + n] for c in chunks for s, n in zip(*c.payloads("/blob")[1:], strict=True)
    ]
    assert got == payloads


@pytest.mark.parametrize("storage", STORAGES)
@pytest.mark.parametrize("mode", MODES)
def test_rosbag2s_upper_case_compression_mode(tmp_path: Path, storage: str, mode: str) -> None:
    # rosbag2 writes compression_mode FILE or MESSAGE (compression_mode_to_string) and reads it
    # in any case; rosbags writes it in lower case.
    bag_dir = write_compressed(tmp_path / "bag", storage, mode)
    metadata = bag_dir / "metadata.yaml"
    written = metadata.read_text()
    assert f"compression_mode: {mode}\n" in written
    metadata.write_text(
        written.replace(f"compression_mode: {mode}", f"compression_mode: {mode.upper()}")
    )
    expected = _rosbags_messages(bag_dir)
    with BagReader(bag_dir) as bag:
        got = [(m.topic, m.log_time, m.data) for m in bag.messages()]
        assert bag.problems == []
    assert got == expected
    echo = bagkit_in_process(["echo", str(bag_dir), "/text", "-n", "1", "--format", "json"])
    assert echo.returncode == 0, echo.stderr
    assert json.loads(echo.stdout)["data"] == {"data": "message 0"}


def _chunk_compressions(stored: Path) -> str:
    """The MCAP chunk compressions of a storage file, by the mcap library ("" for sqlite3)."""
    from mcap.reader import make_reader

    data = stored.read_bytes()
    if stored.name.endswith(".zstd"):
        data = zstandard.ZstdDecompressor().stream_reader(data).read()
    if not stored.name.removesuffix(".zstd").endswith(".mcap"):
        return ""
    import io

    summary = make_reader(io.BytesIO(data)).get_summary()
    assert summary is not None
    return ",".join(sorted({c.compression or "none" for c in summary.chunk_indexes}))


@pytest.mark.parametrize("storage", STORAGES)
@pytest.mark.parametrize("mode", MODES)
def test_info_says_the_file_compression_and_the_chunk_compression_apart(
    tmp_path: Path, storage: str, mode: str
) -> None:
    """`info` of `ros2 bag record --compression-mode file` printed "Compression: none,zstd"."""
    bag_dir = write_compressed(tmp_path / "bag", storage, mode)
    (stored,) = [p for p in bag_dir.iterdir() if p.name != "metadata.yaml"]
    chunks = _chunk_compressions(stored)
    document = json.loads(bagkit_in_process(["info", bag_dir, "--format", "json"]).stdout)
    assert (document["compression_format"], document["compression_mode"]) == ("zstd", mode)
    assert document["chunk_compression"] == chunks
    done = bagkit_in_process(["info", bag_dir])
    assert done.returncode == 0, done.stderr
    fields = dict(line.split(":", 1) for line in done.stdout.splitlines() if "ompression" in line)
    assert fields.pop("Compression").strip().startswith(f"zstd, {mode} mode")
    if chunks:
        assert fields.pop("Chunk compression").strip().startswith(chunks)
    assert not fields, fields
    # The catalogue's one column says both, as info's two lines do (it said "none,zstd").
    from bagkit.fleet.describe import describe_bag

    (row,) = {r["compression"] for r in describe_bag(str(bag_dir))}
    assert row == f"zstd, {mode} mode" + (f"; chunks {chunks}" if chunks else "")
