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
