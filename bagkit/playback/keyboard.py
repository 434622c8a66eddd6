"""Keyboard controls of a replay in a terminal, and a replay that survives Ctrl-Z.

As ``ros2 bag play``: space pauses and resumes, the right arrow publishes the next message while
paused, the up and down arrows raise and lower the rate by 0.1. bagkit's own: the left arrow
(or ``,``/``<``) seeks back a step of bag time, ``.``/``>`` forward. The terminal is put in cbreak
mode without echo (Ctrl-C and Ctrl-Z still send their signals) and restored on exit, and around
a suspension: on SIGTSTP the player is held and the terminal restored before the process stops;
after ``fg`` the timeline re-anchors, so the messages that fell due while stopped are not
published in a burst.
"""

from __future__ import annotations

import os
import select
import signal
import sys
import termios
import threading
import tty
from collections.abc import Callable, Iterator
from contextlib import contextmanager, suppress
from types import FrameType

from bagkit.playback.controls import RATE_STEP, PlayControls

SPACE = b" "
RIGHT = b"\x1b[C"
UP = b"\x1b[A"
DOWN = b"\x1b[B"
LEFT = b"\x1b[D"
BACK_KEYS = (LEFT, b",", b"<")
FORWARD_KEYS = (b".", b">")
# How often the reader thread checks whether it should stop.
POLL_S = 0.2


def key_actions(
    controls: PlayControls, seek_step: Callable[[int], object] | None = None
) -> dict[bytes, Callable[[], object]]:
    """What each key does to ``controls``; ``seek_step(-1)`` / ``(+1)`` seeks a step back/on."""
    actions: dict[bytes, Callable[[], object]] = {
        SPACE: controls.toggle_paused,
        RIGHT: controls.play_next,
        UP: lambda: controls.change_rate(RATE_STEP),
        DOWN: lambda: controls.change_rate(-RATE_STEP),
    }
    if seek_step is not None:
        step = seek_step
        actions.update(dict.fromkeys(BACK_KEYS, lambda: step(-1)))
        actions.update(dict.fromkeys(FORWARD_KEYS, lambda: step(1)))
    return actions


def split_keys(data: bytes) -> list[bytes]:
    """Split bytes read from a terminal into keys: escape sequences of 3 bytes, else single ones."""
    keys = []
    index = 0
    while index < len(data):
        size = 3 if data[index : index + 2] == b"\x1b[" else 1
        keys.append(data[index : index + size])
        index += size
    return keys


@contextmanager
def terminal_controls(
    controls: PlayControls,
    *,
    keyboard: bool,
    seek_step: Callable[[int], object] | None = None,
) -> Iterator[None]:
    """Hold the replay across Ctrl-Z; with ``keyboard`` and a terminal on stdin, read its keys.

    ``seek_step(direction)`` is called with -1 or +1 by the seek keys.
    """
    fd = sys.stdin.fileno() if keyboard and sys.stdin.isatty() else None
    saved = termios.tcgetattr(fd) if fd is not None else None

    def enter_raw() -> None:
        if fd is not None:
            tty.setcbreak(fd, termios.TCSANOW)
            attributes = termios.tcgetattr(fd)
            attributes[3] &= ~termios.ECHO
            termios.tcsetattr(fd, termios.TCSANOW, attributes)

    def restore() -> None:
        if fd is not None and saved is not None:
            with suppress(termios.error):  # the terminal hung up: nothing to restore
                termios.tcsetattr(fd, termios.TCSANOW, saved)

    def on_stop(_signum: int, _frame: FrameType | None) -> None:
        controls.suspend()
        restore()
        # SIGSTOP, not SIGTSTP again: the kernel ignores SIGTSTP in an orphaned process group
        # (a replay started in a session of its own), which would leave the replay held.
        os.kill(os.getpid(), signal.SIGSTOP)  # stops here until SIGCONT
        enter_raw()
        controls.unsuspend()

    previous = signal.signal(signal.SIGTSTP, on_stop)
    stop = threading.Event()
    reader = None
    try:
        if fd is not None:
            enter_raw()
            reader = threading.Thread(
                target=_read_keys,
                args=(fd, key_actions(controls, seek_step), stop),
                daemon=True,
            )
            reader.start()
        yield
    finally:
        stop.set()
        if reader is not None:
            reader.join(timeout=2 * POLL_S)
        restore()
        signal.signal(signal.SIGTSTP, previous)


def _read_keys(fd: int, actions: dict[bytes, Callable[[], object]], stop: threading.Event) -> None:
    while not stop.is_set():
        ready, _, _ = select.select([fd], [], [], POLL_S)
        if not ready:
            continue
        try:
            data = os.read(fd, 64)
        except OSError:
            return  # the terminal went away
        for key in split_keys(data):
            action = actions.get(key)
            if action is not None:
                action()
