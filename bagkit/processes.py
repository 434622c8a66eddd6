"""Subprocesses supervised as a group: each in its own session, stopped in steps, always reaped.

Every process starts in a new session (its own process group), so a terminal's Ctrl-C reaches
only the supervisor and a stop reaches the process and all its children. ``stop_all`` sends
SIGINT to every group, SIGTERM to those still running after ``StopPolicy.interrupt_s``, SIGKILL
after ``terminate_s`` more, then reaps them, joins their output readers and closes their logs.
Standard library only: the CLI, fusion's launcher, the live regression harness and the tests
use it alike::

    with Supervisor() as group:
        group.start(Command("record", ["bagkit", "record", "-a", "-o", "out"], log=log_path))
        group.wait_ready(lambda: Path("out").exists(), timeout=30.0, what="the bag")
"""

from __future__ import annotations

import contextlib
import functools
import os
import signal
import subprocess
import threading
import time
from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import TracebackType
from typing import IO, Any

from bagkit.errors import BagkitError
from bagkit.own_environment import for_programs

__all__ = ["Command", "ProcessError", "StopPolicy", "Supervised", "Supervisor"]

LOG_TAIL_LINES = 15
POLL_S = 0.05

Stream = int | IO[Any] | None
"""What ``subprocess.Popen`` takes for stdin/stdout/stderr (``subprocess.PIPE``, a file...)."""


class ProcessError(BagkitError):
    """A supervised process could not be started, exited early or did not become ready."""

    exit_code = 1


@dataclass(frozen=True, slots=True)
class StopPolicy:
    """How long a process may take to stop after each signal before the next, harder one."""

    interrupt_s: float = 10.0
    terminate_s: float = 5.0


@dataclass(frozen=True, slots=True)
class Command:
    """A program to start, and where its input and output go.

    ``log``: stdout and stderr into this file; else ``on_line``: each line of stdout and
    stderr (decoded, without its newline) to this callable, from a reader thread; else
    ``stdout``/``stderr`` as ``subprocess.Popen`` takes them (None: this process's).
    ``env`` None: this process's environment. ``preexec``: run in the child before it execs
    (limits, ``resource.setrlimit``).
    """

    name: str
    args: Sequence[str]
    env: Mapping[str, str] | None = None
    cwd: Path | None = None
    log: Path | None = None
    on_line: Callable[[str], None] | None = None
    stdin: Stream = subprocess.DEVNULL
    stdout: Stream = None
    stderr: Stream = None
    text: bool = False
    preexec: Callable[[], None] | None = None


@dataclass(slots=True)
class Supervised:
    """A started process, its output reader and log file."""

    command: Command
    process: subprocess.Popen[Any]
    reader: threading.Thread | None = None
    log: IO[bytes] | None = field(default=None, repr=False)

    @property
    def name(self) -> str:
        """The command's name."""
        return self.command.name

    @property
    def returncode(self) -> int | None:
        """The exit code (negative: killed by that signal); None while it runs."""
        return self.process.poll()


