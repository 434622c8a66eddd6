"""Replay controls without rclpy: pause, resume, step and rate, and the timeline they re-anchor.

The keyboard thread, the service callbacks and a SIGTSTP handler call the methods of
:class:`PlayControls`; the publishing loop reads :attr:`PlayControls.timeline` before each
message and waits on the controls (not on a plain sleep) so that a change wakes it. Every change
re-anchors the timeline at the bag time reached at that moment, so playback continues from
there with the bag's spacing: nothing overdue is published in a burst after a pause.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

from bagkit.playback.timing import Timeline

# Up and down arrows change the rate by this much, as `ros2 bag play` (Jazzy) does.
RATE_STEP = 0.1
# How long a step request waits for the publishing loop to take it (a burst: for each message).
STEP_TIMEOUT_S = 2.0
# A burst of 0 messages publishes the rest of the pass: as many steps as a pass can have.
BURST_REST = 2**62


class PlayControls:
    """Paused state, rate and single steps of one replay, shared between threads.

    Args:
        rate: initial playback speed factor (> 0).
        paused: start paused (``--start-paused``).
    """

    def __init__(self, rate: float = 1.0, *, paused: bool = False) -> None:
        if not rate > 0:
            raise ValueError(f"rate must be positive, got {rate}")
        # Reentrant: a SIGTSTP handler runs on the main thread, possibly inside a method.
        self._changed = threading.Condition(threading.RLock())
        self.rate = rate
        self.paused = paused
        self.timeline = Timeline(0, 0, rate)
        self.generation = 0
        """Incremented by every change; the publishing loop waits for it to move."""
        self._frozen_bag_ns = 0  # bag time reached when paused
        self._cued_ns: int | None = None  # where the first pass will start, until it does
        self._suspended = False
        # Wall time held (paused or suspended): the closing report's time paused, apart from
        # the time played.
        self._held_ns = 0
        self._held_since: int | None = _now(None) if paused else None
        self._steps_requested = 0
        self._steps_taken = 0
        self._passes_ended = 0
        self.seek_to: int | None = None
        """Bag time a seek asked for, until the publishing loop takes it."""
        self.stopped = False
        """Set by :meth:`stop`: the publishing loop ends the replay."""
        self.on_rate_change: Callable[[float], None] | None = None
        """Called (outside the lock) with the new rate after each change."""

    def cue(self, bag_ns: int) -> None:
        """Before the first pass (while the player waits for subscribers): stand at ``bag_ns``.

        A seek key pressed during that wait then steps from where the replay will start, not
        from bag time 0.
        """
        with self._changed:
            self._cued_ns = bag_ns

    def start(self, bag_start_ns: int, wall_ns: int) -> None:
        """Anchor a new pass: bag time ``bag_start_ns`` is due at ``wall_ns`` (if not paused)."""
        with self._changed:
            self._cued_ns = None
            self.timeline = Timeline(bag_start_ns, wall_ns, self.rate)
            self._frozen_bag_ns = bag_start_ns
            self._notify()

    @property
    def holding(self) -> bool:
        """Whether no message may be published on schedule (paused by a user or suspended)."""
        return self.paused or self._suspended

    @property
    def interrupting(self) -> bool:
        """Whether the publishing loop must leave its wait: a seek to take, or a stop."""
        return self.seek_to is not None or self.stopped

    def held_ns(self, now_ns: int | None = None) -> int:
        """Wall time spent held (paused by a user or suspended) since the controls were made,
        up to ``now_ns``; the player takes the difference over its passes."""
        with self._changed:
            since = self._held_since
            return self._held_ns + (0 if since is None else _now(now_ns) - since)

    def position(self, now_ns: int | None = None) -> int:
        """The bag time reached (frozen while held; a pending seek's target)."""
        with self._changed:
            if self.seek_to is not None:
                return self.seek_to
            if self._cued_ns is not None:
                return self._cued_ns
            if self.holding:
                return self._frozen_bag_ns
            return self.timeline.bag_time(_now(now_ns))

    def seek(self, bag_ns: int, now_ns: int | None = None) -> None:
        """Continue from bag time ``bag_ns`` (the caller clamps it to the window).

        The timeline is re-anchored there at once, paused or not, so the jump is never counted
        as lateness; the publishing loop takes the seek (:meth:`take_seek`) between messages.
        """
        with self._changed:
            self.seek_to = bag_ns
            self._frozen_bag_ns = bag_ns
            self.timeline = Timeline(bag_ns, _now(now_ns), self.rate)
            self._notify()

    def take_seek(self) -> int | None:
        """For the publishing loop: the bag time to continue from, if a seek is pending."""
        with self._changed:
            target, self.seek_to = self.seek_to, None
            return target

    def stop(self) -> None:
        """End the replay after the message being published (``~/stop``)."""
        with self._changed:
            self.stopped = True
            self._notify()

    def end_pass(self) -> None:
        """For the player: a pass ended; steps not taken yet are forgotten."""
        with self._changed:
            self._steps_requested = self._steps_taken
            self._passes_ended += 1
            self._notify()

    def pause(self, now_ns: int | None = None) -> bool:
        """Pause; return False if already paused."""
        with self._changed:
            if self.paused:
                return False
            self._freeze(now_ns)
            if not self._suspended:
                self._hold(now_ns)
            self.paused = True
            self._notify()
            return True

    def resume(self, now_ns: int | None = None) -> bool:
        """Resume from the bag time reached when paused; return False if not paused."""
        with self._changed:
            if not self.paused:
                return False
            self.paused = False
            if not self._suspended:
                self._release(now_ns)
            self._thaw(now_ns)
            self._notify()
            return True

    def toggle_paused(self, now_ns: int | None = None) -> bool:
        """Pause if playing, resume if paused; return whether it is paused now."""
        with self._changed:
            if not self.resume(now_ns):
                self.pause(now_ns)
            return self.paused

    def set_rate(self, rate: float, now_ns: int | None = None) -> bool:
        """Change the rate from now on; return False (and change nothing) unless ``rate > 0``."""
        if not rate > 0:
            return False
        with self._changed:
            if rate == self.rate:
                return True
            if not self.holding:
                now = _now(now_ns)
                self.timeline = Timeline(self.timeline.bag_time(now), now, rate)
            self.rate = rate
            self._notify()
        if self.on_rate_change is not None:
            self.on_rate_change(rate)
        return True

    def change_rate(self, step: float) -> bool:
        """Add ``step`` to the rate (the up and down arrows); False if the result is not > 0."""
        return self.set_rate(round(self.rate + step, 9))

    def suspend(self, now_ns: int | None = None) -> None:
        """The process is about to stop (SIGTSTP): hold playback without changing ``paused``."""
        with self._changed:
            if not self.holding:
                self._freeze(now_ns)
                self._hold(now_ns)
            self._suspended = True

    def unsuspend(self, now_ns: int | None = None) -> None:
        """The process continues (after SIGCONT): re-anchor at the bag time it stopped at."""
        with self._changed:
            self._suspended = False
            if not self.paused:
                self._release(now_ns)
                self._thaw(now_ns)
            self._notify()

    def play_next(self, timeout_s: float = STEP_TIMEOUT_S) -> bool:
        """While paused, have the next message published; True once the loop has published it."""
        return self.burst(1, timeout_s) == 1

    def burst(self, count: int, timeout_s: float = STEP_TIMEOUT_S) -> int:
        """While paused, publish the next ``count`` messages at once (0: the rest of the pass).

        Returns:
            How many were published: fewer when the pass ended, the replay stopped, or the
            loop took none for ``timeout_s``; 0 unless paused.
        """
        with self._changed:
            if not self.paused or count < 0:
                return 0
            first = self._steps_taken
            wanted = self._steps_requested = first + (count or BURST_REST)
            passes = self._passes_ended
            self._notify()
            while self._steps_taken < wanted and passes == self._passes_ended:
                if not self._wait_for_a_step(self._steps_taken, passes, timeout_s):
                    break
            taken = self._steps_taken - first
            self._steps_requested = self._steps_taken  # forget what was not taken
            return min(taken, wanted - first)

    def _wait_for_a_step(self, taken: int, passes: int, timeout_s: float) -> bool:
        """Wait (lock held) for the loop to take a step; False on a timeout, a pass end, a stop."""
        self._changed.wait_for(
            lambda: self._steps_taken != taken or passes != self._passes_ended or self.stopped,
            timeout_s,
        )
        return self._steps_taken != taken and not self.stopped

    def take_step(self, log_time_ns: int) -> bool:
        """For the publishing loop: whether a step was requested; if so, it is taken now.

        The paused bag time moves to the stepped message, so resuming continues after it.
        """
        with self._changed:
            if not self.paused or self._steps_taken >= self._steps_requested:
                return False
            self._steps_taken += 1
            self._frozen_bag_ns = log_time_ns
            self._notify()
            return True

    def wait_for_change(self, generation: int, timeout_s: float | None = None) -> None:
        """Block until a change after ``generation``, or ``timeout_s`` seconds have passed."""
        with self._changed:
            self._changed.wait_for(lambda: self.generation != generation, timeout_s)

    def _freeze(self, now_ns: int | None) -> None:
        self._frozen_bag_ns = max(self._frozen_bag_ns, self.timeline.bag_time(_now(now_ns)))

    def _hold(self, now_ns: int | None) -> None:
        """Playback was not held and is now: count held time from ``now_ns``."""
        self._held_since = _now(now_ns)

    def _release(self, now_ns: int | None) -> None:
        """Playback is held no more: add the time since it was held."""
        if self._held_since is not None:
            self._held_ns += _now(now_ns) - self._held_since
            self._held_since = None

    def _thaw(self, now_ns: int | None) -> None:
        self.timeline = Timeline(self._frozen_bag_ns, _now(now_ns), self.rate)

    def _notify(self) -> None:
        self.generation += 1
        self._changed.notify_all()


def _now(now_ns: int | None) -> int:
    return time.monotonic_ns() if now_ns is None else now_ns
