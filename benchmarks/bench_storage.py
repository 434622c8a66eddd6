"""Bags in an S3-compatible store on loopback (moto's server), read by range requests.

0. The floor: range GETs of 1 KiB a second that moto answers (one object, one at a time and
   16 at a time, from s3fs), and its CPU per request: on loopback a request costs what the
   server takes to answer it, whatever its size.
1. ``info`` of BAGKIT_BENCH_STORAGE_BAGS bags (default 1,000: the nominal fixture's golden,
   as bag prefixes with metadata.yaml) in moto, against downloading the prefix (s3fs's
   concurrent ``get``) and reading it locally: bytes fetched per bag against its summary
   section (target <= 2x), time (target >= 20x faster), requests of each side per bag by
   operation (HEAD and listings included), and moto's CPU for each side. The same for
   BAGKIT_BENCH_STORAGE_MOTO_BAGS bags of BAGKIT_BENCH_STORAGE_MOTO_MB MB (default 16 of 32:
   camera images and an Imu, a realistic size at a count this machine holds).
   Bags of test-drive size: for each Imu message count of BAGKIT_BENCH_STORAGE_DRIVE_IMU
   (default 100,000, 300,000, 1,000,000: 31, 93, 310 MB, the bags of bench_stats, cached under
   benchmarks/results/), BAGKIT_BENCH_STORAGE_DRIVE_BAGS copies (default 16, fewer where they
   would pass BAGKIT_BENCH_STORAGE_DRIVE_GB in moto, default 6), one uploaded and the rest
   copied inside moto; the same figures, then the bag size at which the time ratio crosses 20x
   (or what it tends to). ``BAGKIT_BENCH_STORAGE_DRIVE_BAGS=0`` leaves them out.
2. ``info`` of BAGKIT_BENCH_STORAGE_NAMED bags (default 100) named one by one by their URLs
   (as ``bagkit info URL`` of each), as bag prefixes and as bare ``.mcap`` files: requests a
   bag by operation, against downloading each and reading it locally.
3. The same as 1. for BAGKIT_BENCH_STORAGE_LARGE_BAGS bags of BAGKIT_BENCH_STORAGE_LARGE_MB MB
   (default 9 of 256: the first opens the client, 8 are timed) on the tests' range-capable HTTP
   server (moto answers a range by reading the whole object), requests counted by the server;
   then the sizes of BAGKIT_BENCH_STORAGE_DRIVE_IMU there, and where the ratio crosses 20x.
4. ``stats summary -t /gps/fix`` over 20 bags of Imu (100 Hz) + NavSatFix (1 Hz): bytes
   fetched against the chunks that hold /gps/fix (target <= 1.2x), values equal to the local
   read.

All in this process (the byte counter is per process), the same stores, the same run.
Run: ``.venv/bin/python -m benchmarks storage``
"""

from __future__ import annotations

import itertools
import os
import shutil
import struct
import tempfile
import time
from collections import Counter
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from benchmarks.storage_stores import (
    HttpServer,
    S3Requests,
    cpu_s,
    peak_rss_mb,
    per_bag,
    start_moto,
    write_images,
)

REPO = Path(__file__).resolve().parents[1]
GOLDEN = REPO / "fixtures" / "nominal" / "golden"
BAGS = int(os.environ.get("BAGKIT_BENCH_STORAGE_BAGS", "1000"))
MOTO_BAGS = int(os.environ.get("BAGKIT_BENCH_STORAGE_MOTO_BAGS", "16"))
MOTO_MB = int(os.environ.get("BAGKIT_BENCH_STORAGE_MOTO_MB", "32"))
LARGE_BAGS = int(os.environ.get("BAGKIT_BENCH_STORAGE_LARGE_BAGS", "9"))
LARGE_MB = int(os.environ.get("BAGKIT_BENCH_STORAGE_LARGE_MB", "256"))
STATS_BAGS = 20
STATS_IMU_MESSAGES = int(os.environ.get("BAGKIT_BENCH_STORAGE_IMU", "50000"))
DRIVE_BAGS = int(os.environ.get("BAGKIT_BENCH_STORAGE_DRIVE_BAGS", "16"))
DRIVE_IMU = os.environ.get("BAGKIT_BENCH_STORAGE_DRIVE_IMU", "100000,300000,1000000")
DRIVE_BYTES = float(os.environ.get("BAGKIT_BENCH_STORAGE_DRIVE_GB", "6")) * 1e9
FLOOR_REQUESTS = 400
SUMMARY_TARGET, SPEED_TARGET, CHUNKS_TARGET = 2.0, 20.0, 1.2
NAMED_BAGS = int(os.environ.get("BAGKIT_BENCH_STORAGE_NAMED", "100"))


