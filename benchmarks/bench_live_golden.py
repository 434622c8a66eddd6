"""Live golden check, N times: passes out of N and wall time, against real time and lockstep.

Each run is ``check_live`` on fixtures/faults as the pytest plugin runs it (its nodes on
/clock, ``bagkit replay --clock`` at the spec's live_rate, ``bagkit record``). The target: every
run passes. Peers measured in the same run: the bag's duration (real time) and lockstep.
``BAGKIT_BENCH_LIVE_RUNS`` sets N (default 5; the README records a run of 20).
"""

from __future__ import annotations

import os
import statistics
import tempfile
import time
from pathlib import Path

from bagkit.bag import BagReader
from bagkit.regression.golden import check_lockstep
from bagkit.regression.live import check_live
from bagkit.regression.spec import load_spec

FIXTURE = Path(__file__).resolve().parents[1] / "fixtures" / "faults"
DEFAULT_RUNS = 5


def main() -> bool:
    """Run the live check N times; True when every run passed."""
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    os.environ.setdefault("ROS_DOMAIN_ID", str(100 + os.getpid() % 130))
    runs = int(os.environ.get("BAGKIT_BENCH_LIVE_RUNS", DEFAULT_RUNS))
    spec = load_spec(FIXTURE)
    with BagReader(spec.bag) as reader:
        bag_s = (reader.end_ns - reader.start_ns) / 1e9
    walls: list[float] = []
    passes = 0
    with tempfile.TemporaryDirectory() as tmp:
        started = time.perf_counter()
        check_lockstep(spec, Path(tmp) / "lockstep")
        lockstep_s = time.perf_counter() - started
        for run in range(runs):
            started = time.perf_counter()
            check = check_live(spec, Path(tmp) / f"live-{run}")
            walls.append(time.perf_counter() - started)
            passes += check.passed
            verdict = "pass" if check.passed else "FAIL\n" + check.summary()
            print(f"run {run + 1:>2}/{runs}: {walls[-1]:6.1f} s  {verdict}", flush=True)
    mean = statistics.fmean(walls)
    print(
        f"{spec.name} live x{spec.live_rate:g}: {passes}/{runs} passed; wall {mean:.1f} s mean "
        f"({min(walls):.1f} - {max(walls):.1f}); bag {bag_s:.1f} s: {mean / bag_s:.2f}x real "
        f"time; lockstep {lockstep_s:.2f} s: live {mean / lockstep_s:.0f}x lockstep"
    )
    return passes == runs
