"""When ``Recorder.run`` stops a recording: told to (an event, or a function that says when),
at the options' duration or message count, or when the recording ended by itself (a full disk).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Protocol

from bagkit.recording.report import RecordProgress
from bagkit.selection.times import NS_PER_S

if TYPE_CHECKING:
    from bagkit.recording.options import RecordOptions

# How often run() looks at its stop conditions before the topics are subscribed (the duration
# counts from there), and at most between two looks afterwards.
POLL_STARTING_S = 0.05
POLL_S = 0.5
# What run() may be told to stop by: an event to set, or a function that says when.
StopWhen = threading.Event | Callable[[], bool]


class Subscribed(Protocol):
    """When the recording's topics were all subscribed (``bagkit.ros.record.subscriptions``)."""

    complete: threading.Event
    """Set once every selected topic is subscribed."""
    complete_at: float
    """The monotonic time it was set."""


def wait_until_done(
    options: RecordOptions,
    subscriptions: Subscribed,
    stopped: threading.Event,
    progress: Callable[[], RecordProgress],
    *,
    stop: StopWhen | None,
    on_progress: Callable[[RecordProgress], None] | None,
    progress_period_s: float,
) -> None:
    """Return when told to stop, at a limit of the options, or when the bag is finished.

    Args:
        options: the recording's (its duration and message count).
        subscriptions: the recording's (the duration counts from their completion).
        stopped: set when the bag is finished.
        progress: the counts so far.
        stop, on_progress, progress_period_s: as ``Recorder.run`` takes them.
    """
    should_stop = _should_stop(stop)
    next_progress = 0.0
    while not stopped.is_set():
        now = time.monotonic()
        if on_progress is not None and now >= next_progress:
            on_progress(progress())
            next_progress = now + progress_period_s
        subscribed = subscriptions.complete.is_set()
        wait = min(POLL_S, progress_period_s) if subscribed else POLL_STARTING_S
        if options.duration_ns is not None and subscribed:
            remaining = subscriptions.complete_at + options.duration_ns / NS_PER_S - now
            if remaining <= 0:
                return
            wait = min(wait, remaining)
        if options.max_messages is not None:
            if progress().messages >= options.max_messages:
                return
            wait = POLL_STARTING_S
        if should_stop(wait):
            return


def _never() -> bool:
    return False


def _should_stop(stop: StopWhen | None) -> Callable[[float], bool]:
    """``stop`` as ``wait(seconds)``: wait up to that long, return whether to stop."""
    if isinstance(stop, threading.Event):
        return stop.wait
    condition = stop if stop is not None else _never

    def wait(seconds: float) -> bool:
        if condition():
            return True
        time.sleep(seconds)
        return condition()

    return wait
