"""Fleet commands with their defaults on 10 small bags, against ``--workers 0``.

Without ``--workers`` a command starts a local Dask cluster only when its bags are enough work
to pay for the start (docs/fleet.md, "Dask only when it pays"). On 10 small bags (hard links
to the nominal fixture's golden, about 2 MB in all) every fleet command with its defaults must
take at most 1.2x the time of ``--workers 0``: whole ``bagkit`` processes, run alternately,
medians of 3. The in-process estimate and the start of a local cluster of 2 workers are
printed beside them, which is what the rule weighs.

Run: ``.venv/bin/python -m benchmarks fleet_defaults``
"""

from __future__ import annotations

import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from benchmarks.bench_stats import RESULTS

REPO = Path(__file__).resolve().parents[1]
BAGKIT = str(Path(sys.executable).with_name("bagkit"))
SOURCE = REPO / "fixtures" / "nominal" / "golden"
FIXTURES = [str(REPO / "fixtures" / name) for name in ("fast", "faults", "nominal")]
BAGS = 10
RUNS = 3
TARGET = 1.2


def small_bags() -> Path:
    """10 bag directories whose files are hard links to the nominal fixture's golden."""
    root = RESULTS / f"fleet_small_defaults_{BAGS}"
    if (root / ".complete").is_file():
        return root
    shutil.rmtree(root, ignore_errors=True)
    for i in range(BAGS):
        bag = root / f"bag_{i:02d}"
        bag.mkdir(parents=True)
        for file in SOURCE.iterdir():
            os.link(file, bag / file.name)
    (root / ".complete").touch()
    return root


def _commands(root: Path, scratch: Path) -> dict[str, list[str]]:
    return {
        "stats summary": [BAGKIT, "stats", "summary", str(root)],
        "find": [BAGKIT, "find", str(root), "--when", "/imu/data: linear_acceleration.z > 10"],
        "export": [BAGKIT, "export", str(root), "-o", str(scratch / "export"), "-t", "/imu/data"],
        "catalog": [BAGKIT, "catalog", "build", str(root), "-o", str(scratch / "c.parquet")],
        "golden check": [
            BAGKIT, "golden", "check", *FIXTURES, "--mode", "lockstep",
            "--failures", str(scratch / "f"),
        ],
    }  # fmt: skip


def _run(command: list[str], scratch: Path) -> float:
    for made in ("export", "c.parquet", "f"):  # every run does the whole work again
        path = scratch / made
        shutil.rmtree(path, ignore_errors=True) if path.is_dir() else path.unlink(missing_ok=True)
    start = time.perf_counter()
    done = subprocess.run(command, capture_output=True, text=True, check=False)
    elapsed = time.perf_counter() - start
    if done.returncode != 0:
        raise RuntimeError(f"{' '.join(command)} failed: {done.stderr.strip()}")
    return elapsed


def main() -> bool:
    """Time each command with its defaults and with --workers 0; True when within the target."""
    from bagkit.fleet.cluster import local_cluster

    root = small_bags()
    start = time.perf_counter()
    local_cluster(2).close()
    print(f"a local cluster of 2 workers starts and closes in {time.perf_counter() - start:.2f} s")
    ok = True
    with tempfile.TemporaryDirectory() as tmp:
        scratch = Path(tmp)
        for name, command in _commands(root, scratch).items():
            default, here = [], []
            for _ in range(RUNS):
                default.append(_run(command, scratch))
                here.append(_run([*command, "--workers", "0"], scratch))
            ratio = statistics.median(d / h for d, h in zip(default, here, strict=True))
            met = ratio <= TARGET
            ok &= met
            print(
                f"{name:14s} default {statistics.median(default):.2f} s, --workers 0 "
                f"{statistics.median(here):.2f} s: {ratio:.2f}x (target <= {TARGET}) "
                f"{'met' if met else 'MISSED'}"
            )
    return ok
