"""glibc calls through ctypes: thread names, malloc thresholds, timer slack (no rclpy).

Each is a no-op where there is no glibc. :func:`bagkit.ros.tuning.process_tuning` applies the
process-wide ones around a node's creation; the recorder's and the player's threads name
themselves and set their own timer slack.
"""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
from collections.abc import Iterator
from typing import Any

# mallopt parameters (glibc malloc.h) and the largest mmap threshold glibc accepts on 64 bits.
_M_TRIM_THRESHOLD = -1
_M_MMAP_THRESHOLD = -3
_MMAP_THRESHOLD_MAX = 32 << 20
# prctl(2) options (linux/prctl.h): the thread's name, its timer slack in ns.
_PR_SET_NAME = 15
_PR_SET_TIMERSLACK = 29
_PR_GET_TIMERSLACK = 30


def _libc_function(name: str) -> Any:
    """A C library function through ctypes, or None where there is no such library or function."""
    try:
        return getattr(ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6"), name)
    except (OSError, AttributeError):
        return None


def name_native_thread(name: str) -> None:
    """Give the calling thread ``name`` (15 bytes at most) in ``top -H``, ``ps -L`` and /proc.

    Python 3.11 names only its own thread objects; without this every thread of the recorder
    shows up as ``python`` beside the middleware's named ones. No-op without glibc.
    """
    prctl = _libc_function("prctl")
    if prctl is not None:
        prctl(_PR_SET_NAME, name.encode()[:15], 0, 0, 0)


def keep_freed_memory() -> None:
    """Let glibc keep freed large buffers for reuse instead of returning them to the kernel.

    Each large message taken is a fresh allocation; glibc serves those with ``mmap`` and unmaps
    them on free, so every 1 MB image costs 256 page faults per copy (benchmarks/README.md,
    "Measurements behind the code"). Process-wide and for good. No-op without glibc.
    """
    mallopt = _libc_function("mallopt")
    if mallopt is None:
        return
    mallopt(_M_MMAP_THRESHOLD, _MMAP_THRESHOLD_MAX)
    mallopt(_M_TRIM_THRESHOLD, 4 * _MMAP_THRESHOLD_MAX)


@contextlib.contextmanager
def precise_timers() -> Iterator[None]:
    """Have the calling thread's sleeps end on time, not up to 50 us late (Linux timer slack).

    With the slack at its minimum, a sleep wakes within a few microseconds of its deadline on an
    idle machine, so the replay's spin window can stay short. The thread's previous slack comes
    back when the block ends. A no-op where prctl is unavailable.
    """
    prctl = _libc_function("prctl")
    previous = prctl(_PR_GET_TIMERSLACK, 0, 0, 0, 0) if prctl is not None else -1
    if previous > 0:
        prctl(_PR_SET_TIMERSLACK, 1, 0, 0, 0)
    try:
        yield
    finally:
        if previous > 0:
            prctl(_PR_SET_TIMERSLACK, previous, 0, 0, 0)
