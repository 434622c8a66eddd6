"""Bag surgery: ``filter`` to a time window and ``recover`` of a 1M-Imu bag against pymcap-cli
(whole processes, :mod:`benchmarks.surgery_peer`); ``filter`` keeping one topic of a
1M-message mixed bag and ``merge`` of two bags against ``rosbags-convert``
(rosbags.convert.converter.convert, the same work: mcap in, mcap out, topic selection), and
``recover`` of a 300 MB truncated bag against the machine's sequential read speed (``cat FILE >
/dev/null``, the file read once before both: warm cache against warm cache, since dropping the
page cache needs root).

Run: ``.venv/bin/python -m benchmarks surgery``
"""

from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np
from rosbags.convert.converter import convert
from rosbags.typesys import Stores, get_typestore

from bagkit.bag import BagWriter, TopicInfo
from bagkit.surgery import Selection, filter_bag, merge_bags, recover_bag
from bagkit.surgery.rewrite import OutputOptions
from benchmarks.surgery_peer import against_pymcap_cli
from benchmarks.timing import best_of

IMU, STRING, TEMPERATURE = (
    "sensor_msgs/msg/Imu",
    "std_msgs/msg/String",
    "sensor_msgs/msg/Temperature",
)
MIXED = 1_000_000
RATIO_TARGET = 3.0
READ_SPEED_TARGET = 0.5
RECOVER_BYTES = 300 << 20


def _payloads(n: int, seed: int = 0) -> dict[str, list[bytes]]:
    """Distinct serialized messages per type (random fields: chunks do not compress away)."""
    store = get_typestore(Stores.ROS2_JAZZY)
    t = store.types
    rng = np.random.default_rng(seed)
    vec = t["geometry_msgs/msg/Vector3"]
    header = t["std_msgs/msg/Header"](
        stamp=t["builtin_interfaces/msg/Time"](sec=1, nanosec=0), frame_id="imu"
    )
    imu = [
        bytes(store.serialize_cdr(t[IMU](
            header=header,
            orientation=t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
            orientation_covariance=rng.random(9),
            angular_velocity=vec(*rng.random(3)),
            angular_velocity_covariance=rng.random(9),
            linear_acceleration=vec(*rng.random(3)),
            linear_acceleration_covariance=rng.random(9),
        ), IMU))
        for _ in range(n)
    ]  # fmt: skip
    text = [bytes(store.serialize_cdr(t[STRING](data=f"status {i}"), STRING)) for i in range(n)]
    temperature = t[TEMPERATURE]
    temp = [
        bytes(
            store.serialize_cdr(
                temperature(header=header, temperature=v, variance=0.0), TEMPERATURE
            )
        )
        for v in rng.random(n).tolist()
    ]
    return {"/imu/data": imu, "/status": text, "/temperature": temp}


def _write(
    path: Path, n: int, *, offset_ns: int = 0, step_ns: int = 1_000_000, imu_only: bool = False
) -> Path:
    """A bag of ``n`` messages: 70% /imu/data, 20% /status, 10% /temperature (or Imu only)."""
    payloads = _payloads(10_000, seed=offset_ns % 1000)
    shares = (
        {"/imu/data": 1.0} if imu_only else {"/imu/data": 0.7, "/status": 0.2, "/temperature": 0.1}
    )
    types = {"/imu/data": IMU, "/status": STRING, "/temperature": TEMPERATURE}
    start = 1_700_000_000_000_000_000 + offset_ns
    with BagWriter(path) as bag:
        for topic in shares:
            bag.add_topic(TopicInfo(topic, types[topic]))
        for base in range(0, n, 10_000):  # blocks of 10 ms... interleaved by topic within a block
            for topic, share in shares.items():
                count = int(10_000 * share)
                times = [
                    start + (base + k * int(1 / share)) * step_ns + len(topic) for k in range(count)
                ]
                data = payloads[topic]
                bag.write_batch(
                    topic, [data[(base + k) % len(data)] for k in range(count)], log_times=times
                )
            bag.flush()
    return path


