"""The process tuning of a run: timer slack for the block, the Fast DDS profile only when asked."""

from __future__ import annotations

import ctypes
from pathlib import Path

import pytest

from bagkit.native import precise_timers
from bagkit.ros.fastdds import PROFILES_FILE_VARIABLE
from bagkit.ros.tuning import process_tuning

_PR_GET_TIMERSLACK = 30


def timer_slack_ns() -> int:
    return int(ctypes.CDLL(None).prctl(_PR_GET_TIMERSLACK, 0, 0, 0, 0))


def test_precise_timers_lower_the_slack_for_the_block_only() -> None:
    before = timer_slack_ns()
    assert before > 1  # Linux's default is 50 us
    with precise_timers():
        assert timer_slack_ns() == 1
    assert timer_slack_ns() == before


def test_process_tuning_gives_the_block_a_profile_unless_disabled(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    monkeypatch.chdir(tmp_path)  # no profile file of the user's in the working directory
    environ = {"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    with process_tuning(False, environ) as applied:
        assert not applied and PROFILES_FILE_VARIABLE not in environ
    with process_tuning(True, environ) as applied:
        assert applied
        profile = Path(environ[PROFILES_FILE_VARIABLE])
        assert "<port_queue_capacity>65536</port_queue_capacity>" in profile.read_text()
    assert PROFILES_FILE_VARIABLE not in environ and not profile.exists()
