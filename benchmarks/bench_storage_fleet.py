"""``info`` of 1,000 bags of test-drive size in an S3-compatible store, against downloading
each and running ``info`` on it (issue 38: fetched bytes <= 2x the summary, >= 20x faster).

moto (``bench_storage``) holds every object in memory and reads the whole object for each
range request, and this machine cannot hold 1,000 bags of hundreds of MB: this leg uses
s3rver, which keeps each object as a file and serves a range from it. One bag is uploaded
through S3; the other 999 objects are hard links to its files in s3rver's directory (no disk
used: the server reads them as it reads any object). ``info`` by range reads the whole fleet;
the download is timed for SAMPLE bags (each bag costs the same: the time a bag is what is
compared) with s3fs's concurrent ``get``, then ``info`` of the local copies.

Run: ``.venv/bin/python -m benchmarks storage_fleet`` (``make bench`` installs s3rver with
npm into .s3rver/; without it the leg says so and counts as missed).
"""

from __future__ import annotations

import os
import shutil
import tempfile
import time
from pathlib import Path

from benchmarks.bench_stats import imu_bag
from benchmarks.bench_storage import SPEED_TARGET, SUMMARY_TARGET, summary_bytes
from benchmarks.storage_stores import S3RVER, start_s3rver

BAGS = int(os.environ.get("BAGKIT_BENCH_STORAGE_FLEET_BAGS", "1000"))
IMU_MESSAGES = int(os.environ.get("BAGKIT_BENCH_STORAGE_FLEET_IMU", "1000000"))  # 310 MB
SAMPLE = 8
BUCKET = "bench"


def _link_copies(data: Path, prefix: str, count: int) -> None:
    """Objects ``prefix/bag_0001 ..`` in s3rver's ``data`` directory: hard links to the files
    (object, metadata, checksum) of ``prefix/bag_0000``."""
    source = data / BUCKET / prefix / "bag_0000"
    for i in range(1, count):
        target = data / BUCKET / prefix / f"bag_{i:04d}"
        target.mkdir()
        for file in source.iterdir():
            os.link(file, target / file.name)


def main() -> bool:
    print(f"storage_fleet (s3rver on loopback; load {os.getloadavg()[0]:.1f}):")
    if not S3RVER.exists():
        print(f"  missed: s3rver is not installed at {S3RVER} (make bench installs it with npm)")
        return False
    from bagkit.fleet.listing import folder_info
    from bagkit.storage.range_file import fetched

    template = imu_bag(IMU_MESSAGES)
    summary = summary_bytes(next(template.glob("*.mcap")))
    size = sum(f.stat().st_size for f in template.iterdir())
    scratch = Path(tempfile.mkdtemp(prefix="bagkit-bench-fleet-"))
    server, endpoint = start_s3rver(scratch / "s3rver", BUCKET)
    os.environ.update(
        AWS_ENDPOINT_URL=endpoint,
        AWS_ACCESS_KEY_ID="S3RVER",
        AWS_SECRET_ACCESS_KEY="S3RVER",
        AWS_DEFAULT_REGION="us-east-1",
    )
    try:
        import s3fs

        fs = s3fs.S3FileSystem()
        started = time.perf_counter()
        fs.put(str(template), f"{BUCKET}/drive/bag_0000", recursive=True)
        uploaded = time.perf_counter() - started
        _link_copies(scratch / "s3rver", "drive", BAGS)
        print(
            f"  {BAGS:,} bags of {IMU_MESSAGES:,} Imu ({size / 1e6:,.0f} MB, summary "
            f"{summary:,} B): one uploaded in {uploaded:.1f} s, the rest linked in the store"
        )

        before = fetched()[0]
        started = time.perf_counter()
        remote = folder_info(f"s3://{BUCKET}/drive")
        info_s = time.perf_counter() - started
        per_bag = (fetched()[0] - before) / BAGS
        assert remote is not None and len(remote.bags) == BAGS and not remote.unread
        assert all(bag.message_count == IMU_MESSAGES for bag in remote.bags)

        local = scratch / "download"
        started = time.perf_counter()
        files = [f"bag_{i:04d}/{f.name}" for i in range(SAMPLE) for f in template.iterdir()]
        for i in range(SAMPLE):
            (local / f"bag_{i:04d}").mkdir(parents=True)
        # Every file at once, as s3fs's get does (its parts concurrently too).
        fs.get([f"{BUCKET}/drive/{f}" for f in files], [str(local / f) for f in files])
        downloaded = folder_info(local)
        download_s = time.perf_counter() - started
        assert downloaded is not None and len(downloaded.bags) == SAMPLE
    finally:
        server.terminate()
        server.wait()
        shutil.rmtree(scratch, ignore_errors=True)
    ratio = (download_s / SAMPLE) / (info_s / BAGS)
    print(
        f"  info by range: {info_s:.2f} s ({info_s / BAGS * 1e3:.1f} ms a bag), "
        f"{per_bag:,.0f} bytes a bag: {per_bag / summary:.2f}x the summary (target <= "
        f"{SUMMARY_TARGET:g})\n"
        f"  download + local info of {SAMPLE} of them: {download_s:.2f} s "
        f"({download_s / SAMPLE * 1e3:,.0f} ms a bag): range reads {ratio:.1f}x faster "
        f"(target >= {SPEED_TARGET:g})\n"
        f"  load at the end {os.getloadavg()[0]:.1f}"
    )
    met = per_bag / summary <= SUMMARY_TARGET and ratio >= SPEED_TARGET
    if not met:
        print(f"  missed: info of {BAGS:,} bags of {size / 1e6:,.0f} MB in the store")
    return met


if __name__ == "__main__":
    main()
