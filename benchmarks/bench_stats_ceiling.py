"""``bagkit stats summary`` of 1M Imu against its ceiling, both as whole processes.

The ceiling (``benchmarks/stats_ceiling.py``) reads the same bag's bytes and computes the same
moments in one numpy pass, knowing the layout in advance. Target (issue 36, item 3): bagkit
within 4x of it. The commands run RUNS times each, interleaved; medians of wall time. The
ceiling's figures are checked against bagkit's (``--format json``) first.

Run: ``.venv/bin/python -m benchmarks stats_ceiling``
"""

from __future__ import annotations

import json
import math
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

from benchmarks.bench_startup import cached_bytecode_env
from benchmarks.bench_stats import LARGE, imu_bag

RUNS = 5
TARGET = 4.0
CEILING = Path(__file__).with_name("stats_ceiling.py")


def _run(command: list[str]) -> tuple[float, float, str]:
    """Wall and CPU (user + system) seconds of ``command``, and its stdout."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    done = subprocess.run(
        command, capture_output=True, text=True, check=True, env=cached_bytecode_env()
    )
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime
    return wall, cpu, done.stdout


def main() -> bool:
    """Print both medians and their ratio; True when bagkit is within TARGET of the ceiling."""
    bag = imu_bag(LARGE)
    bagkit = str(Path(sys.executable).with_name("bagkit"))
    commands = {
        "ceiling": [sys.executable, str(CEILING), str(bag)],
        "bagkit stats summary": [bagkit, "stats", "summary", str(bag), "--format", "json"],
    }
    ceiling_out = _run(commands["ceiling"])[2]
    bagkit_out = _run(commands["bagkit stats summary"])[2]
    (topic,) = json.loads(bagkit_out)["topics"]
    ceiling = [line.split() for line in ceiling_out.splitlines()]
    assert len(ceiling) == len(topic["fields"]) and topic["count"] == LARGE
    for (_, count, *values), field in zip(ceiling, topic["fields"], strict=True):
        assert int(count) == field["count"]
        theirs = [field[k] for k in ("min", "max", "mean", "std")]
        assert all(
            math.isclose(float(a), b, rel_tol=1e-7, abs_tol=1e-9)
            for a, b in zip(values, theirs, strict=True)
        ), field
    times: dict[str, list[float]] = {name: [] for name in commands}
    cpus: dict[str, list[float]] = {name: [] for name in commands}
    for _ in range(RUNS):
        for name, command in commands.items():
            wall, cpu, _ = _run(command)
            times[name].append(wall)
            cpus[name].append(cpu)
    wall = {name: statistics.median(t) for name, t in times.items()}
    cpu = {name: statistics.median(t) for name, t in cpus.items()}
    for name in commands:
        print(
            f"  {name:22s} median wall {wall[name]:6.3f} s, cpu {cpu[name]:6.3f} s ({LARGE:,} Imu)"
        )
    ratio = wall["bagkit stats summary"] / wall["ceiling"]
    cpu_ratio = cpu["bagkit stats summary"] / cpu["ceiling"]
    met = ratio <= TARGET
    print(
        f"bagkit / ceiling: wall {ratio:.2f}x (target <= {TARGET:g}x): "
        f"{'met' if met else 'MISSED'}; cpu {cpu_ratio:.2f}x (what to read under load)"
    )
    return met


if __name__ == "__main__":
    sys.exit(0 if main() else 1)
