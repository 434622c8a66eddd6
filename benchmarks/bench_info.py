"""Bag layer: write throughput vs the mcap library's Writer, read throughput vs rosbags and mcap,
the cost of checking chunk CRCs on read (with/without, same bag), and ``info`` time vs its
0.2 s ceiling on bags 10x apart in size.

Run: ``.venv/bin/python -m benchmarks info``
"""

from __future__ import annotations

import tempfile
import time
from collections.abc import Callable
from pathlib import Path

from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer
from rosbags.highlevel import AnyReader

from bagkit.bag import BagReader, BagWriter, TopicInfo, bag_info, message_definition
from benchmarks.timing import best_of

IMU = "sensor_msgs/msg/Imu"
SMALL, LARGE = 100_000, 1_000_000
INFO_CEILING_S = 0.2
RECORDER_RATE = 60_000  # msg/s the recorder pushes through write() (issue 3)


def _imu_payloads(n: int) -> list[bytes]:
    """A few distinct serialized Imu messages (CDR layout of the real type, 328 bytes)."""
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    t = store.types
    import numpy as np

    out = []
    for i in range(n):
        msg = t[IMU](
            header=t["std_msgs/msg/Header"](
                stamp=t["builtin_interfaces/msg/Time"](sec=i, nanosec=0), frame_id="imu_link"
            ),
            orientation=t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
            orientation_covariance=np.full(9, 0.01 * i),
            angular_velocity=t["geometry_msgs/msg/Vector3"](x=0.1 * i, y=0.2, z=0.3),
            angular_velocity_covariance=np.zeros(9),
            linear_acceleration=t["geometry_msgs/msg/Vector3"](x=0.01, y=-0.02, z=9.81 + i),
            linear_acceleration_covariance=np.zeros(9),
        )
        out.append(bytes(store.serialize_cdr(msg, IMU)))
    return out


def _write_bagkit(path: Path, n: int, payloads: list[bytes]) -> None:
    with BagWriter(path) as bag:
        bag.add_topic(TopicInfo("/imu/data", IMU))
        write = bag.write
        k = len(payloads)
        for i in range(n):
            t = 1_700_000_000_000_000_000 + i * 100_000
            write("/imu/data", payloads[i % k], log_time=t, publish_time=t, sequence=i)


def _write_mcap(path: Path, n: int, payloads: list[bytes]) -> None:
    with open(path, "wb") as f:
        writer = Writer(f, compression=CompressionType.ZSTD)
        writer.start("ros2", "mcap python")
        schema = writer.register_schema(IMU, "ros2msg", message_definition(IMU).encode())
        channel = writer.register_channel("/imu/data", "cdr", schema)
        k = len(payloads)
        for i in range(n):
            t = 1_700_000_000_000_000_000 + i * 100_000
            writer.add_message(
                channel, log_time=t, data=payloads[i % k], publish_time=t, sequence=i
            )
        writer.finish()


def _interleaved(runs: int, first: Callable[[], object], second: Callable[[], object]) -> float:
    """Best time of ``first`` / best time of ``second``, run alternately (same load for both)."""
    best = [float("inf"), float("inf")]
    for _ in range(runs):
        for k, func in enumerate((first, second)):
            start = time.perf_counter()
            func()
            best[k] = min(best[k], time.perf_counter() - start)
    return best[0] / best[1]


def _crc_cost(small: Path, large: Path) -> None:
    """Chunk CRCs are checked on every read by default: their cost, same bags, same run."""
    from bagkit.stats import summarize

    def read(check_crc: bool) -> Callable[[], None]:
        def run() -> None:
            with BagReader(small, check_crc=check_crc) as reader:
                for _ in reader.messages():
                    pass

        return run

    reading = _interleaved(5, read(True), read(False))
    stats = _interleaved(
        3,
        lambda: summarize([large], check_crc=True),
        lambda: summarize([large], check_crc=False),
    )
    print(
        f"CRC check on read, time with/without: read {SMALL:,} messages {reading:.3f}, "
        f"stats summary of {LARGE:,} {stats:.3f} (report; 1.0 = free)"
    )


