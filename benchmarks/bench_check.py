"""``bagkit check`` with a 10-assertion contract on 1,000,000 ``sensor_msgs/msg/Imu``.

Measured in the same run, on the 1M-Imu bag of bench_stats, each as a whole CLI process:
- ``pymcap-cli check --spec`` with the same contract in pymcap-cli's spec format (a forbidden
  topic, the schema, rate bounds over a 1 s window, the longest silence as ``timeout``, four
  value bounds): target at least 10x slower than ``bagkit check``. pymcap-cli is installed
  (pinned) into a venv of its own under benchmarks/results/, made on first run;
- ``bagkit stats summary`` of the same bag: ``check`` within 1.5x of it.
Both contracts hold on the bag (exit 0), so each tool does its whole work.

Run: ``.venv/bin/python -m benchmarks check``
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

from benchmarks.bench_stats import LARGE, RESULTS, imu_bag

PEER = "pymcap-cli==0.34.0"
PEER_VENV = RESULTS / "peer_pymcap"
PEER_TARGET = 10.0
STATS_CEILING = 1.5
RUNS = 3
CONTRACT = """\
forbidden: [/debug]
topics:
  /imu/data:
    type: sensor_msgs/msg/Imu
    rate: {min: 50, max: 200, over: 1s}
    max_gap: 100ms
    values:
      linear_acceleration.x: {min: -10, max: 10}
      linear_acceleration.y: {min: -10, max: 10}
      linear_acceleration.z: {min: -10, max: 10}
      angular_velocity.z: {min: -10, max: 10}
"""
PEER_CONTRACT = """\
version: 1
topics:
  debug: {topic: /debug, expected: false}
  imu:
    topic: /imu/data
    schema: {name: sensor_msgs/msg/Imu}
    frequency: {min: 50, max: 200, window: 1s}
    timeout: 100ms
    values:
      - {path: .linear_acceleration.x, min: -10, max: 10}
      - {path: .linear_acceleration.y, min: -10, max: 10}
      - {path: .linear_acceleration.z, min: -10, max: 10}
      - {path: .angular_velocity.z, min: -10, max: 10}
"""


def peer_cli() -> Path:
    """pymcap-cli in its own venv (made once; its dependencies stay out of bagkit's)."""
    cli = PEER_VENV / "bin" / "pymcap-cli"
    if not cli.exists():
        subprocess.run([sys.executable, "-m", "venv", "--clear", str(PEER_VENV)], check=True)
        pip = [str(PEER_VENV / "bin" / "python"), "-m", "pip", "install", "--quiet", PEER]
        subprocess.run(pip, check=True)
    return cli


def _seconds(command: list[str]) -> float:
    start = time.perf_counter()
    done = subprocess.run(command, capture_output=True, text=True, check=False)
    assert done.returncode == 0, f"{command[0]}: exit {done.returncode}\n{done.stdout[-2000:]}"
    return time.perf_counter() - start


def main() -> bool:
    """Run the measurements, print the ratios; True when every target is met."""
    from bagkit.health import HealthSpec, check_bag

    RESULTS.mkdir(exist_ok=True)
    bag = imu_bag(LARGE)
    (mcap,) = bag.glob("*.mcap")
    spec, peer_spec = RESULTS / "check_health.yaml", RESULTS / "check_pymcap.yaml"
    spec.write_text(CONTRACT)
    peer_spec.write_text(PEER_CONTRACT)
    assertions = check_bag(bag, HealthSpec.load(spec)).assertions
    assert len(assertions) == 10 and all(a.passed for a in assertions)
    cli = peer_cli()
    bagkit = str(Path(sys.executable).with_name("bagkit"))
    print(f"load average before: {os.getloadavg()[0]:.1f}")
    check_runs, stats_runs = [], []
    for _ in range(RUNS):  # interleaved, best of each: the machine's load moves
        check_runs.append(_seconds([bagkit, "check", str(bag), "--spec", str(spec)]))
        stats_runs.append(_seconds([bagkit, "stats", "summary", str(bag), "--format", "json"]))
    ours, stats = min(check_runs), min(stats_runs)
    peer = _seconds([str(cli), "check", "--spec", str(peer_spec), str(mcap)])
    print(f"bagkit check (10 assertions)  {ours:7.2f} s  {LARGE / ours / 1e6:6.2f} M msg/s")
    print(f"bagkit stats summary          {stats:7.2f} s")
    print(f"{PEER} check      {peer:7.2f} s")
    vs_peer, vs_stats = peer / ours, ours / stats
    print(f"speedup vs pymcap-cli check: {vs_peer:6.1f}x (target >= {PEER_TARGET:g}x)")
    print(f"check / stats summary:       {vs_stats:6.2f}x (ceiling {STATS_CEILING:g}x)")
    print(f"load average after: {os.getloadavg()[0]:.1f}")
    return vs_peer >= PEER_TARGET and vs_stats <= STATS_CEILING