@dataclass(frozen=True)
class Timing:
    """One leg's bag size (bytes) and seconds a bag: ``info`` by range, download + local."""

    size: int
    info_s: float
    download_s: float

    @property
    def ratio(self) -> float:
        return self.download_s / self.info_s


def summary_bytes(file: Path) -> int:
    """The summary section's size, from the MCAP footer."""
    with open(file, "rb") as f:
        f.seek(-8 - 29, 2)
        footer = f.read(29)
    (summary_start,) = struct.unpack_from("<Q", footer, 9)
    return file.stat().st_size - summary_start


class Moto:
    """The moto server, the peer's s3fs client and bagkit's, each counting its requests."""

    def __init__(self, pid: int, fs: Any) -> None:
        from bagkit.storage.filesystems import filesystem

        self.pid = pid
        self.fs = fs
        self.bagkit_fs = filesystem("s3://bench")[0]
        self.bagkit_fs.info("bench")  # its client made, as the peer's is
        self.peer = S3Requests(fs)
        self.bagkit = S3Requests(self.bagkit_fs)


def _floor(moto: Moto) -> None:
    """Range GETs of 1 KiB a second moto answers (the peer's client), one and 16 at a time."""
    fs = moto.fs
    fs.pipe_file("bench/floor", bytes(200_000))
    fs.cat_file("bench/floor", 0, 1024)
    cpu, started = cpu_s(moto.pid), time.perf_counter()
    for _ in range(FLOOR_REQUESTS):
        fs.cat_file("bench/floor", 0, 1024)
    one_s, one_cpu = time.perf_counter() - started, cpu_s(moto.pid) - cpu
    started = time.perf_counter()
    with ThreadPoolExecutor(16) as pool:
        list(pool.map(lambda _: fs.cat_file("bench/floor", 0, 1024), range(FLOOR_REQUESTS)))
    many_s = time.perf_counter() - started
    print(
        f"  floor: moto answers {FLOOR_REQUESTS / one_s:.0f} range GETs/s one at a time, "
        f"{FLOOR_REQUESTS / many_s:.0f}/s 16 at a time ({one_cpu / FLOOR_REQUESTS * 1e3:.1f} ms "
        "of its CPU each)"
    )


def _info_against_download(
    moto: Moto, local: Path, key: str, scratch: Path, what: str
) -> tuple[float, Timing]:
    """``info`` of the bags under ``local``, uploaded to ``bench/key``: by range, against
    downloading the prefix (s3fs's concurrent ``get``) and reading it locally."""
    bags = sorted(p for p in local.iterdir() if p.is_dir())
    started = time.perf_counter()
    moto.fs.put(str(local), f"bench/{key}", recursive=True)
    print(f"  {what}: {len(bags)} bags uploaded in {time.perf_counter() - started:.1f} s")
    return _measure_info(moto, bags[0], len(bags), key, scratch)


