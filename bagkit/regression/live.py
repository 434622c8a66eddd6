"""The live system in the loop: recording fixtures, and replaying goldens through DDS.

Both run our own console scripts as subprocesses, as a user would: ``fusion launch`` for the
nodes, ``bagkit record`` for the recording and ``bagkit replay --clock`` for the inputs. Every
process runs in its own session and is stopped by its pid (SIGINT, then SIGKILL), so a failed
run leaves nothing behind. The caller's environment decides the ROS domain and discovery range.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any

import yaml

from bagkit.compare import compare_bags
from bagkit.regression.errors import LiveRunError
from bagkit.regression.golden import GoldenCheck, update_golden
from bagkit.regression.lockstep import LockstepResult, NodeUnderTest
from bagkit.regression.spec import BAG_DIR, FixtureSpec

TRUTH_TOPIC = "/sim/truth"
MAX_FIXTURE_BYTES = 2_000_000
STOP_TIMEOUT_S = 15.0


def _script(name: str) -> str:
    # The console scripts of this environment, whatever PATH says.
    return str(Path(sys.executable).with_name(name))


def _nested(flat: Mapping[str, object]) -> dict[str, Any]:
    """Dotted parameter names as the nested mapping of a ROS 2 parameter file."""
    tree: dict[str, Any] = {}
    for key, value in flat.items():
        *parents, leaf = key.split(".")
        node = tree
        for part in parents:
            node = node.setdefault(part, {})
        node[leaf] = value
    return tree


def write_parameter_file(path: Path, params: Mapping[str, Mapping[str, object]]) -> Path:
    """A ROS 2 parameter file with ``params`` (node name -> dotted overrides)."""
    document = {
        node: {"ros__parameters": _nested(values)} for node, values in params.items() if values
    }
    path.write_text(yaml.safe_dump(document, sort_keys=False))
    return path


class Processes:
    """Subprocesses started in their own sessions, stopped by pid, output kept in log files."""

    def __init__(self, log_dir: Path) -> None:
        self.log_dir = log_dir
        self.started: list[tuple[str, subprocess.Popen[bytes], IO[bytes]]] = []

    def start(self, name: str, args: Sequence[str]) -> subprocess.Popen[bytes]:
        """Start ``args``; stdout and stderr go to ``<log_dir>/<name>.log``."""
        log = (self.log_dir / f"{name}.log").open("wb")
        proc = subprocess.Popen(
            list(args),
            stdout=log,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
            start_new_session=True,
        )
        self.started.append((name, proc, log))
        return proc

    def stop(self, proc: subprocess.Popen[bytes], timeout: float = STOP_TIMEOUT_S) -> int:
        """SIGINT ``proc`` (SIGKILL after ``timeout``); return its exit code."""
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
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

    def log_tail(self, name: str, lines: int = 15) -> str:
        """The end of a process's log, for error messages."""
        text = (self.log_dir / f"{name}.log").read_text(errors="replace")
        return "\n".join(text.splitlines()[-lines:])


@contextmanager
def _processes(log_dir: Path) -> Iterator[Processes]:
    log_dir.mkdir(parents=True, exist_ok=True)
    group = Processes(log_dir)
    try:
        yield group
    finally:
        group.stop_all()


def wait_for_subscribers(
    counts: Mapping[str, int], *, timeout: float, alive: Callable[[], bool]
) -> None:
    """Wait until each topic has at least its count of subscriptions in the ROS graph.

    Raises:
        LiveRunError: ``timeout`` passed, or ``alive()`` turned false (a process died).
    """
    import rclpy
    from rclpy.context import Context

    context = Context()
    rclpy.init(context=context)
    try:
        node = rclpy.create_node("bagkit_golden_wait", context=context)
        deadline = time.monotonic() + timeout
        while True:
            short = {t: n for t, n in counts.items() if node.count_subscribers(t) < n}
            if not short:
                return
            if not alive():
                raise LiveRunError("a process of the live run exited early")
            if time.monotonic() > deadline:
                raise LiveRunError(f"no subscriber after {timeout:.0f} s on {', '.join(short)}")
            time.sleep(0.1)
    finally:
        rclpy.shutdown(context=context)


def _subscriber_counts(nodes: Sequence[NodeUnderTest], inputs: Sequence[str]) -> dict[str, int]:
    from fusion.processors import create_processor

    counts = dict.fromkeys(inputs, 0)
    for node in nodes:
        for topic in create_processor(node.name, dict(node.params)).input_topics:
            if topic in counts:
                counts[topic] += 1
    counts["/clock"] = len(nodes)
    return counts


