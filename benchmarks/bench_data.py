"""``read_dataframe``, ``export`` and ``echo`` on 1,000,000 ``sensor_msgs/msg/Imu`` messages
against rosbags-dataframe, and their peak memory.

Peers measured in the same run, on the same bag (every field of the message):
- ``bagkit.read_dataframe`` vs rosbags + rosbags-dataframe ``get_dataframe``: target >= 10x;
  peak RSS of read_dataframe (above the imports) at most 1.5x the DataFrame's own memory;
- ``bagkit export`` to Parquet vs ``get_dataframe`` + ``DataFrame.to_parquet``: target >= 5x;
  peak RSS of an export of the 1M bag at most 1.5x that of the 100k bag (streaming);
- ``bagkit echo BAG /imu/data -n 1`` as a whole process: under 0.5 s (best of 5), printed
  beside the interpreter's own start-up.

The bags are bench_stats' (one template, fields varied with numpy, bagkit's writer, zstd),
cached under benchmarks/results/ (gitignored); outputs go to a temporary directory.

Run: ``.venv/bin/python -m benchmarks data``
"""

from __future__ import annotations

import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from benchmarks.bench_stats import ARRAYS, LARGE, SCALARS, SMALL, TOPIC, imu_bag

SPEEDUP_DATAFRAME = 10.0
SPEEDUP_EXPORT = 5.0
RSS_OVER_FRAME_CEILING = 1.5
RSS_RATIO_CEILING = 1.5
ECHO_CEILING_S = 0.5
KEYS = [*SCALARS[:2], "header.frame_id", *SCALARS[2:], *ARRAYS]
BAGKIT = str(Path(sys.executable).with_name("bagkit"))


def _seconds(func: object, runs: int = 1) -> float:
    best = float("inf")
    for _ in range(runs):
        start = time.perf_counter()
        func()  # type: ignore[operator]
        best = min(best, time.perf_counter() - start)
    return best


def _ours_dataframe(bag: Path) -> None:
    import bagkit

    frame = bagkit.read_dataframe(bag, TOPIC)
    assert frame.shape == (LARGE, 42)


def _rosbags_dataframe(bag: Path) -> object:
    from rosbags.dataframe import get_dataframe
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    with AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        frame = get_dataframe(reader, TOPIC, KEYS)
    assert frame.shape == (LARGE, len(KEYS))
    return frame


def _ours_export(bag: Path, out: Path) -> None:
    from bagkit.data.export import export

    report = export(bag, out)
    assert report.rows[TOPIC] == LARGE


def _rosbags_export(bag: Path, out: Path) -> None:
    frame = _rosbags_dataframe(bag)
    frame.to_parquet(out / "imu.parquet", compression="zstd")  # type: ignore[attr-defined]


# VmHWM (peak resident set of this process image) restarts at exec, unlike ru_maxrss.
_PROBE = """
import json, re, sys, tempfile
import pandas, pyarrow, pyarrow.parquet
import bagkit
from bagkit.data import frames, export

def peak_kib():
    with open("/proc/self/status") as f:
        return int(re.search(r"VmHWM:\\s+(\\d+)", f.read()).group(1))

baseline = peak_kib()
if sys.argv[1] == "dataframe":
    frame = bagkit.read_dataframe(sys.argv[2], "/imu/data")
    size = int(frame.memory_usage(deep=True).sum())
else:
    with tempfile.TemporaryDirectory() as out:
        rows = export.export(sys.argv[2], out).rows["/imu/data"]
    size = 0
print(json.dumps({"baseline_kib": baseline, "peak_kib": peak_kib(), "frame_bytes": size}))
"""


def _probe(kind: str, bag: Path) -> dict[str, int]:
    out = subprocess.run(
        [sys.executable, "-c", _PROBE, kind, str(bag)], capture_output=True, text=True, check=True
    ).stdout
    return json.loads(out)