def _writers(root: Path, payloads: list[bytes]) -> bool:
    """Same messages through both writers, zstd chunks."""
    t_bagkit = best_of(2, lambda: _write_bagkit(root / f"w{time.monotonic_ns()}", SMALL, payloads))
    t_mcap = best_of(2, lambda: _write_mcap(root / f"m{time.monotonic_ns()}.mcap", SMALL, payloads))
    rate = SMALL / t_bagkit
    print(f"write {SMALL:,} Imu: bagkit {rate:,.0f} msg/s, mcap Writer {SMALL / t_mcap:,.0f} msg/s")
    print(f"  ratio bagkit/mcap Writer: {t_mcap / t_bagkit:.2f}x (target >= 1.0)")
    print(f"  ratio to the recorder's need ({RECORDER_RATE:,} msg/s): {rate / RECORDER_RATE:.1f}x")
    return t_mcap / t_bagkit >= 1.0 and rate >= RECORDER_RATE


def _readers(small: Path) -> bool:
    """Every message (raw bytes, no decoding) of the same bag through the three readers."""

    def read_bagkit() -> None:
        with BagReader(small) as bag:
            for _ in bag.messages():
                pass

    def read_rosbags() -> None:
        with AnyReader([small]) as reader:
            for _ in reader.messages():
                pass

    def read_mcap() -> None:
        with open(small / "small_0.mcap", "rb") as f:
            for _ in make_reader(f).iter_messages():
                pass

    r_bagkit, r_rosbags, r_mcap = (best_of(2, f) for f in (read_bagkit, read_rosbags, read_mcap))
    print(
        f"read {SMALL:,} messages: bagkit {SMALL / r_bagkit:,.0f} msg/s, rosbags "
        f"{SMALL / r_rosbags:,.0f} msg/s, mcap {SMALL / r_mcap:,.0f} msg/s"
    )
    print(f"  ratio bagkit/rosbags: {r_rosbags / r_bagkit:.2f}x (target >= 1.0)")
    print(f"  ratio bagkit/mcap reader: {r_mcap / r_bagkit:.2f}x")
    return r_rosbags / r_bagkit >= 1.0


def _info(small: Path, large: Path) -> bool:
    """``bag_info`` (summary and indexes only) on bags 10x apart, against mcap's summary."""
    size_mb = sum(f.stat().st_size for f in large.glob("*.mcap")) / 1e6
    i_small = best_of(5, lambda: bag_info(small))
    i_large = best_of(5, lambda: bag_info(large))

    def mcap_summary() -> None:
        with open(large / "large_0.mcap", "rb") as f:
            make_reader(f).get_summary()

    i_mcap = best_of(5, mcap_summary)
    print(
        f"info: {SMALL:,} msgs {i_small * 1e3:.1f} ms, {LARGE:,} msgs ({size_mb:.0f} MB) "
        f"{i_large * 1e3:.1f} ms; mcap get_summary on the large bag {i_mcap * 1e3:.1f} ms"
    )
    print(f"  ratio to the {INFO_CEILING_S}s ceiling: {i_large / INFO_CEILING_S:.3f} (target < 1)")
    print(f"  ratio large/small bag (10x the messages): {i_large / i_small:.2f}x")
    return i_large < INFO_CEILING_S


def _crashed_info(root: Path, large: Path) -> None:
    """A crashed recording: no summary, every chunk header is read (salvage scan)."""
    crashed = root / "crashed"
    crashed.mkdir()
    data = (large / "large_0.mcap").read_bytes()
    (crashed / "crashed_0.mcap").write_bytes(data[: len(data) * 9 // 10])
    i_crashed = best_of(1, lambda: bag_info(crashed))
    print(f"info on the large bag cut at 90% (salvage scan): {i_crashed:.2f} s")


def main() -> bool:
    """Print the figures; True when every target is met."""
    payloads = _imu_payloads(64)
    with tempfile.TemporaryDirectory(prefix="bench_info_") as tmp:
        root = Path(tmp)
        ok = _writers(root, payloads)
        small, large = root / "small", root / "large"
        _write_bagkit(small, SMALL, payloads)
        ok &= _readers(small)
        _write_bagkit(large, LARGE, payloads)
        ok &= _info(small, large)
        _crc_cost(small, large)
        _crashed_info(root, large)
    print("targets met" if ok else "targets MISSED")
    return ok
