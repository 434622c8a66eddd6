"""The live system in the loop: replaying goldens through DDS, and recording new goldens.

The system under test is whatever the spec's command lines start (any language). bagkit runs
its own console scripts beside them, as a user would: ``bagkit record`` for the recording and
``bagkit replay --clock`` for the inputs. Every process runs in its own session and is stopped
by its pid (SIGINT, then SIGKILL), so a failed run leaves nothing behind. The caller's
environment decides the ROS domain and discovery range.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Collection, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import IO

from bagkit import extras
from bagkit.bag import BagReader
from bagkit.compare import compare_bags
from bagkit.regression.errors import LiveRunError, SpecError
from bagkit.regression.golden import GoldenCheck, update_golden
from bagkit.regression.spec import BAG_DIR, SPEC_FILE, FixtureSpec

MAX_FIXTURE_BYTES = 2_000_000
STOP_TIMEOUT_S = 15.0
SETTLE_S = 2.0
# /clock between the inputs: the rate the live fixtures were measured at (20 of 20 passes),
# finer than a bare --clock's 40 Hz.
CLOCK_HZ = 100
CLOCK_HOLD_S = 0.5
LOG_TAIL_LINES = 15


def _script(name: str) -> str:
    # The console scripts of this environment, whatever PATH says.
    return str(Path(sys.executable).with_name(name))


class Processes:
    """Subprocesses started in their own sessions, stopped by pid, output kept in log files."""

    def __init__(self, log_dir: Path) -> None:
        self.log_dir = log_dir
        self.started: list[tuple[str, subprocess.Popen[bytes], IO[bytes]]] = []

    def start(self, name: str, args: Sequence[str]) -> subprocess.Popen[bytes]:
        """Start ``args``; stdout and stderr go to ``<log_dir>/<name>.log``.

        Raises:
            LiveRunError: the program cannot be started.
        """
        log = (self.log_dir / f"{name}.log").open("wb")
        try:
            proc = subprocess.Popen(
                list(args),
                stdout=log,
                stderr=subprocess.STDOUT,
                stdin=subprocess.DEVNULL,
                start_new_session=True,
            )
        except OSError as exc:
            log.close()
            raise LiveRunError(f"cannot start {name} ({args[0]}): {exc.strerror}") from exc
        self.started.append((name, proc, log))
        return proc

    def stop(self, proc: subprocess.Popen[bytes], timeout: float = STOP_TIMEOUT_S) -> int:
        """SIGINT ``proc``'s process group (SIGKILL after ``timeout``); return its exit code."""
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGINT)
        try:
            return proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            return proc.wait()

    def stop_all(self) -> None:
        """Stop whatever is still running, last started first."""
        for _, proc, log in reversed(self.started):
            self.stop(proc)
            log.close()

    def exited(self, ignore: Collection[str] = ()) -> str | None:
        """The name of the first process (not in ``ignore``) that has exited, or None."""
        return next(
            (n for n, proc, _ in self.started if n not in ignore and proc.poll() is not None),
            None,
        )

    def check_running(self, ignore: Collection[str] = ()) -> None:
        """Raise if a process (not in ``ignore``) has exited.

        Raises:
            LiveRunError: naming the process, its exit code and the tail of its log.
        """
        name = self.exited(ignore)
        if name is not None:
            code = next(p.returncode for n, p, _ in self.started if n == name)
            raise LiveRunError(
                f"a process of the live run exited early: {name} (exit code {code}); "
                f"the end of its log:\n{self.log_tail(name)}"
            )

    def log_tail(self, name: str, lines: int = LOG_TAIL_LINES) -> str:
        """The end of a process's log, for error messages."""
        for _, _, log in self.started:
            log.flush()
        text = (self.log_dir / f"{name}.log").read_text(errors="replace")
        return "\n".join(text.splitlines()[-lines:]) or "(empty)"


@contextmanager
def _processes(log_dir: Path) -> Iterator[Processes]:
    log_dir.mkdir(parents=True, exist_ok=True)
    group = Processes(log_dir)
    try:
        yield group
    finally:
        group.stop_all()


def _start_system(procs: Processes, commands: Sequence[Sequence[str]], prefix: str) -> None:
    for index, command in enumerate(commands):
        procs.start(f"{prefix}-{index}" if len(commands) > 1 else prefix, command)


def _prepare_graph(procs: Processes, counts: dict[str, int], start_ns: int, timeout: float) -> None:
    """Wait for the subscriptions in ``counts``, then set the nodes' clock to ``start_ns``."""
    from bagkit.ros.errors import SubscriberTimeoutError
    from bagkit.ros.graph_wait import hold_clock, wait_for_subscriptions

    try:
        wait_for_subscriptions(counts, timeout=timeout, alive=lambda: procs.exited() is None)
        clocks = counts.get("/clock", 0)
        if clocks:
            hold_clock(start_ns, subscriptions=clocks, seconds=CLOCK_HOLD_S, timeout=timeout)
    except ChildProcessError:
        procs.check_running()
    except SubscriberTimeoutError as exc:
        raise LiveRunError(f"the system did not come up: {exc}") from exc


def _bag_span(bag: Path) -> tuple[int, int]:
    with BagReader(bag) as reader:
        return reader.start_ns, reader.end_ns