def _launch_args(spec: FixtureSpec, workdir: Path, *, sim_time: bool) -> list[str]:
    params = {node.name: node.params for node in spec.nodes}
    args = [_script("fusion"), "launch"]
    if sim_time:
        args += ["--use-sim-time", "--only", ",".join(node.name for node in spec.nodes)]
    else:
        params = {"sensor_publisher": spec.scenario, **params}
    if any(params.values()):
        args += ["--params", str(write_parameter_file(workdir / "params.yaml", params))]
    return args


def check_live(spec: FixtureSpec, workdir: Path, *, startup_timeout: float = 30.0) -> GoldenCheck:
    """Replay ``spec``'s golden inputs through the nodes on DDS and compare their outputs.

    The nodes run with ``use_sim_time``; ``bagkit replay --clock`` publishes the inputs and the
    clock; ``bagkit record --use-sim-time`` records the outputs; the comparison uses the spec's
    live tolerances.

    Raises:
        LiveRunError: a process failed or the graph did not come up.
    """
    workdir.mkdir(parents=True, exist_ok=True)
    candidate = workdir / "candidate"
    with _processes(workdir / "logs") as procs:
        nodes = procs.start("nodes", _launch_args(spec, workdir, sim_time=True))
        recorder = procs.start(
            "record",
            [_script("bagkit"), "record", "--use-sim-time", "-o", str(candidate), *spec.outputs],
        )
        counts = _subscriber_counts(spec.nodes, spec.inputs)
        counts.update(dict.fromkeys(spec.outputs, 1))  # the recorder's
        wait_for_subscribers(
            counts,
            timeout=startup_timeout,
            alive=lambda: nodes.poll() is None and recorder.poll() is None,
        )
        replay = procs.start(
            "replay",
            [
                _script("bagkit"),
                "replay",
                "--clock",
                "--topics",
                ",".join(spec.inputs),
                str(spec.bag),
            ],
        )
        try:
            code = replay.wait(timeout=2 * spec.duration_s + 60)
        except subprocess.TimeoutExpired:
            raise LiveRunError(f"bagkit replay hangs:\n{procs.log_tail('replay')}") from None
        if code != 0:
            raise LiveRunError(f"bagkit replay exited {code}:\n{procs.log_tail('replay')}")
        time.sleep(2.0)  # the last outputs are still in flight on a loaded machine
        code = procs.stop(recorder)
        if not candidate.exists():
            raise LiveRunError(f"bagkit record exited {code}:\n{procs.log_tail('record')}")
    report = compare_bags(spec.bag, candidate, spec.compare_options("live"))
    return GoldenCheck(spec, "live", candidate, report)


def record_fixture(
    spec: FixtureSpec, workdir: Path, *, log: Callable[[str], None] = print
) -> LockstepResult:
    """Re-record ``spec``'s golden bag from the live system, then rewrite its outputs.

    The whole system (sensor publisher with the spec's scenario, and the nodes under test)
    runs on the wall clock while ``bagkit record`` records inputs, outputs and the ground
    truth for ``spec.duration_s``. The recorded outputs are then replaced by lockstep's (the
    recorder joins a little after the nodes, so the live outputs start from a state the bag
    does not hold; the golden tests compare against outputs computed from the bag alone).

    Raises:
        LiveRunError: a process failed, or the bag is larger than 2 MB.
    """
    workdir.mkdir(parents=True, exist_ok=True)
    recording = workdir / BAG_DIR
    topics = [*spec.inputs, *spec.outputs, TRUTH_TOPIC]
    with _processes(workdir / "logs") as procs:
        recorder = procs.start(
            "record", [_script("bagkit"), "record", "-o", str(recording), *topics]
        )
        time.sleep(1.0)  # the recorder is in the graph before the first sensor message
        nodes = procs.start("system", _launch_args(spec, workdir, sim_time=False))
        log(f"{spec.name}: recording {spec.duration_s:.0f} s of the live system ...")
        deadline = time.monotonic() + spec.duration_s + 1.0
        while time.monotonic() < deadline:
            if nodes.poll() is not None or recorder.poll() is not None:
                raise LiveRunError(
                    f"the live system stopped early:\n{procs.log_tail('system')}\n"
                    f"{procs.log_tail('record')}"
                )
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
    return update_golden(spec)