def _rosbags_convert(srcs: list[Path], dst: Path, include: list[str]) -> None:
    convert(srcs, dst, "mcap", 9, None, "file", None, None, [], include, [], [])


def _fresh(path: Path) -> Path:
    shutil.rmtree(path, ignore_errors=True)
    return path


def _versus(
    label: str, tmp: Path, ours: Callable[[Path], object], theirs: Callable[[Path], object]
) -> bool:
    t_ours = best_of(2, lambda: ours(_fresh(tmp / "ours")))
    t_theirs = best_of(1, lambda: theirs(_fresh(tmp / "theirs")))
    ratio = t_theirs / t_ours
    print(f"  {label}: bagkit {t_ours:.2f} s, rosbags-convert {t_theirs:.2f} s")
    print(f"  ratio rosbags-convert/bagkit: {ratio:.1f}x (target >= {RATIO_TARGET}x)", flush=True)
    return ratio >= RATIO_TARGET


def _filter_and_merge(tmp: Path) -> bool:
    mixed = _write(tmp / "mixed", MIXED)
    met = _versus(
        f"filter /temperature of {MIXED:,} messages",
        tmp,
        lambda out: filter_bag(mixed, out, Selection.create(topics=["/temperature"])),
        lambda out: _rosbags_convert([mixed], out, ["/temperature"]),
    )
    a = _write(tmp / "a", 250_000)
    b = _write(tmp / "b", 250_000, offset_ns=333_333, step_ns=1_100_000)
    met &= _versus(
        "merge of two interleaved 250,000-message bags",
        tmp,
        lambda out: merge_bags([a, b], out),
        lambda out: _rosbags_convert([a, b], out, []),
    )
    return met


def _recover(tmp: Path) -> bool:
    bag = _write(tmp / "large", 1_200_000, imu_only=True)
    whole = next(bag.glob("*.mcap"))
    cut = tmp / "cut.mcap"
    with open(whole, "rb") as src, open(cut, "wb") as dst:
        dst.write(src.read(min(RECOVER_BYTES, whole.stat().st_size - 4096)))
    size = cut.stat().st_size
    subprocess.run(["cat", str(cut)], stdout=subprocess.DEVNULL, check=True)  # warm the cache
    t_cat = best_of(3, lambda: subprocess.run(f"cat {cut} > /dev/null", shell=True, check=True))
    # cp writes the same bytes: the floor of any rewrite (for reference, no target).
    copy = tmp / "copy.mcap"
    t_cp = best_of(2, lambda: subprocess.run(["cp", str(cut), str(copy)], check=True))
    copy.unlink()
    print(f"  cut bag: {size / 1e6:.0f} MB")
    print(f"  cat (warm): {t_cat * 1000:.0f} ms = {size / t_cat / 1e9:.2f} GB/s")
    print(f"  cp: {t_cp * 1000:.0f} ms = {size / t_cp / 1e9:.2f} GB/s")
    met = True
    for check_crc in (True, False):
        options = OutputOptions(check_crc=check_crc)
        t = best_of(2, lambda o=options: recover_bag(cut, _fresh(tmp / "rec"), o))  # type: ignore[misc]
        ratio = t_cat / t
        label = "with CRC check" if check_crc else "--no-crc"
        print(
            f"  recover {label}: {t * 1000:.0f} ms = {size / t / 1e9:.2f} GB/s, "
            f"{ratio:.2f} of cat (target >= {READ_SPEED_TARGET}), {t_cp / t:.2f} of cp"
        )
        met &= ratio >= READ_SPEED_TARGET
    return met


def main() -> bool:
    """Run the surgery benchmarks; return whether every target was met."""
    with tempfile.TemporaryDirectory(
        prefix="bench_surgery_", dir=os.environ.get("BENCH_TMP")
    ) as tmp:
        imu = _write(Path(tmp) / "imu", 1_000_000, imu_only=True)
        met = against_pymcap_cli(imu, Path(tmp))
        shutil.rmtree(imu)
        met &= _filter_and_merge(Path(tmp))
        met &= _recover(Path(tmp))
    return met
