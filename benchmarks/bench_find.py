"""``bagkit find`` over 40 bags of 100k Imu, and the first match of ``echo --where``.

Measured in the same run:
- ``find_fleet`` of ``/imu/data: linear_acceleration.z > 2.0`` (about 2% of the messages, in
  short runs) over the 40 bags of bench_fleet, in one process: against a Python loop over
  rosbags' reader and deserializer computing the same episodes (target at least 10x). The
  peer runs over PEER_BAGS of the bags (identical hard links) and is scaled to 40: its time per
  bag does not depend on the others; its episodes are checked equal to bagkit's on those bags;
- the same on 2 local workers against one process pinned to one core (target at least 1.7x,
  as bench_fleet measures; the cluster started before the timings);
- ``find_fleet`` of ``/imu/data: gap > 100ms`` over the same 40 bags, one process, against a
  rosbags loop over every message's log time (no deserialization needed) computing the same
  silences (target at least 10x), scaled from PEER_BAGS bags like the first;
- ``bagkit echo BAG /imu/data --where 'linear_acceleration.z > 2.326'`` (1% of the messages)
  on the 1M-Imu bag of bench_stats: seconds from the start of the process to the first line
  on stdout (target at most 0.5 s).

Run: ``.venv/bin/python -m benchmarks find``
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

from benchmarks.bench_fleet import BAGS, imu_fleet
from benchmarks.bench_stats import LARGE, TOPIC, imu_bag

WHEN = f"{TOPIC}: linear_acceleration.z > 2.0"
GAP_WHEN = f"{TOPIC}: gap > 100ms"
SILENCE_NS = 100_000_000
GAP_NS = 50_000_000
PEER_BAGS = 2
RUNS = 3
PEER_TARGET = 10.0
WORKERS_TARGET = 1.7
FIRST_MATCH_CEILING_S = 0.5


def _rosbags_episodes(bag: Path) -> list[tuple[int, int, int]]:
    """The peer: every message read and deserialized by rosbags, episodes in a Python loop."""
    from rosbags.highlevel import AnyReader

    episodes: list[list[int]] = []
    last_hit = False
    with AnyReader([bag]) as reader:
        connections = [c for c in reader.connections if c.topic == TOPIC]
        for connection, log_time, raw in reader.messages(connections=connections):
            msg: Any = reader.deserialize(raw, connection.msgtype)
            hit = msg.linear_acceleration.z > 2.0
            if hit and episodes and (last_hit or log_time - episodes[-1][1] < GAP_NS):
                episodes[-1][1], episodes[-1][2] = log_time, episodes[-1][2] + 1
            elif hit:
                episodes.append([log_time, log_time, 1])
            last_hit = hit
    return [(a, b, c) for a, b, c in episodes]


def _rosbags_gaps(bag: Path) -> list[tuple[int, int]]:
    """The peer of ``gap > 100ms``: each message's log time from rosbags' reader, silences
    (and the one after the last message, to the bag's end) in a Python loop."""
    from rosbags.highlevel import AnyReader

    silences: list[tuple[int, int]] = []
    last = None
    with AnyReader([bag]) as reader:
        connections = [c for c in reader.connections if c.topic == TOPIC]
        for _, log_time, _ in reader.messages(connections=connections):
            if last is not None and log_time - last > SILENCE_NS:
                silences.append((last, log_time))
            last = log_time
        end = reader.end_time - 1  # rosbags' end is one past the last message
    if last is not None and end - last > SILENCE_NS:
        silences.append((last, end))
    return silences


def _best(func: object, runs: int = RUNS) -> float:
    best = float("inf")
    for _ in range(runs):
        start = time.perf_counter()
        func()  # type: ignore[operator]
        best = min(best, time.perf_counter() - start)
    return best


def _first_line_s(bag: Path) -> float:
    bagkit = str(Path(sys.executable).with_name("bagkit"))
    condition = "linear_acceleration.z > 2.326"
    start = time.perf_counter()
    with subprocess.Popen(
        [bagkit, "echo", str(bag), TOPIC, "--where", condition, "--format", "json"],
        stdout=subprocess.PIPE,
        text=True,
    ) as proc:
        assert proc.stdout is not None
        proc.stdout.readline()
        seconds = time.perf_counter() - start
        proc.kill()
    return seconds


def main() -> bool:
    from distributed import Client

    from bagkit.fleet import local_cluster
    from bagkit.fleet.find import find_fleet

    bags = imu_fleet()
    found = find_fleet(bags[:PEER_BAGS], when=WHEN, gap_ns=GAP_NS)
    mine = [(e.start_ns, e.end_ns, e.count) for e in found.episodes]
    peer = [ep for bag in bags[:PEER_BAGS] for ep in _rosbags_episodes(bag)]
    assert mine == peer, "bagkit and the rosbags loop disagree"
    print(f"{len(found.episodes) // PEER_BAGS} episodes per bag; equal to the rosbags loop")

    peer_s = _best(lambda: [_rosbags_episodes(b) for b in bags[:PEER_BAGS]], 1) * BAGS / PEER_BAGS
    one_s = _best(lambda: find_fleet(bags, when=WHEN, gap_ns=GAP_NS))
    ratio = peer_s / one_s
    print(
        f"find, {BAGS} x 100k Imu, one process: {one_s:.2f} s; rosbags loop (scaled from "
        f"{PEER_BAGS} bags): {peer_s:.1f} s: {ratio:.1f}x (target >= {PEER_TARGET:g}x)"
    )

    gaps = find_fleet(bags[:PEER_BAGS], when=GAP_WHEN)
    peer_gaps = [gap for bag in bags[:PEER_BAGS] for gap in _rosbags_gaps(bag)]
    assert [(e.start_ns, e.end_ns) for e in gaps.episodes] == peer_gaps, "gaps disagree"
    gap_peer_s = _best(lambda: [_rosbags_gaps(b) for b in bags[:PEER_BAGS]], 1)
    gap_peer_s *= BAGS / PEER_BAGS
    gap_s = _best(lambda: find_fleet(bags, when=GAP_WHEN))
    gap_ratio = gap_peer_s / gap_s
    print(
        f"find {GAP_WHEN!r}, {BAGS} bags, one process: {gap_s:.3f} s ({gaps.count} silences in "
        f"{PEER_BAGS} bags, equal to the peer's); rosbags loop (scaled): {gap_peer_s:.1f} s: "
        f"{gap_ratio:.1f}x (target >= {PEER_TARGET:g}x)"
    )

    started = time.perf_counter()
    cluster = local_cluster(2)
    print(f"cluster of 2 workers started in {time.perf_counter() - started:.1f} s")
    try:
        with Client(cluster) as client:
            pinned: list[float] = []
            spread: list[float] = []
            for _ in range(RUNS):  # interleaved: the machine's load moves
                os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})
                try:
                    pinned.append(_best(lambda: find_fleet(bags, when=WHEN, gap_ns=GAP_NS), 1))
                finally:
                    os.sched_setaffinity(0, range(os.cpu_count() or 1))
                spread.append(
                    _best(lambda: find_fleet(bags, when=WHEN, gap_ns=GAP_NS, client=client), 1)
                )
    finally:
        cluster.close()
    workers = min(pinned) / min(spread)
    print(
        f"find on 2 workers: {min(spread):.2f} s against {min(pinned):.2f} s on one core: "
        f"{workers:.2f}x (target >= {WORKERS_TARGET:g}x)"
    )

    first = min(_first_line_s(imu_bag(LARGE)) for _ in range(RUNS))
    print(
        f"echo --where, 1M Imu, 1% matching: first line after {first:.3f} s "
        f"(target <= {FIRST_MATCH_CEILING_S:g} s)"
    )
    return (
        ratio >= PEER_TARGET
        and gap_ratio >= PEER_TARGET
        and workers >= WORKERS_TARGET
        and first <= FIRST_MATCH_CEILING_S
    )