def _measure_info(
    moto: Moto, template: Path, count: int, key: str, scratch: Path
) -> tuple[float, Timing]:
    """``info`` of the ``count`` copies of the bag ``template`` under ``bench/key``: by range,
    against downloading the prefix (s3fs's concurrent ``get``) and reading it locally; the
    bytes fetched a bag against its summary, and the times."""
    from bagkit.bag.info import bag_info
    from bagkit.fleet.listing import folder_info
    from bagkit.storage.range_file import fetched

    fs = moto.fs
    file = next(template.glob("*.mcap"))
    summary = summary_bytes(file)
    size = sum(f.stat().st_size for f in template.iterdir())
    exact = bag_info(template)  # the modules imported for both sides

    before, sent, cpu = fetched(), Counter(moto.bagkit.counts), cpu_s(moto.pid)
    started = time.perf_counter()
    remote = folder_info(f"s3://bench/{key}")
    remote_s = time.perf_counter() - started
    remote_cpu = cpu_s(moto.pid) - cpu
    spent = fetched()[0] - before[0]
    remote_requests = moto.bagkit.counts - sent
    assert remote is not None and len(remote.bags) == count and not remote.unread
    bounded = {t.topic: t.rate_hz for t in remote.bags[0].topics}
    worst = max(
        (
            abs(bound - t.rate_hz) / t.rate_hz
            for t in exact.topics
            if t.rate_hz and (bound := bounded[t.topic]) is not None
        ),
        default=0.0,
    )

    target = scratch / "download" / key
    sent, cpu = Counter(moto.peer.counts), cpu_s(moto.pid)
    started = time.perf_counter()
    fs.get(f"bench/{key}", str(target), recursive=True)
    downloaded = folder_info(target)
    download_s = time.perf_counter() - started
    download_cpu = cpu_s(moto.pid) - cpu
    peer_requests = moto.peer.counts - sent
    assert downloaded is not None and len(downloaded.bags) == count
    shutil.rmtree(target)
    requests_ratio = peer_requests.total() / remote_requests.total()
    print(
        f"  info by range: {remote_s:.2f} s; {spent / count:,.0f} bytes per bag (summary "
        f"{summary:,} B, bag {size:,} B): {spent / count / summary:.2f}x the summary (target "
        f"<= {SUMMARY_TARGET:g}); rates from chunk bounds, worst {worst:.1%} below exact\n"
        f"    requests a bag: {per_bag(remote_requests, count)}; moto CPU {remote_cpu:.2f} s\n"
        f"  download + local info: {download_s:.2f} s\n"
        f"    requests a bag: {per_bag(peer_requests, count)}; moto CPU {download_cpu:.2f} s\n"
        f"  range reads {download_s / remote_s:.1f}x faster (target >= {SPEED_TARGET:g}); the "
        f"download makes {requests_ratio:.2f}x their requests; moto's peak RSS "
        f"{peak_rss_mb(moto.pid):,} MB"
    )
    return spent / count / summary, Timing(size, remote_s / count, download_s / count)


def _info_part(moto: Moto, scratch: Path) -> bool:
    """The 1,000 golden bags (and the optional large ones): whether the golden's met both
    targets."""
    local = scratch / "fleet"
    for i in range(BAGS):
        shutil.copytree(GOLDEN, local / f"bag_{i:04d}", copy_function=os.link)
    summaries, timing = _info_against_download(moto, local, "fleet", scratch, "the nominal golden")
    shutil.rmtree(local)
    if MOTO_BAGS:
        local = scratch / "moto_large"
        write_images(local / "bag_00", MOTO_MB)
        for i in range(1, MOTO_BAGS):
            shutil.copytree(local / "bag_00", local / f"bag_{i:02d}", copy_function=os.link)
        os.sync()
        what = f"bags of {MOTO_MB} MB (camera + Imu)"
        _info_against_download(moto, local, "moto_large", scratch, what)
        moto.fs.rm("bench/moto_large", recursive=True)
        shutil.rmtree(local)
    met = summaries <= SUMMARY_TARGET and timing.ratio >= SPEED_TARGET
    if not met:
        print(
            f"  missed: info of {BAGS:,} golden bags, {summaries:.2f}x the summary "
            f"(<= {SUMMARY_TARGET}) and {timing.ratio:.1f}x faster (>= {SPEED_TARGET})"
        )
    return met


