"""The ceiling for ``stats summary`` of an Imu bag: read its bytes, the same moments in numpy.

``python benchmarks/stats_ceiling.py BAG`` reads each MCAP file of BAG (a bag of ``bench_stats``:
one Imu topic, every message the same size), decompresses each chunk, views its message records
as one numpy array (no per-message Python) and accumulates count, min, max, sum and sum of
squares of every numeric field (the 37 doubles and the stamp), then prints mean and std as
``stats summary`` does. No checks a reader of untrusted bags needs: what a tool that knew the
layout in advance would do, and so the floor ``bench_stats_ceiling`` compares bagkit against.
"""

from __future__ import annotations

import mmap
import struct
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import zstandard

MAGIC = b"\x89MCAP0\r\n"
CHUNK, MESSAGE = 0x06, 0x05
# Message record: opcode u8, length u64, channel u16, sequence u32, log time u64, publish u64.
MESSAGE_HEADER = 1 + 8 + 2 + 4 + 8 + 8
# Imu CDR with frame_id "imu_link": 4-byte encapsulation, stamp (i4, u4), frame_id (u4 + 9),
# then 37 doubles from CDR offset 24 (orientation, its covariance, angular velocity, ...).
IMU_SIZE = 4 + 320
DOUBLES_AT, DOUBLES = 4 + 24, 37


def chunks(path: Path) -> Iterator[bytes]:
    """The decompressed records of each chunk of one MCAP file, one at a time."""
    zstd = zstandard.ZstdDecompressor()
    with path.open("rb") as file, mmap.mmap(file.fileno(), 0, access=mmap.ACCESS_READ) as data:
        assert data[: len(MAGIC)] == MAGIC
        offset = len(MAGIC)
        while offset + 9 <= len(data):
            opcode, length = data[offset], struct.unpack_from("<Q", data, offset + 1)[0]
            body = offset + 9
            if opcode == CHUNK:
                size = struct.unpack_from("<Q", data, body + 16)[0]
                name_length = struct.unpack_from("<I", data, body + 28)[0]
                compressed = data[body + 32 : body + 32 + name_length] != b""
                at = body + 32 + name_length
                records = data[at + 8 : at + 8 + struct.unpack_from("<Q", data, at)[0]]
                yield zstd.decompress(records, max_output_size=size) if compressed else records
            offset = body + length


def moments(bag: Path) -> dict[str, tuple[int, float, float, float, float]]:
    """Field -> (count, min, max, mean, std) over every message of ``bag``."""
    count = 0
    total = np.zeros(DOUBLES + 2)
    squares = np.zeros(DOUBLES + 2)
    low = np.full(DOUBLES + 2, np.inf)
    high = np.full(DOUBLES + 2, -np.inf)
    shift: np.ndarray | None = None
    record = MESSAGE_HEADER + IMU_SIZE
    for path in sorted(bag.glob("*.mcap")):
        for records in chunks(path):
            start = 0
            while records[start] != MESSAGE:  # schema and channel records before the messages
                start += 9 + struct.unpack_from("<Q", records, start + 1)[0]
            rows = np.frombuffer(records, np.uint8, offset=start).reshape(-1, record)
            assert (rows[:, 0] == MESSAGE).all(), "not a bag of one fixed-size message type"
            payload = rows[:, MESSAGE_HEADER:]
            doubles = payload[:, DOUBLES_AT : DOUBLES_AT + 8 * DOUBLES].copy().view("<f8")
            stamp = payload[:, 4:12].copy().view("<u4").astype(np.float64)
            values = np.concatenate([stamp, doubles], axis=1)
            if shift is None:  # moments about the first message: no cancellation in std
                shift = values[0].copy()
            np.minimum(low, values.min(axis=0), out=low)
            np.maximum(high, values.max(axis=0), out=high)
            values -= shift
            count += len(values)
            total += values.sum(axis=0)
            squares += np.square(values).sum(axis=0)
    assert shift is not None
    mean = total / count
    # The sample standard deviation, as stats summary reports it.
    std = np.sqrt(np.maximum(squares / count - mean * mean, 0.0) * count / max(count - 1, 1))
    mean += shift
    names = ["header.stamp.sec", "header.stamp.nanosec", *(f"f{i}" for i in range(DOUBLES))]
    return {
        name: (count, float(low[i]), float(high[i]), float(mean[i]), float(std[i]))
        for i, name in enumerate(names)
    }


if __name__ == "__main__":
    for field, (n, lo, hi, mean, std) in moments(Path(sys.argv[1])).items():
        print(f"{field} {n} {lo!r} {hi!r} {mean!r} {std!r}")
