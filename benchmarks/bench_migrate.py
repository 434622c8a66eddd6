"""``bagkit migrate`` of a 1M-message Imu bag whose stored Imu lacks one field of today's
(``linear_acceleration_covariance``), against ``bagkit filter`` of the same bag (every topic:
the copy with no decoding) measured in the same run; and the peak memory of each, in a child
process of its own, against the bag's size (flat: it must not grow with the bag).

Run: ``.venv/bin/python -m benchmarks migrate``
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from bagkit.bag import BagWriter, TopicInfo, message_definition
from benchmarks.bench_surgery import IMU, _payloads

MESSAGES = 1_000_000
RATIO_TARGET = 0.5
# The last field of Imu, float64[9]: 72 bytes at the end of each payload.
REMOVED = "float64[9] linear_acceleration_covariance"
REMOVED_BYTES = 72

_RUN = """
import resource, sys, time
from pathlib import Path
from bagkit.surgery import Selection, filter_bag
from bagkit.surgery.migrate import MigrateOptions, migrate_bag
start = time.perf_counter()
if sys.argv[1] == "migrate":
    report = migrate_bag(Path(sys.argv[2]), Path(sys.argv[3]), MigrateOptions())
    assert report.migrated and report.migrated[0].migrated, "nothing was migrated"
else:
    filter_bag(Path(sys.argv[2]), Path(sys.argv[3]), Selection())
usage = resource.getrusage(resource.RUSAGE_SELF)
print(time.perf_counter() - start, usage.ru_maxrss, usage.ru_utime + usage.ru_stime)
"""


def _old_imu_bag(path: Path, count: int) -> Path:
    """``count`` Imu messages stored with the Imu definition less its last field."""
    text = "\n".join(
        line
        for line in message_definition(IMU).splitlines()
        if line.split("#")[0].strip() != REMOVED
    )
    assert text != message_definition(IMU), "the field to remove is not in today's Imu"
    payloads = [p[:-REMOVED_BYTES] for p in _payloads(10_000)["/imu/data"]]
    start = 1_700_000_000_000_000_000
    with BagWriter(path) as bag:
        bag.add_topic(TopicInfo("/imu/data", IMU), text)
        for base in range(0, count, 10_000):
            times = [start + (base + k) * 1_000_000 for k in range(10_000)]
            bag.write_batch("/imu/data", payloads, log_times=times)
            bag.flush()
    return path


def _run(command: str, bag: Path, out: Path) -> tuple[float, int, float]:
    """(seconds, peak RSS in KiB, CPU seconds of all its threads, start-up included) of one
    command in a fresh interpreter."""
    shutil.rmtree(out, ignore_errors=True)
    done = subprocess.run(
        [sys.executable, "-c", _RUN, command, str(bag), str(out)],
        capture_output=True,
        text=True,
        check=True,
    )
    seconds, rss, cpu = done.stdout.split()
    return float(seconds), int(rss), float(cpu)


def main() -> bool:
    """Run the migrate benchmark; return whether its targets were met."""
    with tempfile.TemporaryDirectory(
        prefix="bench_migrate_", dir=os.environ.get("BENCH_TMP")
    ) as tmp:
        small = _old_imu_bag(Path(tmp) / "small", MESSAGES // 10)
        bag = _old_imu_bag(Path(tmp) / "old", MESSAGES)
        size = sum(f.stat().st_size for f in bag.iterdir())
        runs: dict[str, list[tuple[float, int, float]]] = {"filter": [], "migrate": []}
        for _ in range(2):
            for command, times in runs.items():
                times.append(_run(command, bag, Path(tmp) / command))
        t_filter = min(t for t, _, _ in runs["filter"])
        t_migrate = min(t for t, _, _ in runs["migrate"])
        cpu_filter = min(c for _, _, c in runs["filter"])
        cpu_migrate = min(c for _, _, c in runs["migrate"])
        _, rss_small, _ = _run("migrate", small, Path(tmp) / "small_out")
        rss = min(r for _, r, _ in runs["migrate"])
    ratio = t_filter / t_migrate
    print(f"  bag: {MESSAGES:,} Imu messages, {size / 1e6:.0f} MB, one field added by migrate")
    print(f"  filter (every topic): {t_filter:.2f} s; migrate: {t_migrate:.2f} s")
    print(f"  migrate / filter throughput: {ratio:.2f} (target >= {RATIO_TARGET})")
    # On a loaded machine each process gets a share of the cores: the CPU ratio is what the
    # time ratio tends to there, the time ratio with idle cores shows the threads' overlap.
    print(
        f"  CPU seconds (all threads, start-up included): filter {cpu_filter:.2f}, "
        f"migrate {cpu_migrate:.2f}; ratio {cpu_filter / cpu_migrate:.2f}"
    )
    print(
        f"  peak RSS of migrate: {rss / 1024:.0f} MiB for {MESSAGES:,} messages, "
        f"{rss_small / 1024:.0f} MiB for {MESSAGES // 10:,} (flat: about equal)"
    )
    flat = rss < 1.5 * rss_small
    return ratio >= RATIO_TARGET and flat
