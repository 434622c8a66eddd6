"""The process tuning a recording or a replay gets: Fast DDS queues, malloc, timers (glibc).

Three settings, each with its own scope:

- the Fast DDS shared-memory profile (:func:`bagkit.ros.fastdds.large_receive_queue`): read
  when a participant is created, so it must be in effect around the node's creation;
- malloc thresholds (:func:`keep_freed_memory`): process-wide, for good;
- timer slack (:func:`precise_timers`): the calling thread's, for the block.

:func:`process_tuning` applies the first two; ``Recorder.start`` and ``Player.open`` open it
around their node's creation, and the player's publishing loop runs under
:func:`precise_timers`. So the CLI, the regression harness, the benchmarks and a Python user of
``Recorder(options).run()`` or ``Player(options).run()`` get the same run; ``tune_process=False``
in the options leaves the host process alone. No rclpy import (ctypes only).
"""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
from collections.abc import Iterator, MutableMapping
from typing import Any

from bagkit.ros.fastdds import large_receive_queue

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
    them on free, so every 1 MB image costs 256 page faults per copy (measured here: copying
    1 MB 0.8 ms -> 0.08 ms, writing it 2.7 ms -> 0.8 ms). Process-wide and for good. No-op
    without glibc.
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


@contextlib.contextmanager
def process_tuning(
    enabled: bool = True,
    environ: MutableMapping[str, str] | None = None,
    *,
    segment_size: int | None = None,
) -> Iterator[bool]:
    """Tune the process for a recording or a replay; open it around the node's creation.

    Keeps freed memory (:func:`keep_freed_memory`) and gives the participants created in the
    block a large shared-memory queue (:func:`~bagkit.ros.fastdds.large_receive_queue`, unless
    the user has a Fast DDS setting of their own).

    Args:
        enabled: False: change nothing (``tune_process=False`` in the options).
        environ: the environment to change (default: ``os.environ``).
        segment_size: the shared-memory segment a sender needs (the player's, for the bag's
            largest messages); None: Fast DDS's default.

    Yields:
        Whether the Fast DDS profile is in effect.
    """
    if not enabled:
        yield False
        return
    keep_freed_memory()
    with large_receive_queue(environ, segment_size=segment_size) as profile:
        yield profile
