"""The participant census's liveness check: a Fast DDS participant of an exited process."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from bagkit.ros.participants import _process_may_live

FAST_DDS_PREFIX = bytes([1, 15, 0x78, 0xFD])


def _gid(pid: int, vendor_prefix: bytes = FAST_DDS_PREFIX) -> bytes:
    """A 16-byte endpoint gid as Fast DDS makes it for a participant of process ``pid``."""
    return vendor_prefix + (pid & 0xFFFF).to_bytes(2, "little") + bytes(10)


def test_a_participant_of_a_live_process_counts() -> None:
    assert _process_may_live(_gid(os.getpid()))


def test_a_participant_of_an_exited_process_does_not() -> None:
    done = subprocess.run(
        [sys.executable, "-c", "import os; print(os.getpid())"],
        check=True,
        capture_output=True,
        text=True,
    )
    pid = int(done.stdout)
    same_bits = [p for p in os.listdir("/proc") if p.isdigit() and int(p) & 0xFFFF == pid & 0xFFFF]
    if same_bits:
        pytest.skip(f"process {same_bits[0]} has the exited pid's low 16 bits")
    assert not _process_may_live(_gid(pid))


def test_another_vendor_always_counts() -> None:
    # RTI's vendor id: its prefix does not hold a process id that we know of.
    assert _process_may_live(_gid(pid=0xFFFE, vendor_prefix=bytes([1, 1, 0, 0])))
