"""``convert`` and ROS 1 bags: ``bagkit convert`` of a 1M-message Imu db3 bag to MCAP against
``rosbags-convert`` on the same bag (rosbags.convert.converter.convert, what its CLI runs), and
``bagkit info`` of a 1 GB ROS 1 bag (from its index) against ``bagkit info`` of the same
messages stored as MCAP, both as a user runs them (``bagkit`` subprocesses, best of 3).

Run: ``.venv/bin/python -m benchmarks convert``
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
from functools import partial
from pathlib import Path

import numpy as np
from rosbags.convert.converter import convert
from rosbags.rosbag1 import Writer as Ros1Writer
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

from bagkit.bag import BagWriter, TopicInfo
from bagkit.surgery.convert import convert_bags
from bagkit.surgery.rewrite import OutputOptions
from benchmarks.timing import best_of, best_of_with_cpu

IMU = "sensor_msgs/msg/Imu"
MESSAGES = 1_000_000
RATIO_TARGET = 3.0
ROS1_BYTES = 1 << 30
INFO_GAP_TARGET_S = 0.2
START = 1_700_000_000_000_000_000
BAGKIT = str(Path(sys.executable).with_name("bagkit"))


def _imus(store_name: Stores, n: int, *, ros1: bool) -> list[bytes]:
    """``n`` distinct serialized Imu messages (random fields: chunks do not compress away)."""
    store = get_typestore(store_name)
    t = store.types
    rng = np.random.default_rng(0)
    vec = t["geometry_msgs/msg/Vector3"]
    found = []
    for i in range(n):
        stamp = t["builtin_interfaces/msg/Time"](1, i)
        header = (
            t["std_msgs/msg/Header"](i, stamp, "imu")
            if ros1
            else t["std_msgs/msg/Header"](stamp, "imu")
        )
        msg = t[IMU](
            header,
            t["geometry_msgs/msg/Quaternion"](0.0, 0.0, 0.0, 1.0),
            rng.random(9),
            vec(*rng.random(3)),
            rng.random(9),
            vec(*rng.random(3)),
            rng.random(9),
        )
        found.append(
            bytes(store.serialize_ros1(msg, IMU) if ros1 else store.serialize_cdr(msg, IMU))
        )
    return found


def _db3(path: Path) -> Path:
    store = get_typestore(Stores.ROS2_JAZZY)
    payloads = _imus(Stores.ROS2_JAZZY, 1000, ros1=False)
    with Writer(path, version=9, storage_plugin=StoragePlugin.SQLITE3) as writer:
        connection = writer.add_connection("/imu/data", IMU, typestore=store)
        for i in range(MESSAGES):
            writer.write(connection, START + i * 10_000_000, payloads[i % 1000])
    return path


def _fresh(path: Path) -> Path:
    shutil.rmtree(path, ignore_errors=True)
    return path


def _convert(tmp: Path) -> bool:
    db3 = _db3(tmp / "imu_db3")
    met = True
    for compression in ("none", "zstd"):
        options = OutputOptions(compression=compression)
        t_ours, cpu_ours = best_of_with_cpu(
            2,
            lambda o=options: convert_bags([db3], _fresh(tmp / "ours"), None, o),  # type: ignore[misc]
        )
        t_theirs, cpu_theirs = best_of_with_cpu(
            1,
            lambda: convert(
                [db3], _fresh(tmp / "theirs"), "mcap", 9, None, "file", None, None, [], [], [], []
            ),
        )
        ratio = t_theirs / t_ours
        print(
            f"  convert {MESSAGES:,} Imu db3 -> MCAP ({compression}): bagkit {t_ours:.2f} s "
            f"(CPU {cpu_ours:.2f} s), rosbags-convert {t_theirs:.2f} s (CPU {cpu_theirs:.2f} s, "
            f"uncompressed), ratio {ratio:.1f}x (target >= {RATIO_TARGET}x), by CPU "
            f"{cpu_theirs / cpu_ours:.1f}x",
            flush=True,
        )
        met &= ratio >= RATIO_TARGET
    return met


def _info(tmp: Path) -> bool:
    ros1_store = get_typestore(Stores.ROS1_NOETIC)
    ros1 = _imus(Stores.ROS1_NOETIC, 1000, ros1=True)
    cdr = _imus(Stores.ROS2_JAZZY, 1000, ros1=False)
    count = ROS1_BYTES // (len(ros1[0]) + 60)
    bag = tmp / "large.bag"
    with Ros1Writer(bag) as writer:
        connection = writer.add_connection("/imu/data", IMU, typestore=ros1_store)
        for i in range(count):
            writer.write(connection, START + i * 1_000_000, ros1[i % 1000])
    mcap = tmp / "large_mcap"
    with BagWriter(mcap) as out:
        out.add_topic(TopicInfo("/imu/data", IMU))
        for base in range(0, count, 100_000):
            n = min(100_000, count - base)
            times = [START + (base + k) * 1_000_000 for k in range(n)]
            out.write_batch(
                "/imu/data", [cdr[(base + k) % 1000] for k in range(n)], log_times=times
            )
    info_s: dict[str, float] = {}
    for label, path in (("ROS 1", bag), ("MCAP", mcap)):
        command = [BAGKIT, "info", str(path)]
        subprocess.run(command, check=True, capture_output=True)  # warm the page cache
        info_s[label] = best_of(
            3, partial(subprocess.run, command, check=True, capture_output=True)
        )
    gap = info_s["ROS 1"] - info_s["MCAP"]
    print(
        f"  info of a {bag.stat().st_size / 1e9:.2f} GB ROS 1 bag ({count:,} messages): "
        f"{info_s['ROS 1'] * 1000:.0f} ms; of the same as MCAP: {info_s['MCAP'] * 1000:.0f} ms; "
        f"gap {gap * 1000:.0f} ms (target <= {INFO_GAP_TARGET_S * 1000:.0f} ms)",
        flush=True,
    )
    return gap <= INFO_GAP_TARGET_S


def main() -> bool:
    """Run the convert benchmarks; return whether every target was met."""
    with tempfile.TemporaryDirectory(
        prefix="bench_convert_", dir=os.environ.get("BENCH_TMP")
    ) as tmp:
        met = _info(Path(tmp))
        met &= _convert(Path(tmp))
    return met
