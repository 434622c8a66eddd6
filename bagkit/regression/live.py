"""The live system in the loop: replaying goldens through DDS, and recording new goldens.

The system under test is whatever the spec's command lines start (any language), each in its
own session under :class:`bagkit.processes.Supervisor` (SIGINT, SIGTERM, then SIGKILL), so a
failed run leaves nothing behind.
bagkit's side runs in this process through the library, as ``bagkit record`` and
``bagkit replay --clock`` would (the same ``Recorder(options)`` and ``Player(options)``, the same
process tuning), and every wait is on an event: a subscription in the graph, the recorder
started, the outputs recorded. docs/regression.md says why in-process. The caller's environment
decides the ROS domain and discovery range.
"""

from __future__ import annotations

import shutil
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

from bagkit.bag import BagReader
from bagkit.compare import compare_bags
from bagkit.errors import BagkitError
from bagkit.extras import ROS, require
from bagkit.playback.options import PlayOptions, ServiceRequestReplay
from bagkit.processes import Command, ProcessError, StopPolicy, Supervisor
from bagkit.recording.options import RecordOptions
from bagkit.regression.errors import LiveRunError, SpecError
from bagkit.regression.golden import GoldenCheck, update_golden
from bagkit.regression.spec import BAG_DIR, SPEC_FILE, FixtureSpec
from bagkit.selection.services import event_topic

if TYPE_CHECKING:
    from bagkit.recording.report import RecordProgress
    from bagkit.ros.record.recorder import Recorder

MAX_FIXTURE_BYTES = 2_000_000
STOP_TIMEOUT_S = 15.0
# After the replay, how long the last outputs may take to reach the recorder (a loaded machine).
OUTPUTS_TIMEOUT_S = 10.0
POLL_S = 0.05
# A live system has this long to publish its first message once launched.
FIRST_MESSAGE_TIMEOUT_S = 60.0
# How long a golden's recording waits past its duration for the bag to span it.
LAST_MESSAGE_TIMEOUT_S = 5.0
# /clock between the inputs: the rate the live fixtures were measured at (20 of 20 passes),
# finer than a bare --clock's 40 Hz.
CLOCK_HZ = 100
CLOCK_HOLD_S = 0.5


@contextmanager
def _processes(log_dir: Path) -> Iterator[Supervisor]:
    """The system under test's processes, each logging to ``<log_dir>/<name>.log``."""
    log_dir.mkdir(parents=True, exist_ok=True)
    with Supervisor(StopPolicy(interrupt_s=STOP_TIMEOUT_S)) as group:
        yield group


def _check_running(procs: Supervisor) -> None:
    """Raise LiveRunError naming a process of the system that has exited, with its log's end."""
    gone = procs.exited()
    if gone is not None:
        raise LiveRunError(
            f"a process of the live run exited early: {gone.name} (exit code "
            f"{gone.returncode}); the end of its log:\n{procs.log_tail(gone)}"
        )


def _start_system(
    procs: Supervisor, log_dir: Path, commands: Sequence[Sequence[str]], prefix: str
) -> None:
    """Start the spec's command lines, each logging to ``<log_dir>/<name>.log``.

    Raises:
        LiveRunError: a program cannot be started.
    """
    for index, command in enumerate(commands):
        name = f"{prefix}-{index}" if len(commands) > 1 else prefix
        try:
            procs.start(Command(name, command, log=log_dir / f"{name}.log"))
        except ProcessError as exc:
            raise LiveRunError(str(exc)) from exc


def _wait_for(
    recorder: Recorder, procs: Supervisor, done: Callable[[RecordProgress], bool], timeout: float
) -> bool:
    """Poll the recorder's progress until ``done``; False after ``timeout`` s or if it stopped.

    Raises:
        LiveRunError: a process of the system exited.
    """
    give_up = time.monotonic() + timeout
    while not done(recorder.progress()):
        _check_running(procs)
        if time.monotonic() > give_up or recorder.stopped.wait(POLL_S):
            return False
    return True