def _echo_seconds(bag: Path) -> tuple[float, float]:
    """Best wall time of 5 runs, and the CPU time (user + system) of that run."""
    best = (float("inf"), 0.0)
    for _ in range(5):
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        start = time.perf_counter()
        result = subprocess.run(
            [BAGKIT, "echo", str(bag), TOPIC, "-n", "1"], capture_output=True, check=True
        )
        wall = time.perf_counter() - start
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        assert result.stdout.count(b"log_time:") == 1
        cpu = after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime
        best = min(best, (wall, cpu))
    return best


def main() -> bool:
    """Run the measurements, print the ratios; True when every target is met."""
    start = time.perf_counter()
    large, small = imu_bag(LARGE), imu_bag(SMALL)
    print(f"bags ready in {time.perf_counter() - start:.1f} s ({large.name}, {small.name})")

    ours = _seconds(lambda: _ours_dataframe(large), runs=3)
    theirs = _seconds(lambda: _rosbags_dataframe(large))
    vs_frame = theirs / ours
    print(f"bagkit read_dataframe          {ours:7.2f} s  {LARGE / ours / 1e6:6.2f} M msg/s")
    print(f"rosbags-dataframe get_dataframe {theirs:6.2f} s  {LARGE / theirs / 1e6:6.2f} M msg/s")
    print(f"speedup: {vs_frame:6.1f}x (target >= {SPEEDUP_DATAFRAME:g}x)")

    with tempfile.TemporaryDirectory() as tmp:
        ours_out, theirs_out = Path(tmp, "ours"), Path(tmp, "theirs")
        theirs_out.mkdir()
        ours_export = _seconds(lambda: _ours_export(large, ours_out), runs=3)
        theirs_export = _seconds(lambda: _rosbags_export(large, theirs_out))
        sizes = [
            sum(f.stat().st_size for f in d.rglob("*.parquet")) for d in (ours_out, theirs_out)
        ]
    vs_export = theirs_export / ours_export
    print(f"bagkit export (Parquet, zstd)  {ours_export:7.2f} s  ({sizes[0] / 2**20:.0f} MiB)")
    print(f"get_dataframe + to_parquet     {theirs_export:7.2f} s  ({sizes[1] / 2**20:.0f} MiB)")
    print(f"speedup: {vs_export:6.1f}x (target >= {SPEEDUP_EXPORT:g}x)")

    frame_rss = _probe("dataframe", large)
    above = (frame_rss["peak_kib"] - frame_rss["baseline_kib"]) * 1024
    over_frame = above / frame_rss["frame_bytes"]
    print(
        f"read_dataframe peak RSS above imports {above / 2**20:.0f} MiB for a DataFrame of "
        f"{frame_rss['frame_bytes'] / 2**20:.0f} MiB: {over_frame:.2f}x "
        f"(ceiling {RSS_OVER_FRAME_CEILING:g}x)"
    )
    small_rss, large_rss = _probe("export", small), _probe("export", large)
    rss_ratio = large_rss["peak_kib"] / small_rss["peak_kib"]
    print(
        f"export peak RSS {small_rss['peak_kib'] / 1024:.0f} MiB for {SMALL:,} msgs, "
        f"{large_rss['peak_kib'] / 1024:.0f} MiB for {LARGE:,} (after imports "
        f"{small_rss['baseline_kib'] / 1024:.0f} MiB): ratio {rss_ratio:.2f} "
        f"(ceiling {RSS_RATIO_CEILING:g})"
    )

    echo, echo_cpu = _echo_seconds(large)
    python = _seconds(lambda: subprocess.run([sys.executable, "-c", "pass"], check=True), runs=5)
    print(
        f"bagkit echo -n 1 on {LARGE:,} msgs: {echo:.3f} s whole process ({echo_cpu:.3f} s "
        f"CPU), best of 5 (ceiling {ECHO_CEILING_S:g} s; the interpreter alone starts in "
        f"{python:.3f} s)"
    )
    return (
        vs_frame >= SPEEDUP_DATAFRAME
        and vs_export >= SPEEDUP_EXPORT
        and over_frame <= RSS_OVER_FRAME_CEILING
        and rss_ratio <= RSS_RATIO_CEILING
        and echo < ECHO_CEILING_S
    )