class Supervisor:
    """Processes started in their own sessions, stopped together (``with`` stops them too)."""

    def __init__(self, policy: StopPolicy | None = None) -> None:
        self.policy = policy or StopPolicy()
        self.started: list[Supervised] = []

    def __enter__(self) -> Supervisor:
        return self

    def __exit__(
        self, kind: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.stop_all()

    def start(self, command: Command) -> Supervised:
        """Start ``command`` in a new session.

        Raises:
            ProcessError: the program cannot be started (not found, not executable).
        """
        log = command.log.open("wb") if command.log is not None else None
        merged = log is not None or command.on_line is not None
        try:
            process = subprocess.Popen(
                list(command.args),
                stdin=command.stdin,
                stdout=log or (subprocess.PIPE if merged else command.stdout),
                stderr=subprocess.STDOUT if merged else command.stderr,
                env=for_programs(os.environ if command.env is None else command.env),
                cwd=command.cwd,
                text=command.text and not merged,
                start_new_session=True,
                preexec_fn=functools.partial(_in_child, command.preexec),  # noqa: PLW1509 (no locks)
            )
        except OSError as exc:
            if log is not None:
                log.close()
            raise ProcessError(
                f"cannot start {command.name} ({command.args[0]}): {exc.strerror}"
            ) from exc
        one = Supervised(command, process, log=log)
        if command.log is None and command.on_line is not None:
            one.reader = threading.Thread(
                target=_copy_lines, args=(process.stdout, command.on_line), daemon=True
            )
            one.reader.start()
        self.started.append(one)
        return one

    def exited(self, ignore: Collection[str] = ()) -> Supervised | None:
        """The first process (by name not in ``ignore``) that has exited, or None."""
        return next(
            (p for p in self.started if p.name not in ignore and p.returncode is not None), None
        )

    def check_running(self, ignore: Collection[str] = ()) -> None:
        """Raise if a process (not in ``ignore``) has exited.

        Raises:
            ProcessError: naming the process, its exit code and the end of its log.
        """
        gone = self.exited(ignore)
        if gone is not None:
            tail = f"; the end of its log:\n{self.log_tail(gone)}" if gone.command.log else ""
            raise ProcessError(f"{gone.name} exited early with code {gone.returncode}{tail}")

    def wait_ready(
        self, ready: Callable[[], bool], timeout: float, *, what: str = "the processes"
    ) -> None:
        """Poll ``ready`` until it holds, while every process runs.

        Raises:
            ProcessError: a process exited first, or ``ready`` did not hold within ``timeout``.
        """
        deadline = time.monotonic() + timeout
        while not ready():
            self.check_running()
            if time.monotonic() >= deadline:
                raise ProcessError(f"{what} not ready after {timeout:g} s")
            time.sleep(POLL_S)

    def wait_any(self, stop: threading.Event) -> Supervised | None:
        """Block until a process exits (return it) or ``stop`` is set (return None)."""
        while not stop.wait(POLL_S):
            gone = self.exited()
            if gone is not None:
                return gone
        return None

    def stop(self, one: Supervised) -> int:
        """Stop ``one`` (SIGINT, SIGTERM, SIGKILL), reap it; return its exit code."""
        self._stop([one])
        code = one.returncode
        assert code is not None  # reaped by _stop
        return code

    def stop_all(self) -> None:
        """Stop every process at once, then reap them; exit codes in ``started``."""
        self._stop(self.started)

    def kill_all(self) -> None:
        """SIGKILL every running process now (a second Ctrl-C: nobody waits)."""
        for one in self.started:
            if one.process.poll() is None:
                _signal_group(one.process, signal.SIGKILL)

    def log_tail(self, one: Supervised, lines: int = LOG_TAIL_LINES) -> str:
        """The end of ``one``'s log file, for error messages ("(empty)" without)."""
        if one.command.log is None:
            return "(empty)"
        text = one.command.log.read_text(errors="replace")
        return "\n".join(text.splitlines()[-lines:]) or "(empty)"

    def _stop(self, group: Sequence[Supervised]) -> None:
        steps = (
            (signal.SIGINT, self.policy.interrupt_s),
            (signal.SIGTERM, self.policy.terminate_s),
            (signal.SIGKILL, None),
        )
        for signum, grace_s in steps:
            running = [p for p in group if p.process.poll() is None]
            for one in running:
                _signal_group(one.process, signum)
            deadline = None if grace_s is None else time.monotonic() + grace_s
            for one in running:
                left = None if deadline is None else max(0.0, deadline - time.monotonic())
                with contextlib.suppress(subprocess.TimeoutExpired):
                    one.process.wait(timeout=left)
        for one in group:
            if one.reader is not None:
                one.reader.join(timeout=1.0)
            if one.log is not None:
                one.log.close()


def _in_child(preexec: Callable[[], None] | None) -> None:
    """Run in the child before it execs: SIGINT back to its default, then ``preexec``.

    An ignored signal stays ignored across exec. A supervisor started with SIGINT ignored (a
    shell script's ``bagkit ... &``: bash ignores SIGINT in background jobs) would pass that on,
    and its children would ignore the SIGINT that stops them cleanly. In their own session, no
    terminal's Ctrl-C reaches them: only the supervisor's.
    """
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    if preexec is not None:
        preexec()


def _signal_group(process: subprocess.Popen[Any], signum: int) -> None:
    # ProcessLookupError: the group is gone already, nothing left to stop.
    with contextlib.suppress(ProcessLookupError):
        os.killpg(process.pid, signum)


def _copy_lines(stream: IO[bytes], on_line: Callable[[str], None]) -> None:
    with stream:
        for raw in stream:
            on_line(raw.decode(errors="replace").rstrip("\n"))
