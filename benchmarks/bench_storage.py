"""Bags in an S3-compatible store on loopback (moto's server), read by range requests.

1. ``info`` of BAGKIT_BENCH_STORAGE_BAGS bags (default 1,000: the nominal fixture's golden,
   as bag prefixes with metadata.yaml) in moto, then of BAGKIT_BENCH_STORAGE_LARGE_BAGS bags
   of BAGKIT_BENCH_STORAGE_LARGE_MB MB (default 9 of 256: camera images and an Imu; the first
   opens the client, 8 are timed) on the tests' range-capable HTTP server (moto answers a
   range by reading the whole object): bytes fetched per bag against its summary section
   (target <= 2x), and the time against fetching the bags concurrently (s3fs's or fsspec's
   ``get``) and reading them locally (target >= 20x faster). On loopback a request costs
   what the server takes to answer it whatever its size: the golden's 184 KB download is as
   many requests as its info; the large bags show what bytes cost.
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
import threading
import time
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
GOLDEN = REPO / "fixtures" / "nominal" / "golden"
BAGS = int(os.environ.get("BAGKIT_BENCH_STORAGE_BAGS", "1000"))
LARGE_BAGS = int(os.environ.get("BAGKIT_BENCH_STORAGE_LARGE_BAGS", "9"))
LARGE_MB = int(os.environ.get("BAGKIT_BENCH_STORAGE_LARGE_MB", "256"))
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


def _info_against_download(fs: Any, local: Path, key: str, scratch: Path, what: str) -> None:
    """``info`` of the bags under ``local``, uploaded to ``bench/key``: by range, against
    downloading the prefix (s3fs's concurrent ``get``) and reading it locally."""
    from bagkit.bag.info import bag_info
    from bagkit.fleet.listing import folder_info
    from bagkit.storage.filesystems import filesystem
    from bagkit.storage.range_file import fetched

    bags = sorted(p for p in local.iterdir() if p.is_dir())
    started = time.perf_counter()
    fs.put(str(local), f"bench/{key}", recursive=True)
    print(f"  {what}: {len(bags)} bags uploaded in {time.perf_counter() - started:.1f} s")
    file = next(bags[0].glob("*.mcap"))
    summary = summary_bytes(file)
    size = sum(f.stat().st_size for f in bags[0].iterdir())
    # Both sides warm: the modules imported (a local info), bagkit's S3 client made as the
    # download's is (one HEAD).
    exact = bag_info(bags[0])
    filesystem(f"s3://bench/{key}")[0].info(f"bench/{key}")

    before, requests = fetched()
    started = time.perf_counter()
    remote = folder_info(f"s3://bench/{key}")
    remote_s = time.perf_counter() - started
    spent, asked = fetched()[0] - before, fetched()[1] - requests
    assert remote is not None and len(remote.bags) == len(bags) and not remote.unread
    bounded = {t.topic: t.rate_hz for t in remote.bags[0].topics}
    worst = max(
        (abs(bounded[t.topic] - t.rate_hz) / t.rate_hz for t in exact.topics if t.rate_hz),
        default=0.0,
    )

    target = scratch / "download" / key
    started = time.perf_counter()
    fs.get(f"bench/{key}", str(target), recursive=True)
    downloaded = folder_info(target)
    download_s = time.perf_counter() - started
    assert downloaded is not None and len(downloaded.bags) == len(bags)
    shutil.rmtree(target)
    per_bag = spent / len(bags)
    print(
        f"  info by range: {remote_s:.2f} s ({asked / len(bags):.1f} requests, {per_bag:,.0f} "
        f"bytes per bag; summary {summary:,} B, bag {size:,} B): {per_bag / summary:.2f}x "
        f"the summary (target <= 2); rates from chunk bounds, worst {worst:.1%} below exact"
    )
    print(
        f"  download + local info: {download_s:.2f} s: range reads {download_s / remote_s:.1f}x "
        "faster (target >= 20)"
    )


def _info_part(fs: Any, scratch: Path) -> None:
    local = scratch / "fleet"
    for i in range(BAGS):
        shutil.copytree(GOLDEN, local / f"bag_{i:04d}", copy_function=os.link)
    _info_against_download(fs, local, "fleet", scratch, "the nominal golden")
    _large_part(scratch)


def _large_part(scratch: Path) -> None:
    """``info`` of LARGE_BAGS bags of LARGE_MB MB on the tests' range-capable HTTP server
    (moto answers a range by reading the whole object: a 64 MB read per request), against
    fetching each bag (fsspec's concurrent ``get``) and reading it locally."""
    from concurrent.futures import ThreadPoolExecutor

    import fsspec

    from bagkit.bag.info import bag_info
    from bagkit.fleet.execute import REMOTE_READERS
    from bagkit.fleet.listing import folder_info
    from bagkit.storage.range_file import fetched

    template = scratch / "large" / "bag_00"
    _write_images(template)
    files = sorted(p.name for p in template.iterdir())
    # The server in a process of its own (in this one, it would share the GIL with the reads).
    server = subprocess.Popen(
        [sys.executable, "-m", "benchmarks.bench_storage", "serve", str(template), str(LARGE_BAGS)],
        stdout=subprocess.PIPE,
        cwd=REPO,
    )
    try:
        assert server.stdout is not None
        base = server.stdout.readline().decode().strip()
        urls = [f"{base}/large/bag_{i:02d}" for i in range(LARGE_BAGS)]
        mcap = template / next(n for n in files if n.endswith(".mcap"))
        summary = summary_bytes(mcap)
        size = sum((template / n).stat().st_size for n in files)
        exact = bag_info(template)  # modules imported for both sides
        bag_info(urls[0])  # the HTTP client made, as the download's is below
        before, requests = fetched()
        started = time.perf_counter()
        with ThreadPoolExecutor(REMOTE_READERS) as pool:
            remote = list(pool.map(bag_info, urls[1:]))
        remote_s = time.perf_counter() - started
        spent, asked = fetched()[0] - before, fetched()[1] - requests
        fs = fsspec.filesystem("http")
        target = scratch / "download" / "large"
        started = time.perf_counter()
        sources = [f"{u}/{n}" for u in urls[1:] for n in files]
        fs.get(sources, [str(target / s.split("/large/", 1)[1]) for s in sources])
        downloaded = folder_info(target)
        download_s = time.perf_counter() - started
        assert downloaded is not None and len(downloaded.bags) == len(remote)
    finally:
        server.terminate()
        server.wait()
    count = len(remote)
    bounded = {t.topic: t.rate_hz for t in remote[0].topics}
    worst = max(abs(bounded[t.topic] - t.rate_hz) / t.rate_hz for t in exact.topics if t.rate_hz)
    print(
        f"  {count} bags of {size / 1e6:.0f} MB (camera + Imu) on an HTTP range server: info "
        f"{remote_s:.2f} s ({asked / count:.1f} requests, {spent / count:,.0f} bytes per bag, "
        f"{spent / count / summary:.2f}x the summary of {summary:,} B; rates worst "
        f"{worst:.1%} below exact); fetch + local info {download_s:.2f} s: range reads "
        f"{download_s / remote_s:.1f}x faster (target >= 20)"
    )


def _write_images(path: Path) -> None:
    """A bag of about LARGE_MB MB: 640x480 RGB images at 10 Hz (random pixels: incompressible)
    and a 100 Hz Imu, in chunks of 4 MiB."""
    import numpy as np
    from rosbags.typesys import Stores, get_typestore

    from bagkit.bag import BagWriter, TopicInfo

    store = get_typestore(Stores.ROS2_JAZZY)
    types = store.types
    rng = np.random.default_rng(5)
    t0 = 1_700_000_000_000_000_000
    image_type, imu_type = "sensor_msgs/msg/Image", "sensor_msgs/msg/Imu"
    stamp = types["builtin_interfaces/msg/Time"]
    vec = types["geometry_msgs/msg/Vector3"]
    frames = LARGE_MB * (1 << 20) // (640 * 480 * 3)
    with BagWriter(path, chunk_size=4 << 20) as bag:
        bag.add_topic(TopicInfo("/camera/image", image_type))
        bag.add_topic(TopicInfo("/imu/data", imu_type))
        for i in range(frames * 10):
            t = t0 + i * 10_000_000
            header = types["std_msgs/msg/Header"](
                stamp=stamp(sec=t // 10**9, nanosec=t % 10**9), frame_id="cam"
            )
            if i % 10 == 0:
                image = types[image_type](
                    header=header,
                    height=480,
                    width=640,
                    encoding="rgb8",
                    is_bigendian=0,
                    step=640 * 3,
                    data=rng.integers(0, 256, 640 * 480 * 3, dtype=np.uint8),
                )
                data = bytes(store.serialize_cdr(image, image_type))
                bag.write("/camera/image", data, log_time=t)
            imu = types[imu_type](
                header=header,
                orientation=types["geometry_msgs/msg/Quaternion"](0.0, 0.0, 0.0, 1.0),
                orientation_covariance=np.zeros(9),
                angular_velocity=vec(0.0, 0.0, 0.0),
                angular_velocity_covariance=np.zeros(9),
                linear_acceleration=vec(0.0, 0.0, 9.81),
                linear_acceleration_covariance=np.zeros(9),
            )
            bag.write("/imu/data", bytes(store.serialize_cdr(imu, imu_type)), log_time=t)


def _stats_part(fs: Any, scratch: Path) -> None:
    import numpy as np
    from rosbags.typesys import Stores, get_typestore

    from bagkit.bag import BagWriter, TopicInfo
    from bagkit.bag.mcap_file import McapFile
    from bagkit.fleet.inputs import bag_paths
    from bagkit.selection.query import Query
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
    query = Query(topics=("/gps/fix",))
    remote = summarize(bag_paths(["s3://bench/imu_gps"]), query)
    remote_s = time.perf_counter() - started
    per_bag = (fetched()[0] - before) / STATS_BAGS
    local = summarize(bag_paths([str(root)]), query)
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


def _serve(template: Path, bags: int) -> None:
    """The tests' range-capable HTTP server holding ``bags`` copies of the bag ``template``
    (one bytes object behind all: memory for one); prints its URL, serves until killed."""
    from tests.storage.servers import HttpStore, start_http

    store = HttpStore()
    for file in template.iterdir():
        data = file.read_bytes()
        for i in range(bags):
            store.objects[f"/large/bag_{i:02d}/{file.name}"] = data
    start_http(store)
    print(store.url, flush=True)
    threading.Event().wait()


if __name__ == "__main__":
    if sys.argv[1:2] == ["serve"]:
        _serve(Path(sys.argv[2]), int(sys.argv[3]))
    else:
        main()
