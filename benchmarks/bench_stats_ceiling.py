"""``bagkit stats summary`` of 1M Imu against its ceiling, both as whole processes.

The ceiling (``benchmarks/stats_ceiling.py``) reads the same bag's bytes and computes the same
moments in one numpy pass, knowing the layout in advance. Targets (issue 36, item 3): bagkit
within 4x of it, and at least 40x faster than the peer rosbags + rosbags-dataframe + pandas
(``bench_stats.rosbags_dataframe``: a frame of every numeric field, then its moments) started
the same way. bagkit and the ceiling run RUNS times each, interleaved, the peer (about 30 s a
run) PEER_RUNS times among them; medians of wall time. The ceiling's figures are checked
against bagkit's (``--format json``) first. Each process's peak RSS is printed beside its time.

Run: ``.venv/bin/python -m benchmarks stats_ceiling``
"""

from __future__ import annotations

import json
import math
import resource
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

from benchmarks.bench_startup import cached_bytecode_env
from benchmarks.bench_stats import LARGE, imu_bag

RUNS = 5
PEER_RUNS = 1
TARGET = 4.0
TARGET_VS_PEER = 40.0
CEILING = Path(__file__).with_name("stats_ceiling.py")
REPOSITORY = Path(__file__).resolve().parents[1]
PEER = (
    "import sys; from pathlib import Path; "
    "from benchmarks.bench_stats import rosbags_dataframe as r; r(Path(sys.argv[1]))"
)
GNU_TIME = "/usr/bin/time"


def _run(command: list[str]) -> tuple[float, float, str, int]:
    """Wall and CPU (user + system) seconds of ``command``, its stdout and peak RSS in KiB
    (by GNU time: the child's own, where ``ru_maxrss`` would include this process's at fork;
    0 without GNU time)."""
    timed = shutil.which(GNU_TIME) is not None
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    done = subprocess.run(
        [GNU_TIME, "-f", "%M", *command] if timed else command,
        capture_output=True,
        text=True,
        check=True,
        env=cached_bytecode_env(),
        cwd=REPOSITORY,
    )
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime
    peak = int(done.stderr.strip().splitlines()[-1]) if timed else 0
    return wall, cpu, done.stdout, peak


def main() -> bool:
    """Print the medians and ratios; True when bagkit is within TARGET of the ceiling and at
    least TARGET_VS_PEER faster than the peer."""
    bag = imu_bag(LARGE)
    bagkit = str(Path(sys.executable).with_name("bagkit"))
    commands = {
        "ceiling": [sys.executable, str(CEILING), str(bag)],
        "bagkit stats summary": [bagkit, "stats", "summary", str(bag), "--format", "json"],
        "rosbags-dataframe": [sys.executable, "-c", PEER, str(bag)],
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
    peaks: dict[str, list[int]] = {name: [] for name in commands}
    peer_rounds = {RUNS // 2 + i for i in range(PEER_RUNS)}  # the peer among the others
    for round_ in range(RUNS):
        for name, command in commands.items():
            if name == "rosbags-dataframe" and round_ not in peer_rounds:
                continue
            wall, cpu, _, peak = _run(command)
            times[name].append(wall)
            cpus[name].append(cpu)
            peaks[name].append(peak)
    median_wall = {name: statistics.median(t) for name, t in times.items()}
    median_cpu = {name: statistics.median(t) for name, t in cpus.items()}
    for name in commands:
        print(
            f"  {name:22s} median wall {median_wall[name]:6.3f} s, cpu {median_cpu[name]:6.3f} s, "
            f"peak RSS {max(peaks[name]) / 1024:5.0f} MiB ({LARGE:,} Imu, "
            f"{len(times[name])} runs)"
        )
    ours = "bagkit stats summary"
    ratio, cpu_ratio = (
        median_wall[ours] / median_wall["ceiling"],
        median_cpu[ours] / median_cpu["ceiling"],
    )
    vs_peer = median_wall["rosbags-dataframe"] / median_wall[ours]
    met, peer_met = ratio <= TARGET, vs_peer >= TARGET_VS_PEER
    print(
        f"bagkit / ceiling: wall {ratio:.2f}x (target <= {TARGET:g}x): "
        f"{'met' if met else 'MISSED'}; cpu {cpu_ratio:.2f}x (what to read under load)"
    )
    print(
        f"rosbags-dataframe / bagkit: wall {vs_peer:.1f}x (target >= {TARGET_VS_PEER:g}x): "
        f"{'met' if peer_met else 'MISSED'}; cpu "
        f"{median_cpu['rosbags-dataframe'] / median_cpu[ours]:.1f}x"
    )
    # What any reader of these bytes can reach against the peer: the bound on the line above.
    print(
        f"rosbags-dataframe / ceiling: wall "
        f"{median_wall['rosbags-dataframe'] / median_wall['ceiling']:.1f}x, cpu "
        f"{median_cpu['rosbags-dataframe'] / median_cpu['ceiling']:.1f}x"
    )
    return met and peer_met


if __name__ == "__main__":
    sys.exit(0 if main() else 1)
