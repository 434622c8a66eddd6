"""MCAP files written by the mcap library with every layout option: chunked or not, with or
without indexes and statistics, any compression."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from bag_samples import IMU, STRING, deserialize, imu_cdr, string_cdr
from bagkit_runs import bagkit_in_process
from mcap.writer import CompressionType, IndexType, Writer

from bagkit.bag import BagReader, message_definition

VARIANTS: dict[str, dict[str, Any]] = {
    "default": {},
    "lz4_small_chunks": {"compression": CompressionType.LZ4, "chunk_size": 2048},
    "uncompressed": {"compression": CompressionType.NONE, "chunk_size": 4096},
    "no_chunks": {"use_chunking": False},
    "no_indexes": {"index_types": IndexType.NONE, "chunk_size": 4096},
    "no_statistics": {"use_statistics": False, "chunk_size": 4096},
    "no_summary_offsets_or_crcs": {"use_summary_offsets": False, "enable_crcs": False},
    # Closed (Footer, closing magic) with no summary section at all: its summary_start is 0.
    "no_summary": {
        "use_statistics": False,
        "index_types": IndexType.NONE,
        "repeat_channels": False,
        "repeat_schemas": False,
        "use_summary_offsets": False,
    },
}


def _write(path: Path, options: dict[str, Any]) -> None:
    with open(path, "wb") as f:
        writer = Writer(f, **options)
        writer.start("ros2", "mcap python")
        imu_schema = writer.register_schema(IMU, "ros2msg", message_definition(IMU).encode())
        string_schema = writer.register_schema(
            STRING, "ros2msg", message_definition(STRING).encode()
        )
        imu = writer.register_channel("/imu", "cdr", imu_schema)
        text = writer.register_channel("/text", "cdr", string_schema)
        for i in range(150):
            # Out of order on purpose: every 7th message arrives 15 ms late.
            t = 1_000_000_000 + i * 10_000_000 + (15_000_000 if i % 7 == 0 else 0)
            writer.add_message(imu, log_time=t, data=imu_cdr(i), publish_time=t, sequence=i)
            if i % 5 == 0:
                writer.add_message(text, log_time=t + 1, data=string_cdr(str(i)), publish_time=t)
        writer.finish()


@pytest.mark.parametrize("variant", sorted(VARIANTS))
def test_reads_every_layout(tmp_path: Path, variant: str) -> None:
    path = tmp_path / "variant.mcap"
    _write(path, VARIANTS[variant])
    with BagReader(path) as bag:
        assert bag.topic_counts == {"/imu": 150, "/text": 30}
        assert bag.topics["/imu"].type == IMU
        messages = list(bag.messages())
        chunk_payloads = sum(len(c.message_index.get("/imu", [])) for c in bag.chunks())
        assert bag.problems == []
        # Statistics, chunk and message indexes, the summary itself are optional: every
        # variant was closed cleanly.
        assert bag.has_summary
    log_times = [m.log_time for m in messages]
    assert log_times == sorted(log_times)
    assert bag.start_ns == log_times[0] and bag.end_ns == log_times[-1]
    imu = sorted((m for m in messages if m.topic == "/imu"), key=lambda m: m.sequence)
    assert [m.data for m in imu] == [imu_cdr(i) for i in range(150)]
    assert [deserialize(m.data, STRING).data for m in messages if m.topic == "/text"] == [
        str(i) for i in range(0, 150, 5)
    ]
    assert chunk_payloads == 150


@pytest.mark.parametrize("variant", ["lz4_small_chunks", "no_indexes", "no_chunks", "default"])
def test_equal_log_times_keep_storage_order(tmp_path: Path, variant: str) -> None:
    path = tmp_path / "ties.mcap"
    written: list[tuple[int, int]] = []
    with open(path, "wb") as f:
        writer = Writer(f, **VARIANTS[variant])
        writer.start("ros2", "mcap python")
        schema = writer.register_schema(IMU, "ros2msg", message_definition(IMU).encode())
        channels = [writer.register_channel(f"/imu{n}", "cdr", schema) for n in range(3)]
        for i in range(300):
            # Three messages per log time, one per channel, in a rotating channel order; a
            # late one (every 11th) sorts before messages written earlier.
            t = 1_000 + (i // 3) * 10 - (25 if i % 11 == 0 else 0)
            channel = channels[(i + i // 3) % 3]
            writer.add_message(channel, log_time=t, data=imu_cdr(i), publish_time=t, sequence=i)
            written.append((t, i))
        writer.finish()
    with BagReader(path) as bag:
        read = [(m.log_time, m.sequence) for m in bag.messages()]
        assert bag.problems == []
    # Python's sort is stable: equal log times stay in the order they were written.
    assert read == sorted(written, key=lambda entry: entry[0])


def test_doctor_of_a_closed_file_without_summary(tmp_path: Path) -> None:
    # Valid MCAP (the summary section is optional): a note, not "not closed cleanly".
    path = tmp_path / "bare.mcap"
    _write(path, VARIANTS["no_summary"])
    doctor = bagkit_in_process(["doctor", path, "--format", "json"])
    assert doctor.returncode == 0, doctor.stdout
    report = json.loads(doctor.stdout)
    assert report["problems"] == []
    assert any("no summary section" in n["note"] for n in report["notes"]), report