def _record_for(recorder: Recorder, procs: Supervisor, span_s: float) -> None:
    """Record until the bag spans ``span_s``, or LAST_MESSAGE_TIMEOUT_S past when it should.

    The bag's span, not a deadline: a machine that stalls (a virtual machine off its host's
    CPU) finds a deadline passed on waking, the seconds before it unrecorded.

    Raises:
        LiveRunError: a process exited, or no message came within FIRST_MESSAGE_TIMEOUT_S.
    """
    if not _wait_for(recorder, procs, lambda p: p.messages > 0, FIRST_MESSAGE_TIMEOUT_S):
        raise LiveRunError(
            f"no message recorded within {FIRST_MESSAGE_TIMEOUT_S:.0f} s of starting the "
            "system (see the logs)"
        )
    span_ns = span_s * 1e9
    _wait_for(recorder, procs, lambda p: p.span_ns >= span_ns, span_s + LAST_MESSAGE_TIMEOUT_S)


def _prepare_graph(
    procs: Supervisor, counts: dict[str, int], start_ns: int, timeout: float
) -> None:
    """Wait for the subscriptions in ``counts``, then set the nodes' clock to ``start_ns``."""
    from bagkit.ros.errors import SubscriberTimeoutError
    from bagkit.ros.graph_wait import hold_clock, wait_for_subscriptions

    try:
        wait_for_subscriptions(counts, timeout=timeout, alive=lambda: procs.exited() is None)
        clocks = counts.get("/clock", 0)
        if clocks:
            hold_clock(start_ns, subscriptions=clocks, seconds=CLOCK_HOLD_S, timeout=timeout)
    except ChildProcessError:
        _check_running(procs)
    except SubscriberTimeoutError as exc:
        raise LiveRunError(f"the system did not come up: {exc}") from exc


def _bag_span(bag: Path) -> tuple[int, int]:
    with BagReader(bag) as reader:
        return reader.start_ns, reader.end_ns


@contextmanager
def _recording(options: RecordOptions) -> Iterator[Recorder]:
    """A started recorder (its node in the graph, the topics looked for once), stopped after.

    Raises:
        LiveRunError: the recorder cannot start, or the recording failed (a full disk).
    """
    from bagkit.ros.record.recorder import Recorder

    recorder = Recorder(options)
    try:
        recorder.start()
    except BagkitError as exc:
        raise LiveRunError(f"the recorder did not start: {exc}") from exc
    try:
        yield recorder
    finally:
        report = recorder.stop()
    if report.error is not None:
        raise LiveRunError(f"the recording failed: {report.error}")


def _replay_inputs(spec: FixtureSpec) -> None:
    """Publish the golden's inputs and /clock at ``live_rate``, as ``bagkit replay --clock``.

    Raises:
        LiveRunError: the replay could not start or its subscribers did not come.
    """
    from bagkit.ros.replay.player import Player

    options = PlayOptions(
        spec.bag,
        rate=spec.live_rate,
        topics=(*spec.inputs, *map(event_topic, spec.services)),
        clock_hz=CLOCK_HZ,
        services=False,
        # The golden's requests go to the live services; their events are outputs.
        service_requests=ServiceRequestReplay() if spec.services else None,
    )
    try:
        Player(options).run()
    except BagkitError as exc:
        raise LiveRunError(f"replaying the inputs failed: {exc}") from exc


