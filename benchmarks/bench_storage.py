"""Bags in an S3-compatible store on loopback (moto's server), read by range requests.

1. ``info`` of BAGKIT_BENCH_STORAGE_BAGS bags (default 1,000: the nominal fixture's golden,
   as bag prefixes with metadata.yaml): bytes fetched per bag against its summary section
   (target <= 2x), and the time against downloading each bag and reading it locally (target
   >= 20x faster).
2. ``stats summary -t /gps/fix`` over 20 bags of Imu (100 Hz) + NavSatFix (1 Hz): bytes
   fetched against the chunks that hold /gps/fix (target <= 1.2x), values equal to the local
   read.

Both in this process (the byte counter is per process), the same store, the same run.
Run: ``.venv/bin/python -m benchmarks storage``
"""

from __future__ import annotations

import os
import shutil
import socket
import struct
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
GOLDEN = REPO / "fixtures" / "nominal" / "golden"
BAGS = int(os.environ.get("BAGKIT_BENCH_STORAGE_BAGS", "1000"))
STATS_BAGS = 20
STATS_IMU_MESSAGES = int(os.environ.get("BAGKIT_BENCH_STORAGE_IMU", "50000"))


def _moto() -> tuple[subprocess.Popen[bytes], str]:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    server = subprocess.Popen(
        [str(Path(sys.executable).with_name("moto_server")), "-H", "127.0.0.1", "-p", str(port)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    for _ in range(300):
        try:
            socket.create_connection(("127.0.0.1", port), timeout=0.2).close()
            break
        except OSError:
            time.sleep(0.1)
    return server, f"http://127.0.0.1:{port}"


def summary_bytes(file: Path) -> int:
    """The summary section's size, from the MCAP footer."""
    with open(file, "rb") as f:
        f.seek(-8 - 29, 2)
        footer = f.read(29)
    (summary_start,) = struct.unpack_from("<Q", footer, 9)
    return file.stat().st_size - summary_start


def _info_part(fs: Any, scratch: Path) -> None:
    from bagkit.bag import bag_info
    from bagkit.fleet.listing import folder_info
    from bagkit.storage.range_file import fetched

    put = fs.put
    started = time.perf_counter()
    local = scratch / "fleet"
    for i in range(BAGS):
        shutil.copytree(GOLDEN, local / f"bag_{i:04d}", copy_function=os.link)
    put(str(local), "bench/", recursive=True)
    print(f"  {BAGS} bags uploaded in {time.perf_counter() - started:.1f} s")
    summary = summary_bytes(GOLDEN / "golden_0.mcap")
    size = sum(f.stat().st_size for f in GOLDEN.iterdir())

    before, requests = fetched()
    started = time.perf_counter()
    remote = folder_info("s3://bench/fleet")
    remote_s = time.perf_counter() - started
    spent, asked = fetched()[0] - before, fetched()[1] - requests
    assert remote is not None and len(remote.bags) == BAGS and not remote.unread

    get = fs.get
    started = time.perf_counter()
    for i in range(BAGS):
        target = scratch / "download" / f"bag_{i:04d}"
        get(f"bench/fleet/bag_{i:04d}/", str(target), recursive=True)
        bag_info(target)
        shutil.rmtree(target)
    download_s = time.perf_counter() - started
    per_bag = spent / BAGS
    print(
        f"  info of {BAGS} bags: {remote_s:.2f} s by range ({asked / BAGS:.1f} requests, "
        f"{per_bag:,.0f} bytes per bag; summary {summary:,} B, bag {size:,} B): "
        f"{per_bag / summary:.2f}x the summary (target <= 2)"
    )
    print(
        f"  download + local info: {download_s:.2f} s: range reads {download_s / remote_s:.1f}x "
        "faster (target >= 20)"
    )


def _stats_part(fs: Any, scratch: Path) -> None:
    import numpy as np
    from rosbags.typesys import Stores, get_typestore

    from bagkit.bag import BagWriter, TopicInfo
    from bagkit.bag.mcap_file import McapFile
    from bagkit.fleet.inputs import bag_paths
    from bagkit.stats.summary import summarize
    from bagkit.storage.range_file import fetched

    store = get_typestore(Stores.ROS2_JAZZY)
    types = store.types
    rng = np.random.default_rng(3)
    h = types["std_msgs/msg/Header"]
    stamp = types["builtin_interfaces/msg/Time"]
    vec = types["geometry_msgs/msg/Vector3"]
    imu_type, fix_type = "sensor_msgs/msg/Imu", "sensor_msgs/msg/NavSatFix"
    root = scratch / "imu_gps"
    template = root / "bag_00"
    t0 = 1_700_000_000_000_000_000
    with BagWriter(template) as bag:
        bag.add_topic(TopicInfo("/imu/data", imu_type))
        bag.add_topic(TopicInfo("/gps/fix", fix_type))
        for i in range(STATS_IMU_MESSAGES):
            t = t0 + i * 10_000_000
            header = h(stamp=stamp(sec=t // 10**9, nanosec=t % 10**9), frame_id="imu")
            imu = types[imu_type](
                header=header,
                orientation=types["geometry_msgs/msg/Quaternion"](0.0, 0.0, 0.0, 1.0),
                orientation_covariance=np.zeros(9),
                angular_velocity=vec(*rng.normal(0, 0.01, 3)),
                angular_velocity_covariance=np.zeros(9),
                linear_acceleration=vec(*rng.normal([0, 0, 9.81], 0.05)),
                linear_acceleration_covariance=np.zeros(9),
            )
            bag.write("/imu/data", bytes(store.serialize_cdr(imu, imu_type)), log_time=t)
            if i % 100 == 0:
                fix = types[fix_type](
                    header=header,
                    status=types["sensor_msgs/msg/NavSatStatus"](status=0, service=1),
                    latitude=48.0 + rng.normal(0, 1e-5),
                    longitude=11.0,
                    altitude=500.0 + rng.normal(),
                    position_covariance=np.zeros(9),
                    position_covariance_type=0,
                )
                bag.write("/gps/fix", bytes(store.serialize_cdr(fix, fix_type)), log_time=t)
    for i in range(1, STATS_BAGS):
        shutil.copytree(template, root / f"bag_{i:02d}", copy_function=os.link)
    fs.put(str(root), "bench/", recursive=True)
    file = next(template.glob("*.mcap"))
    mcap = McapFile(file)
    mcap.open()
    channel = {c.id for c in mcap.index.channels.values() if c.topic == "/gps/fix"}
    holding = [c for c in mcap.index.chunk_indexes if channel & set(c.message_index_offsets)]
    chunk_bytes = sum(c.chunk_length + c.message_index_length for c in holding)
    chunks = len(mcap.index.chunk_indexes)
    mcap.close()

    before = fetched()[0]
    started = time.perf_counter()
    remote = summarize(bag_paths(["s3://bench/imu_gps"]), topics=["/gps/fix"])
    remote_s = time.perf_counter() - started
    per_bag = (fetched()[0] - before) / STATS_BAGS
    local = summarize(bag_paths([str(root)]), topics=["/gps/fix"])
    same = remote.to_dict()["topics"] == local.to_dict()["topics"]
    print(
        f"  stats summary -t /gps/fix of {STATS_BAGS} bags ({STATS_IMU_MESSAGES:,} Imu each, "
        f"{file.stat().st_size:,} B; /gps/fix in {len(holding)} of {chunks} chunks, "
        f"{chunk_bytes:,} B): {per_bag:,.0f} bytes fetched per bag, "
        f"{per_bag / chunk_bytes:.2f}x the chunks (target <= 1.2), {remote_s:.2f} s; "
        f"values equal to the local read: {same}"
    )


def main() -> None:
    print(f"storage (moto's S3 server on loopback; load {os.getloadavg()[0]:.1f}):")
    server, endpoint = _moto()
    os.environ.update(
        AWS_ENDPOINT_URL=endpoint,
        AWS_ACCESS_KEY_ID="bench",
        AWS_SECRET_ACCESS_KEY="bench",
        AWS_DEFAULT_REGION="us-east-1",
    )
    scratch = Path(tempfile.mkdtemp(prefix="bagkit-bench-storage-"))
    try:
        import s3fs

        fs = s3fs.S3FileSystem()
        fs.mkdir("bench")
        _info_part(fs, scratch)
        _stats_part(fs, scratch)
    finally:
        server.terminate()
        server.wait()
        shutil.rmtree(scratch, ignore_errors=True)


if __name__ == "__main__":
    main()
