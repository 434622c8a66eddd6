"""Run bagkit commands on fuzzed inputs and classify each run.

In-process: worker subprocesses (memory limited with RLIMIT_AS) call ``run_app`` exactly as the
``bagkit`` console script does, one task after another, and report exit code, stderr and peak
memory (VmHWM, reset before each task). A task that outlives its timeout kills its worker (a
hang); a worker that dies takes its task with it (a crash). A sample also runs as real
``bagkit`` subprocesses. Run as ``python runner.py --worker`` to be a worker.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import queue
import resource
import selectors
import subprocess
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path

MEMORY_LIMIT = 1536 << 20  # RLIMIT_AS of every run
MEMORY_BOMB = 1 << 30  # peak resident memory above this is a finding
CATEGORIES = ("clean", "traceback", "hang", "crash", "memory bomb")
BAGKIT = str(Path(sys.executable).with_name("bagkit"))
_ENV = {**os.environ, "COLUMNS": "160", "BAGKIT_TRACEBACK": ""}


@dataclass(frozen=True, slots=True)
class Task:
    key: str  # "<case id> <command>"
    argv: list[str]


@dataclass(frozen=True, slots=True)
class Outcome:
    key: str
    category: str
    exit_code: int | None
    last_line: str
    seconds: float
    peak_mib: float


def classify(
    exit_code: int | None, stderr: str, peak_bytes: int, *, timed_out: bool = False
) -> tuple[str, str]:
    """(category, the line that shows it) of one run.

    Clean: exit 0; exit 1 with at most one ``error:`` line; exit 2 ending with its one
    ``error:`` line; warnings allowed, never a traceback. An ``internal error`` line (exit 70)
    is an exception that escaped: a traceback.
    """
    lines = [line for line in stderr.splitlines() if line.strip()]
    last = lines[-1] if lines else ""
    errors = [line for line in lines if line.startswith("error:")]
    if timed_out:
        return "hang", last
    if exit_code is None or exit_code < 0:
        return "crash", f"signal {-exit_code if exit_code else '?'}; {last}"
    if peak_bytes > MEMORY_BOMB or "error: out of memory" in stderr:
        return "memory bomb", f"{peak_bytes / 2**20:.0f} MiB; {last}"
    if "Traceback (most recent call last)" in stderr or "internal error" in stderr:
        return "traceback", last
    # Exit 1 without an error line: a comparison that found differences (its report on stdout).
    if (
        exit_code == 0
        or (exit_code == 1 and len(errors) <= 1)
        or (exit_code == 2 and errors == lines[-1:])
    ):
        return "clean", last
    return "traceback", f"exit {exit_code}: {last}"


def _peak_bytes() -> int:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) * 1024
    return 0


def _limit_memory() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_LIMIT, MEMORY_LIMIT))


def worker_main() -> None:
    """Read tasks (JSON lines) on stdin, answer each with one JSON line on the original stdout."""
    _limit_memory()
    answers = os.fdopen(os.dup(1), "w")
    quiet = os.open(os.devnull, os.O_WRONLY)
    os.dup2(quiet, 1)  # what C code prints must not mix with the answers
    os.dup2(quiet, 2)
    from bagkit.cli.common import run_app
    from bagkit.cli.main import app

    for line in sys.stdin:
        task = json.loads(line)
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")  # reset VmHWM: the peak of this task alone
        out, err = io.StringIO(), io.StringIO()
        start = time.monotonic()
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                run_app(app, task["argv"])
            except SystemExit as exc:
                code = exc.code if isinstance(exc.code, int) else 1
            except BaseException as exc:  # escaped run_app: reported, not raised
                err.write(f"\nTraceback (most recent call last): escaped run_app: {exc!r}\n")
                code = 1
        lines = [line[:2000] for line in err.getvalue().splitlines()[-50:]]
        answer = {"exit": code, "stderr": "\n".join(lines), "peak": _peak_bytes()}
        answer["seconds"] = time.monotonic() - start
        answers.write(json.dumps(answer) + "\n")
        answers.flush()


class _Worker:
    """One worker subprocess, restarted after a hang or a crash."""

    def __init__(self) -> None:
        self.proc = subprocess.Popen(
            [sys.executable, __file__, "--worker"],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            env=_ENV,
        )
        self.buffer = b""

    def run(self, task: Task, timeout: float) -> Outcome:
        assert self.proc.stdin is not None and self.proc.stdout is not None
        start = time.monotonic()
        self.proc.stdin.write((json.dumps({"argv": task.argv}) + "\n").encode())
        self.proc.stdin.flush()
        line = self._read_line(start + timeout)
        if line is None:
            timed_out = self.proc.poll() is None
            self.stop()
            code = None if timed_out else self.proc.returncode
            category, last = classify(code, "", 0, timed_out=timed_out)
            return Outcome(task.key, category, code, last, time.monotonic() - start, 0.0)
        answer = json.loads(line)
        category, last = classify(answer["exit"], answer["stderr"], answer["peak"])
        return Outcome(
            task.key, category, answer["exit"], last, answer["seconds"], answer["peak"] / 2**20
        )

    def _read_line(self, deadline: float) -> bytes | None:
        """The next answer line, None on timeout or when the worker died."""
        assert self.proc.stdout is not None
        fd = self.proc.stdout.fileno()
        with selectors.DefaultSelector() as selector:
            selector.register(fd, selectors.EVENT_READ)
            while b"\n" not in self.buffer:
                remaining = deadline - time.monotonic()
                if remaining <= 0 or not selector.select(remaining):
                    return None
                chunk = os.read(fd, 1 << 16)
                if not chunk:
                    return None
                self.buffer += chunk
        line, _, self.buffer = self.buffer.partition(b"\n")
        return line

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.wait()


def run_in_process(tasks: list[Task], *, jobs: int, timeout: float) -> list[Outcome]:
    """Run ``tasks`` on ``jobs`` workers; outcomes in the order of ``tasks``."""
    pending: queue.Queue[tuple[int, Task]] = queue.Queue()
    for item in enumerate(tasks):
        pending.put(item)
    results: dict[int, Outcome] = {}

    def serve() -> None:
        worker = _Worker()
        try:
            while True:
                try:
                    index, task = pending.get_nowait()
                except queue.Empty:
                    return
                results[index] = worker.run(task, timeout)
                # After a memory bomb the worker keeps its pages (its VmHWM cannot be reset below
                # them): a fresh one, so that the next task's peak is its own.
                if worker.proc.poll() is not None or results[index].category == "memory bomb":
                    worker.stop()
                    worker = _Worker()
        finally:
            worker.stop()

    threads = [threading.Thread(target=serve) for _ in range(jobs)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    return [results[i] for i in range(len(tasks))]


def run_subprocess(task: Task, *, timeout: float) -> Outcome:
    """Run ``bagkit`` itself on the task (memory limited); peak memory from wait4's rusage."""
    start = time.monotonic()
    proc = subprocess.Popen(
        [BAGKIT, *task.argv],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        env=_ENV,
        preexec_fn=_limit_memory,  # noqa: PLW1509 (no threads in between: the child only execs)
    )
    chunks: list[bytes] = []
    assert proc.stderr is not None
    reader = threading.Thread(target=lambda: chunks.append(proc.stderr.read()))  # type: ignore[union-attr]
    reader.start()
    timed_out = False
    while True:
        pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
        if pid:
            break
        if time.monotonic() - start > timeout:
            timed_out = True
            proc.kill()
            _, status, usage = os.wait4(proc.pid, 0)
            break
        time.sleep(0.01)
    code = os.waitstatus_to_exitcode(status)
    proc.returncode = code
    reader.join()
    stderr = b"".join(chunks).decode(errors="replace")
    peak = usage.ru_maxrss * 1024
    category, last = classify(code, stderr, peak, timed_out=timed_out)
    return Outcome(task.key, category, code, last, time.monotonic() - start, peak / 2**20)


if __name__ == "__main__" and sys.argv[1:] == ["--worker"]:
    worker_main()
