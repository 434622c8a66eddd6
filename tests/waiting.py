"""Waiting in tests that talk to other processes or DDS: poll until true, fail with a reason."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import psutil


def wait_for(
    condition: Callable[[], bool], timeout: float = 10.0, *, what: str = "the condition"
) -> None:
    """Poll ``condition`` every 10 ms; fail the test if it is not true within ``timeout`` s."""
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, f"timed out after {timeout} s waiting for {what}"
        time.sleep(0.01)


def running(pid: int) -> bool:
    """Whether ``pid`` runs (a zombie not yet reaped has stopped)."""
    try:
        return psutil.Process(pid).status() != psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return False


def wait_matched(*publishers: Any, count: int = 1, timeout: float = 10.0) -> None:
    """Wait until each of ``publishers`` has matched ``count`` subscriptions."""
    wait_for(
        lambda: all(p.get_subscription_count() >= count for p in publishers),
        timeout,
        what=f"{count} subscription(s) on {', '.join(p.topic_name for p in publishers)}",
    )