def _drive_part(moto: Moto, scratch: Path) -> None:
    """``info`` of bags of test-drive size in moto: for each size of DRIVE_IMU (Imu messages at
    100 Hz, 310 bytes each: the 1M bag is 310 MB), DRIVE_BAGS copies, fewer where they would
    pass DRIVE_BYTES in moto (which answers every request by reading the whole object into
    memory); one uploaded, the rest copied inside moto (CopyObject). Then the size at which
    the ratio crosses 20x."""
    from benchmarks.bench_stats import imu_bag

    timings = []
    for messages in sorted(int(n) for n in DRIVE_IMU.split(",") if n):
        template = imu_bag(messages)
        size = sum(f.stat().st_size for f in template.iterdir())
        count = max(2, min(DRIVE_BAGS, int(DRIVE_BYTES // size)))
        key = f"drive_{messages}"
        started = time.perf_counter()
        moto.fs.put(str(template), f"bench/{key}/bag_00", recursive=True)
        uploaded = time.perf_counter() - started
        source = f"bench/{key}/bag_00"
        copies = [f"bench/{key}/bag_{i:02d}" for i in range(1, count)]
        with ThreadPoolExecutor(4) as pool:  # moto hashes and writes each copy: 2 cores
            list(pool.map(lambda to, src=source: moto.fs.copy(src, to, recursive=True), copies))
        print(
            f"  {count} bags of {messages:,} Imu ({size / 1e6:,.0f} MB): one uploaded in "
            f"{uploaded:.1f} s, {count - 1} copied in moto in "
            f"{time.perf_counter() - started - uploaded:.1f} s"
        )
        try:
            timings.append(_measure_info(moto, template, count, key, scratch)[1])
        finally:
            moto.fs.rm(f"bench/{key}", recursive=True)
    print(f"  {_crossing(timings)}")


def _crossing(timings: list[Timing], store: str = "moto") -> str:
    """Where the time ratio crosses 20x: between two sizes measured, or from the line through
    the two largest (each side's seconds a bag = a fixed cost + a cost a byte; in moto the
    download's cost grows faster: each 50 MB part s3fs asks for costs moto a read of the whole
    object, so this is a bound for the sizes near those measured)."""
    timings = sorted(timings, key=lambda t: t.size)
    ratios = ", ".join(f"{t.size / 1e6:,.0f} MB {t.ratio:.1f}x" for t in timings)
    for low, high in itertools.pairwise(timings):
        if low.ratio < 20 <= high.ratio:
            share = (20 - low.ratio) / (high.ratio - low.ratio)
            crossed = low.size + share * (high.size - low.size)
            return f"ratios {ratios}: 20x crossed at about {crossed / 1e6:,.0f} MB"
    if timings and timings[0].ratio >= 20:
        return f"ratios {ratios}: 20x at every size measured"
    if len(timings) < 2:
        return f"ratios {ratios}"
    low, high = timings[-2:]
    info_per_byte = (high.info_s - low.info_s) / (high.size - low.size)
    download_per_byte = (high.download_s - low.download_s) / (high.size - low.size)
    if info_per_byte <= 0 or download_per_byte / info_per_byte >= 20:
        fixed_info = high.info_s - info_per_byte * high.size
        fixed_download = high.download_s - download_per_byte * high.size
        bytes_at = (fixed_download - 20 * fixed_info) / (20 * info_per_byte - download_per_byte)
        return f"ratios {ratios}: 20x reached at about {bytes_at / 1e6:,.0f} MB (extrapolated)"
    return (
        f"ratios {ratios}: 20x not reached in {store} at any size measured; on the line "
        "through the two largest (each side a fixed cost + a cost a byte) the ratio stays "
        f"under {download_per_byte / info_per_byte:.1f}x"
    )


def _named_part(moto: Moto, scratch: Path) -> None:
    """``info`` of bags named one by one by their URLs (as ``bagkit info URL`` of each): bag
    prefixes and bare ``.mcap`` files (the nominal golden), REMOTE_READERS at a time as bagkit
    reads a list of bags in storage (``run_each``: the first alone), against
    downloading each (s3fs's ``get``) and reading it locally; requests a bag by operation."""
    from bagkit.bag.info import bag_info
    from bagkit.fleet.execute import REMOTE_READERS, readers_for, run_each
    from bagkit.storage.range_file import fetched

    fs = moto.fs
    local = scratch / "named"
    mcap = next(GOLDEN.glob("*.mcap"))
    summary = summary_bytes(mcap)
    (local / "bare").mkdir(parents=True)
    for i in range(NAMED_BAGS):
        shutil.copytree(GOLDEN, local / "prefix" / f"bag_{i:03d}", copy_function=os.link)
        os.link(mcap, local / "bare" / f"bag_{i:03d}.mcap")
    fs.put(str(local), "bench/", recursive=True)
    for what, names in (
        ("bag prefixes", [f"prefix/bag_{i:03d}" for i in range(NAMED_BAGS)]),
        ("bare .mcap files", [f"bare/bag_{i:03d}.mcap" for i in range(NAMED_BAGS)]),
    ):
        sent, before = Counter(moto.bagkit.counts), fetched()[0]
        started = time.perf_counter()
        urls = [f"s3://bench/named/{n}" for n in names]
        run_each(bag_info, urls, None, threads=readers_for(urls))
        remote_s = time.perf_counter() - started
        remote_requests = moto.bagkit.counts - sent
        spent = (fetched()[0] - before) / NAMED_BAGS
        target = scratch / "download" / "named"

        def download(name: str, target: Path = target) -> None:
            fs.get(f"bench/named/{name}", str(target / name), recursive=True)
            bag_info(target / name)

        sent = Counter(moto.peer.counts)
        started = time.perf_counter()
        with ThreadPoolExecutor(REMOTE_READERS) as pool:
            list(pool.map(download, names))
        download_s = time.perf_counter() - started
        peer_requests = moto.peer.counts - sent
        shutil.rmtree(target)
        print(
            f"  {NAMED_BAGS} {what} named one by one: info {remote_s:.2f} s, download + local "
            f"info {download_s:.2f} s: {download_s / remote_s:.1f}x\n"
            f"    info: {spent:,.0f} bytes a bag ({spent / summary:.2f}x the summary); "
            f"requests a bag: info {per_bag(remote_requests, NAMED_BAGS)}; download "
            f"{per_bag(peer_requests, NAMED_BAGS)}"
        )
    shutil.rmtree(local)


def _large_part(scratch: Path) -> None:
    """``info`` of LARGE_BAGS bags of LARGE_MB MB (camera + Imu) on the tests' range-capable
    HTTP server, then the same for the sizes of DRIVE_IMU and where the ratio crosses 20x."""
    from benchmarks.bench_stats import imu_bag

    template = scratch / "large" / "bag_00"
    write_images(template, LARGE_MB)
    os.sync()  # its write-back would slow whichever side runs first
    _http_info(template, scratch, "camera + Imu")
    if DRIVE_BAGS:
        sizes = sorted(int(n) for n in DRIVE_IMU.split(",") if n)
        timings = [_http_info(imu_bag(n), scratch, f"{n:,} Imu") for n in sizes]
        print(f"  on the HTTP range server: {_crossing(timings, 'the HTTP range server')}")


def _http_info(template: Path, scratch: Path, what: str) -> Timing:
    """``info`` of LARGE_BAGS copies of ``template`` on the tests' range-capable HTTP server
    (moto answers a range by reading the whole object), against fetching each bag (fsspec's
    concurrent ``get``) and reading it locally."""
    import fsspec

    from bagkit.bag.info import bag_info
    from bagkit.fleet.execute import REMOTE_READERS
    from bagkit.fleet.listing import folder_info
    from bagkit.storage.range_file import fetched

    files = sorted(p.name for p in template.iterdir())
    server = HttpServer(template, LARGE_BAGS)
    try:
        urls = [f"{server.url}/large/bag_{i:02d}" for i in range(LARGE_BAGS)]
        mcap = template / next(n for n in files if n.endswith(".mcap"))
        summary = summary_bytes(mcap)
        size = sum((template / n).stat().st_size for n in files)
        exact = bag_info(template)  # modules imported for both sides
        bag_info(urls[0])  # the HTTP client made, as the download's is below
        before, answered = fetched(), server.requests()
        started = time.perf_counter()
        with ThreadPoolExecutor(REMOTE_READERS) as pool:
            remote = list(pool.map(bag_info, urls[1:]))
        remote_s = time.perf_counter() - started
        spent = fetched()[0] - before[0]
        remote_requests, answered = server.requests() - answered, server.requests()
        fs = fsspec.filesystem("http")
        target = scratch / "download" / "large"
        started = time.perf_counter()
        sources = [f"{u}/{n}" for u in urls[1:] for n in files]
        fs.get(sources, [str(target / s.split("/large/", 1)[1]) for s in sources])
        downloaded = folder_info(target)
        download_s = time.perf_counter() - started
        peer_requests = server.requests() - answered
        assert downloaded is not None and len(downloaded.bags) == len(remote)
        shutil.rmtree(target)
    finally:
        server.stop()
    count = len(remote)
    bounded = {t.topic: t.rate_hz for t in remote[0].topics}
    worst = max(
        (
            abs(bound - t.rate_hz) / t.rate_hz
            for t in exact.topics
            if t.rate_hz and (bound := bounded[t.topic]) is not None
        ),
        default=0.0,
    )
    print(
        f"  {count} bags of {size / 1e6:.0f} MB ({what}) on an HTTP range server: info "
        f"{remote_s:.2f} s ({spent / count:,.0f} bytes per bag, {spent / count / summary:.2f}x "
        f"the summary of {summary:,} B; rates worst {worst:.1%} below exact); fetch + local "
        f"info {download_s:.2f} s: range reads {download_s / remote_s:.1f}x faster (target "
        f">= {SPEED_TARGET:g})\n"
        f"    requests a bag: info {per_bag(remote_requests, count)}; fetch "
        f"{per_bag(peer_requests, count)}"
    )
    return Timing(size, remote_s / count, download_s / count)


def _stats_part(fs: Any, scratch: Path) -> bool:
    """``stats -t /gps/fix`` of bags in moto: whether it fetched at most CHUNKS_TARGET times
    the chunks holding the topic and gave the local read's values."""
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
        f"{per_bag / chunk_bytes:.2f}x the chunks (target <= {CHUNKS_TARGET}), {remote_s:.2f} s; "
        f"values equal to the local read: {same}"
    )
    met = per_bag / chunk_bytes <= CHUNKS_TARGET and same
    if not met:
        print("  missed: stats of one small topic in storage")
    return met


def main() -> bool:
    """Print every part; whether the issue's targets (the golden ``info`` and ``stats``) were
    met."""
    print(f"storage (moto's S3 server on loopback; load {os.getloadavg()[0]:.1f}):")
    server, endpoint = start_moto()
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
        moto = Moto(server.pid, fs)
        _floor(moto)
        info_met = _info_part(moto, scratch)
        if DRIVE_BAGS:
            _drive_part(moto, scratch)
        _named_part(moto, scratch)
        _large_part(scratch)
        stats_met = _stats_part(fs, scratch)
    finally:
        server.terminate()
        server.wait()
        shutil.rmtree(scratch, ignore_errors=True)
    print(f"  load at the end {os.getloadavg()[0]:.1f}")
    return info_met and stats_met


if __name__ == "__main__":
    main()
