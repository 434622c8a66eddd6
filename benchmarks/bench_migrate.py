"""``bagkit migrate`` of a 1M-message Imu bag whose stored Imu lacks one field of today's
(``linear_acceleration_covariance``), against two ``bagkit filter`` runs of the same bag
measured in the same run. The target (issue 39: ">= 0.5 of ``bagkit filter`` on the same bag,
the decode and encode are the extra work") is taken against the filter that reads and writes
what migrate reads and writes: a ``--where`` that every message passes, so that every chunk is
opened, one field of every message decoded, the records written into new chunks and
compressed; what migrate adds is the decode and encode of every field. The filter of every
topic is printed beside it: it copies chunks as stored (no decompression beyond the CRC check,
no recompression), so against it migrate also pays the recompression of every byte, and the
floor printed last (the CPU of decompressing the input's chunks and of compressing the
migrated records as the output stores them, bagkit's zstd, chunk by chunk on this thread)
bounds that ratio. And the peak memory of migrate, in a child process of its own, against the
bag's size (flat: it must not grow with the bag).

Run: ``.venv/bin/python -m benchmarks migrate``
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

from mcap.records import Chunk
from mcap.stream_reader import StreamReader

from bagkit.bag import BagWriter, TopicInfo, message_definition
from bagkit.bag.bag_files import compressor
from bagkit.bag.mcapio.chunks import decompress
from benchmarks.bench_surgery import IMU, _payloads

MESSAGES = 1_000_000
RATIO_TARGET = 0.5
# The last field of Imu, float64[9]: 72 bytes at the end of each payload.
REMOVED = "float64[9] linear_acceleration_covariance"
REMOVED_BYTES = 72
# Every message passes (the field is uniform in [0, 1)): filter opens and rewrites every chunk.
EVERY_MESSAGE = "linear_acceleration.z >= 0"

_RUN = """
import resource, sys, time
from pathlib import Path
from bagkit.surgery import Selection, filter_bag
from bagkit.surgery.migrate import MigrateOptions, migrate_bag
start = time.perf_counter()
if sys.argv[1] == "migrate":
    report = migrate_bag(Path(sys.argv[2]), Path(sys.argv[3]), MigrateOptions())
    assert report.migrated and report.migrated[0].migrated, "nothing was migrated"
elif sys.argv[1] == "rewrite":
    from bagkit.selection.query import Query
    where = Selection.of(Query.create([], [], None, None, sys.argv[4]))
    report = filter_bag(Path(sys.argv[2]), Path(sys.argv[3]), where)
    assert report.chunks_copied == 0, "chunks were copied as stored"
    assert sum(report.topic_counts.values()) == report.input_messages, "messages were dropped"
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
        [sys.executable, "-c", _RUN, command, str(bag), str(out), EVERY_MESSAGE],
        capture_output=True,
        text=True,
        check=True,
    )
    seconds, rss, cpu = done.stdout.split()
    return float(seconds), int(rss), float(cpu)


def _chunks(bag: Path) -> Iterator[Chunk]:
    for path in sorted(bag.glob("*.mcap")):
        with path.open("rb") as f:
            for record in StreamReader(f, emit_chunks=True).records:
                if isinstance(record, Chunk):
                    yield record


def _floor(bag: Path, migrated: Path) -> tuple[float, float]:
    """CPU seconds of decompressing ``bag``'s chunks, and of compressing ``migrated``'s
    records with its compression (zstd), chunk by chunk."""
    unpack = 0.0
    for chunk in _chunks(bag):
        start = time.thread_time()
        decompress(chunk.compression, chunk.data, chunk.uncompressed_size, 1 << 30)
        unpack += time.thread_time() - start
    _, compress = compressor("zstd")
    pack = 0.0
    for chunk in _chunks(migrated):
        records = decompress(chunk.compression, chunk.data, chunk.uncompressed_size, 1 << 30)
        start = time.thread_time()
        compress([records])
        pack += time.thread_time() - start
    return unpack, pack


def main() -> bool:
    """Run the migrate benchmark; return whether its targets were met."""
    with tempfile.TemporaryDirectory(
        prefix="bench_migrate_", dir=os.environ.get("BENCH_TMP")
    ) as tmp:
        small = _old_imu_bag(Path(tmp) / "small", MESSAGES // 10)
        bag = _old_imu_bag(Path(tmp) / "old", MESSAGES)
        size = sum(f.stat().st_size for f in bag.iterdir())
        runs: dict[str, list[tuple[float, int, float]]] = {
            "filter": [],
            "rewrite": [],
            "migrate": [],
        }
        for _ in range(2):
            for command, times in runs.items():
                times.append(_run(command, bag, Path(tmp) / command))
        wall = {command: min(t for t, _, _ in times) for command, times in runs.items()}
        cpu = {command: min(c for _, _, c in times) for command, times in runs.items()}
        unpack, pack = _floor(bag, Path(tmp) / "migrate")
        _, rss_small, _ = _run("migrate", small, Path(tmp) / "small_out")
        rss = min(r for _, r, _ in runs["migrate"])
    ratio = wall["rewrite"] / wall["migrate"]
    copy_ratio = wall["filter"] / wall["migrate"]
    print(f"  bag: {MESSAGES:,} Imu messages, {size / 1e6:.0f} MB, one field added by migrate")
    # CPU: all threads, the interpreter's start-up included. On a loaded machine each process
    # gets a share of the cores: the CPU ratio is what the time ratio tends to there, the time
    # ratio with idle cores shows the threads' overlap.
    for command, what in (
        ("filter", "filter, every topic (chunks copied as stored)"),
        ("rewrite", f"filter --where '{EVERY_MESSAGE}' (every chunk opened and rewritten)"),
        ("migrate", "migrate"),
    ):
        print(f"  {what}: {wall[command]:.2f} s, {cpu[command]:.2f} s CPU")
    print(
        "  migrate / filter --where (chunks rewritten, the target's peer) throughput: "
        f"{ratio:.2f} (target >= {RATIO_TARGET}), CPU {cpu['rewrite'] / cpu['migrate']:.2f}"
    )
    print(
        f"  migrate / filter (chunks copied as stored) throughput: {copy_ratio:.2f}, "
        f"CPU {cpu['filter'] / cpu['migrate']:.2f}"
    )
    floor = (unpack + pack) / 2
    print(
        f"  floor: input decompressed {unpack:.2f} s CPU + output compressed {pack:.2f} s CPU"
        f" = at least {floor:.2f} s on 2 cores: a ratio to the copy of at most "
        f"{wall['filter'] / floor:.2f}"
    )
    print(
        f"  peak RSS of migrate: {rss / 1024:.0f} MiB for {MESSAGES:,} messages, "
        f"{rss_small / 1024:.0f} MiB for {MESSAGES // 10:,} (flat: about equal)"
    )
    flat = rss < 1.5 * rss_small
    return ratio >= RATIO_TARGET and flat
