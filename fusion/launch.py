"""``fusion launch``: each node in its own process, output prefixed, stopped together.

What ``ros2 launch`` does for this system (ros2launch has no wheels): start the nodes, merge their
output with a ``[node]`` prefix, forward Ctrl-C/SIGTERM as SIGINT, wait, then kill stragglers,
and fail as soon as one node dies.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from types import FrameType
from typing import IO

from fusion.errors import NodeFailedError
from fusion.params import load_parameter_file
from fusion.processors import NODE_NAMES, create_processor

_COLOURS = ("\033[36m", "\033[32m", "\033[33m", "\033[35m")
_RESET = "\033[0m"
EXIT_INTERRUPTED = 130


@dataclass(slots=True)
class NodeProcess:
    """A started node."""

    name: str
    process: subprocess.Popen[bytes]
    reader: threading.Thread


def validate_parameter_file(path: Path, names: Sequence[str]) -> None:
    """Check ``path`` for every node in ``names`` before anything starts.

    rclpy silently ignores parameters a node does not declare; this catches misspelt names and
    bad values in each node's own section (``/**`` may hold parameters for some nodes only).

    Raises:
        ConfigError: the file is not a parameter file, or a node's section is invalid.
    """
    for name in names:
        create_processor(name, load_parameter_file(path, name, wildcard=False))


def node_command(
    name: str, *, params_file: Path | None = None, use_sim_time: bool = False
) -> list[str]:
    """The command line that runs node ``name`` in this Python environment."""
    command = [sys.executable, "-m", f"fusion.nodes.{name}", "--ros-args"]
    if params_file is not None:
        command += ["--params-file", str(params_file)]
    if use_sim_time:
        command += ["-p", "use_sim_time:=true"]
    return command


class Launcher:
    """Starts nodes and supervises them until a signal arrives or one of them exits."""

    def __init__(
        self,
        names: Sequence[str] = NODE_NAMES,
        *,
        params_file: Path | None = None,
        use_sim_time: bool = False,
        output: IO[str] | None = None,
        stop_timeout: float = 10.0,
    ) -> None:
        self.names = tuple(names)
        self.params_file = params_file
        self.use_sim_time = use_sim_time
        self.output = output if output is not None else sys.stdout
        self.stop_timeout = stop_timeout
        self.nodes: list[NodeProcess] = []
        self._stop = threading.Event()
        self._write_lock = threading.Lock()
        self._colour = self.output.isatty() and "NO_COLOR" not in os.environ

    def run(self) -> int:
        """Run until SIGINT/SIGTERM (exit 130) or until a node exits.

        A second SIGINT/SIGTERM while the nodes stop kills them at once.

        Raises:
            NodeFailedError: a node exited on its own or could not be stopped.
        """
        previous = {
            sig: signal.signal(sig, self._on_signal) for sig in (signal.SIGINT, signal.SIGTERM)
        }
        try:
            for index, name in enumerate(self.names):
                self._start(name, index)
            died = self._supervise()
            unclean = self._stop_all()
        finally:
            for sig, handler in previous.items():
                signal.signal(sig, handler)
        if died is not None:
            raise NodeFailedError(f"node {died.name} exited with code {died.process.returncode}")
        if unclean:
            raise NodeFailedError(f"node(s) did not stop cleanly: {', '.join(unclean)}")
        return EXIT_INTERRUPTED

    def _on_signal(self, signum: int, frame: FrameType | None) -> None:
        if self._stop.is_set():
            # A second Ctrl-C while the nodes shut down: do not make the user wait.
            for node in self.nodes:
                if node.process.poll() is None:
                    os.killpg(node.process.pid, signal.SIGKILL)
        self._stop.set()

    def _start(self, name: str, index: int) -> None:
        env = dict(os.environ, PYTHONUNBUFFERED="1")
        process = subprocess.Popen(
            node_command(name, params_file=self.params_file, use_sim_time=self.use_sim_time),
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
            env=env,
            # Own session: a terminal's Ctrl-C reaches only the launcher, which forwards it,
            # so every node is stopped exactly once and in a known way.
            start_new_session=True,
        )
        prefix = f"[{name}] "
        if self._colour:
            prefix = f"{_COLOURS[index % len(_COLOURS)]}{prefix}{_RESET}"
        assert process.stdout is not None
        reader = threading.Thread(
            target=self._copy_output, args=(process.stdout, prefix), daemon=True
        )
        reader.start()
        self.nodes.append(NodeProcess(name, process, reader))

    def _copy_output(self, stream: IO[bytes], prefix: str) -> None:
        for raw in stream:
            line = raw.decode(errors="replace").rstrip("\n")
            with self._write_lock:
                self.output.write(f"{prefix}{line}\n")
                self.output.flush()

    def _supervise(self) -> NodeProcess | None:
        while not self._stop.wait(0.1):
            for node in self.nodes:
                if node.process.poll() is not None:
                    return node
        return None

    def _stop_all(self) -> list[str]:
        for node in self.nodes:
            if node.process.poll() is None:
                os.killpg(node.process.pid, signal.SIGINT)
        deadline = time.monotonic() + self.stop_timeout
        unclean = []
        for node in self.nodes:
            try:
                node.process.wait(timeout=max(0.0, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                os.killpg(node.process.pid, signal.SIGKILL)
                node.process.wait()
            if node.process.returncode != 0:
                unclean.append(node.name)
            node.reader.join(timeout=1.0)
        return unclean
