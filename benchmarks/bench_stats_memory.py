"""Peak memory of ``bagkit stats summary`` over Imu bags of growing size, as whole processes.

Target (issue 36, item 3): memory flat over a 10 GB bag. Bags of ``bench_stats`` (random Imu,
310 bytes a message on disk, zstd chunks) of each size in ``BAGKIT_BENCH_STATS_GB`` (default
``1,2,4``; add 10 where the disk has room: the bags are cached under benchmarks/results/, 17 GB
for 1,2,4,10, and a 10 GB bag takes minutes to write). Each is summarized once by a fresh
``bagkit stats summary BAG --format json`` under GNU time, whose maximum resident set size is the
child's own (``ru_maxrss`` read by this process would include the size it had when it forked).
Flat: the largest bag's peak RSS within FLAT of the smallest's; the time per GB is printed
beside it (linear in the size where nothing grows with it).

Run: ``BAGKIT_BENCH_STATS_GB=1,2,4,10 .venv/bin/python -m benchmarks stats_memory``
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

from benchmarks.bench_startup import cached_bytecode_env
from benchmarks.bench_stats import imu_bag

FLAT = 1.2
GNU_TIME = "/usr/bin/time"
# stats_imu_1000000_0.mcap is 310,394,160 bytes.
BYTES_PER_MESSAGE = 310.4


def sizes_gb() -> list[float]:
    """The bag sizes to measure, in GB (1e9 bytes), smallest first."""
    text = os.environ.get("BAGKIT_BENCH_STATS_GB", "1,2,4")
    return sorted(float(part) for part in text.split(",") if part.strip())


def _summarize(bag: Path) -> tuple[float, int, int]:
    """Wall seconds, peak RSS in KiB and the message count of one ``stats summary`` process."""
    bagkit = str(Path(sys.executable).with_name("bagkit"))
    command = [GNU_TIME, "-f", "%M", bagkit, "stats", "summary", str(bag), "--format", "json"]
    start = time.perf_counter()
    done = subprocess.run(
        command, capture_output=True, text=True, check=True, env=cached_bytecode_env()
    )
    wall = time.perf_counter() - start
    (topic,) = json.loads(done.stdout)["topics"]
    return wall, int(done.stderr.strip().splitlines()[-1]), topic["count"]


def main() -> bool:
    """Print peak RSS and time per bag size; True when the peak stays within FLAT."""
    if shutil.which(GNU_TIME) is None:
        print(f"{GNU_TIME} (GNU time) is missing: peak RSS not measured")
        return False
    peaks: list[int] = []
    for gigabytes in sizes_gb():
        messages = round(gigabytes * 1e9 / BYTES_PER_MESSAGE)
        start = time.perf_counter()
        bag = imu_bag(messages)
        made = time.perf_counter() - start
        size = sum(f.stat().st_size for f in bag.glob("*.mcap"))
        wall, peak_kib, count = _summarize(bag)
        assert count == messages
        peaks.append(peak_kib)
        print(
            f"  {size / 1e9:5.2f} GB, {messages:>11,} Imu: peak RSS {peak_kib / 1024:6.1f} MiB, "
            f"{wall:6.2f} s ({wall / (size / 1e9):5.2f} s/GB; bag ready in {made:.0f} s)"
        )
    ratio = peaks[-1] / peaks[0]
    met = ratio <= FLAT
    print(
        f"peak RSS largest / smallest bag: {ratio:.2f} (target <= {FLAT:g}): "
        f"{'met' if met else 'MISSED'}"
    )
    return met


if __name__ == "__main__":
    sys.exit(0 if main() else 1)