def check_live(spec: FixtureSpec, workdir: Path, *, startup_timeout: float = 30.0) -> GoldenCheck:
    """Replay ``spec``'s golden inputs through the nodes on DDS and compare their outputs.

    The spec's ``launch`` commands start the nodes (with use_sim_time); a recorder with sim
    time records the outputs; once the graph shows the subscriptions the spec waits for, the
    nodes' clock is set to the golden's start, and a player publishes the inputs and the clock
    at ``live_rate``; the comparison uses the spec's live tolerances.

    Raises:
        SpecError: the spec has no launch command.
        LiveRunError: a process failed or the graph did not come up.
    """
    if not spec.launch:
        raise SpecError(f"{spec.directory / SPEC_FILE}: live mode needs a launch command")
    require(ROS, "live golden replay")
    workdir.mkdir(parents=True, exist_ok=True)
    candidate = workdir / "candidate"
    drifted = GoldenCheck.drifted(spec, "live", candidate)
    if drifted is not None:
        return drifted
    start_ns, _ = _bag_span(spec.bag)
    with BagReader(spec.bag) as golden:
        expected = sum(golden.topic_counts.get(topic, 0) for topic in spec.outputs)
    options = RecordOptions(candidate, topics=tuple(spec.outputs), use_sim_time=True)
    with _processes(workdir / "logs") as procs, _recording(options) as recorder:
        # The recorder keeps nothing that arrives before its first /clock, and a node may
        # publish the moment its own clock is set (a timer due at the bag's start): the
        # recorder gets the clock before any node exists.
        _prepare_graph(procs, {"/clock": 1}, start_ns, startup_timeout)
        _start_system(procs, workdir / "logs", spec.launch, "launch")
        counts = {**spec.subscription_counts(), **dict.fromkeys(spec.outputs, 1)}
        counts["/clock"] = counts.get("/clock", 0) + 1  # the recorder's, matched again
        _prepare_graph(procs, counts, start_ns, startup_timeout)
        _replay_inputs(spec)
        # The last outputs are still in flight when the replay ends; fewer than the golden's
        # are for the comparison to report.
        _wait_for(recorder, procs, lambda p: p.messages >= expected, OUTPUTS_TIMEOUT_S)
        _check_running(procs)
    report = compare_bags(spec.bag, candidate, spec.compare_options("live"))
    return GoldenCheck(spec, "live", candidate, report)


def record_golden(
    spec: FixtureSpec, workdir: Path, *, log: Callable[[str], None] = print
) -> dict[str, int]:
    """Record ``spec``'s golden bag from the live system; return its message counts by topic.

    A recorder records the inputs, outputs and ``record_topics`` while the spec's
    ``record_launch`` commands run the whole system on the wall clock for ``duration`` from
    its first message (a golden shorter than that is said through ``log``). With a
    processor factory, the recorded outputs are then replaced by lockstep's (the recorder joins
    a little after the nodes, so the live outputs start from a state the bag does not hold).

    Raises:
        SpecError: the spec has no record_launch command.
        LiveRunError: a process failed, or the bag is larger than 2 MB.
    """
    if not spec.record_launch:
        raise SpecError(f"{spec.directory / SPEC_FILE}: recording needs record_launch")
    require(ROS, "bagkit golden record")
    workdir.mkdir(parents=True, exist_ok=True)
    recording = workdir / BAG_DIR
    topics = tuple(dict.fromkeys([*spec.inputs, *spec.outputs, *spec.record_topics]))
    # The recorder has started (its node is in the graph) before the system's first input.
    with _processes(workdir / "logs") as procs, _recording(RecordOptions(recording, topics)) as rec:
        _start_system(procs, workdir / "logs", spec.record_launch, "system")
        log(f"{spec.name}: recording {spec.duration_s:.0f} s of the live system ...")
        # The duration is the bag's span, not time since launch (the processes take seconds
        # to start), plus a second, so that a topic at 1 Hz has its message at the end.
        _record_for(rec, procs, spec.duration_s + 1.0)
    size = sum(f.stat().st_size for f in recording.iterdir())
    if size > MAX_FIXTURE_BYTES:
        raise LiveRunError(f"the recording is {size / 1e6:.1f} MB, more than 2 MB")
    if spec.bag.exists():
        shutil.rmtree(spec.bag)
    shutil.move(recording, spec.bag)
    if spec.processor is not None:
        update_golden(spec)
    with BagReader(spec.bag) as reader:
        span_s = (reader.end_ns - reader.start_ns) / 1e9 if reader.message_count else 0.0
        if span_s < spec.duration_s:
            # Which topic started late or ended early tells a slow start from an early stop.
            spans = ", ".join(
                f"{topic} {(first - reader.start_ns) / 1e9:.2f}-"
                f"{(last - reader.start_ns) / 1e9:.2f} s"
                for topic, (first, last) in sorted(reader.topic_spans().items())
            )
            log(
                f"{spec.name}: the golden spans {span_s:.1f} s of the {spec.duration_s:g} s "
                f"asked ({spans}): the system stopped publishing or the recorder stopped early"
            )
        return dict(reader.topic_counts)