def check_live(spec: FixtureSpec, workdir: Path, *, startup_timeout: float = 30.0) -> GoldenCheck:
    """Replay ``spec``'s golden inputs through the nodes on DDS and compare their outputs.

    The spec's ``launch`` commands start the nodes (with use_sim_time); ``bagkit record
    --use-sim-time`` records the outputs; once the graph shows the subscriptions the spec
    waits for, the nodes' clock is set to the golden's start, and ``bagkit replay --clock``
    publishes the inputs and the clock at ``live_rate``; the comparison uses the spec's live
    tolerances.

    Raises:
        SpecError: the spec has no launch command.
        LiveRunError: a process failed or the graph did not come up.
    """
    if not spec.launch:
        raise SpecError(f"{spec.directory / SPEC_FILE}: live mode needs a launch command")
    extras.require(extras.ROS, "live golden replay")
    workdir.mkdir(parents=True, exist_ok=True)
    candidate = workdir / "candidate"
    start_ns, end_ns = _bag_span(spec.bag)
    replay_timeout = 2 * (end_ns - start_ns) / 1e9 / spec.live_rate + 60
    with _processes(workdir / "logs") as procs:
        recorder = procs.start(
            "record",
            [_script("bagkit"), "record", "--use-sim-time", "-o", str(candidate), *spec.outputs],
        )
        # The recorder keeps nothing that arrives before its first /clock, and a node may
        # publish the moment its own clock is set (a timer due at the bag's start): the
        # recorder gets the clock before any node exists.
        _prepare_graph(procs, {"/clock": 1}, start_ns, startup_timeout)
        _start_system(procs, spec.launch, "launch")
        counts = {**spec.subscription_counts(), **dict.fromkeys(spec.outputs, 1)}
        counts["/clock"] = counts.get("/clock", 0) + 1  # the recorder's, matched again
        _prepare_graph(procs, counts, start_ns, startup_timeout)
        replay = procs.start(
            "replay",
            [
                _script("bagkit"),
                "replay",
                "--clock",
                str(CLOCK_HZ),
                "--rate",
                repr(spec.live_rate),
                "--topics",
                ",".join(spec.inputs),
                str(spec.bag),
            ],
        )
        try:
            code = replay.wait(timeout=replay_timeout)
        except subprocess.TimeoutExpired:
            raise LiveRunError(f"bagkit replay hangs:\n{procs.log_tail('replay')}") from None
        if code != 0:
            raise LiveRunError(f"bagkit replay exited {code}:\n{procs.log_tail('replay')}")
        time.sleep(SETTLE_S)  # the last outputs are still in flight on a loaded machine
        procs.check_running(ignore=("replay",))
        code = procs.stop(recorder)
        if not candidate.exists():
            raise LiveRunError(f"bagkit record exited {code}:\n{procs.log_tail('record')}")
    report = compare_bags(spec.bag, candidate, spec.compare_options("live"))
    return GoldenCheck(spec, "live", candidate, report)


def record_golden(
    spec: FixtureSpec, workdir: Path, *, log: Callable[[str], None] = print
) -> dict[str, int]:
    """Record ``spec``'s golden bag from the live system; return its message counts by topic.

    ``bagkit record`` records the inputs, outputs and ``record_topics`` while the spec's
    ``record_launch`` commands run the whole system on the wall clock for ``duration``. With a
    processor factory, the recorded outputs are then replaced by lockstep's (the recorder joins
    a little after the nodes, so the live outputs start from a state the bag does not hold).

    Raises:
        SpecError: the spec has no record_launch command.
        LiveRunError: a process failed, or the bag is larger than 2 MB.
    """
    if not spec.record_launch:
        raise SpecError(f"{spec.directory / SPEC_FILE}: recording needs record_launch")
    extras.require(extras.ROS, "bagkit golden record")
    workdir.mkdir(parents=True, exist_ok=True)
    recording = workdir / BAG_DIR
    topics = list(dict.fromkeys([*spec.inputs, *spec.outputs, *spec.record_topics]))
    with _processes(workdir / "logs") as procs:
        recorder = procs.start(
            "record", [_script("bagkit"), "record", "-o", str(recording), *topics]
        )
        time.sleep(1.0)  # the recorder is in the graph before the first input
        _start_system(procs, spec.record_launch, "system")
        log(f"{spec.name}: recording {spec.duration_s:.0f} s of the live system ...")
        deadline = time.monotonic() + spec.duration_s + 1.0
        while time.monotonic() < deadline:
            procs.check_running()
            time.sleep(0.2)
        code = procs.stop(recorder)
        if not recording.exists():
            raise LiveRunError(f"bagkit record exited {code}:\n{procs.log_tail('record')}")
    size = sum(f.stat().st_size for f in recording.iterdir())
    if size > MAX_FIXTURE_BYTES:
        raise LiveRunError(f"the recording is {size / 1e6:.1f} MB, more than 2 MB")
    if spec.bag.exists():
        shutil.rmtree(spec.bag)
    shutil.move(recording, spec.bag)
    if spec.processor is not None:
        update_golden(spec)
    with BagReader(spec.bag) as reader:
        return dict(reader.topic_counts)
