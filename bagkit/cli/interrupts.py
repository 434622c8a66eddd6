"""Ctrl-C during a command: remembered, and raised again, even where Python swallows it."""

from __future__ import annotations

import os
import signal
import sys
import threading
from typing import Any

# A Ctrl-C swallowed by a finalizer is raised again this long after (the finalizer is done).
REINTERRUPT_S = 0.05


class InterruptLatch:
    """Remembers a Ctrl-C even when its KeyboardInterrupt is swallowed on the way.

    Python ignores an exception raised in a gc callback or ``__del__`` (Dask's run there, and
    the gc runs them amid any loop): the command would then go on, a looping replay forever,
    and Python would print the ignored KeyboardInterrupt's traceback. The latch keeps that
    quiet, raises the interrupt again in the main thread, and remembers it for the exit code.
    """

    def __init__(self, *, take_ignored: bool = False) -> None:
        self.seen = False
        self._take_ignored = take_ignored
        self._previous: Any = None
        self._previous_unraisable: Any = None
        self._again: threading.Timer | None = None

    def __enter__(self) -> None:
        current = signal.getsignal(signal.SIGINT)
        # Only the default handler is wrapped (an ignored SIGINT stays ignored unless taken),
        # and signal handlers can only be set from the main thread.
        taken = current is signal.default_int_handler or (
            self._take_ignored and current == signal.SIG_IGN
        )
        if taken and threading.current_thread() is threading.main_thread():
            self._previous = current
            signal.signal(signal.SIGINT, self._on_sigint)
            self._previous_unraisable = sys.unraisablehook
            sys.unraisablehook = self._on_unraisable

    def __exit__(self, *_: object) -> None:
        if self._again is not None:
            self._again.cancel()
        if self._previous is not None:
            signal.signal(signal.SIGINT, self._previous)
            sys.unraisablehook = self._previous_unraisable

    def _on_sigint(self, signum: int, frame: Any) -> None:
        self.seen = True
        signal.default_int_handler(signum, frame)

    def _on_unraisable(self, unraisable: Any) -> None:
        if isinstance(unraisable.exc_value, KeyboardInterrupt):
            self.seen = True  # reported as "interrupted" when the command returns
            if self._again is None or not self._again.is_alive():
                # Raised again once the finalizer is left (here it would be swallowed again).
                self._again = threading.Timer(REINTERRUPT_S, os.kill, (os.getpid(), signal.SIGINT))
                self._again.daemon = True
                self._again.start()
        else:
            self._previous_unraisable(unraisable)
