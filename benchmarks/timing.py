"""Timing shared by the benchmarks: the best of several runs, on a machine others share."""

from __future__ import annotations

import time
from collections.abc import Callable


def best_of(runs: int, func: Callable[[], object]) -> float:
    """The fastest of ``runs`` calls of ``func``, in seconds (a load spike only slows a run)."""
    best = float("inf")
    for _ in range(runs):
        start = time.perf_counter()
        func()
        best = min(best, time.perf_counter() - start)
    return best


def best_of_with_cpu(runs: int, func: Callable[[], object]) -> tuple[float, float]:
    """The fastest of ``runs`` calls of ``func`` and the least CPU (all threads of this
    process) that one call took, in seconds: on a loaded machine the CPU says more."""
    wall = cpu = float("inf")
    for _ in range(runs):
        start, start_cpu = time.perf_counter(), time.process_time()
        func()
        wall = min(wall, time.perf_counter() - start)
        cpu = min(cpu, time.process_time() - start_cpu)
    return wall, cpu
