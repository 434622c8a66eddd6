"""``fusion launch``: each node in its own process, output prefixed, stopped together.

What ``ros2 launch`` does for this system (ros2launch has no wheels): start the nodes, merge their
output with a ``[node]`` prefix, forward Ctrl-C/SIGTERM as SIGINT, wait, then kill stragglers,
and fail as soon as one node dies. The processes are bagkit's ``Supervisor``'s.
"""

from __future__ import annotations

import os
import signal
import sys
import threading
from collections.abc import Callable, Sequence
from pathlib import Path
from types import FrameType
from typing import IO

from bagkit.processes import Command, StopPolicy, Supervisor
from bagkit.words import counted
from fusion.errors import NodeFailedError
from fusion.params import load_parameter_file
from fusion.processors import NODE_NAMES, create_processor

_COLOURS = ("\033[36m", "\033[32m", "\033[33m", "\033[35m")
_RESET = "\033[0m"
EXIT_INTERRUPTED = 130


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
        self.nodes = Supervisor(StopPolicy(interrupt_s=stop_timeout))
        self._stop = threading.Event()
        self._write_lock = threading.Lock()
        self._colour = self.output.isatty() and "NO_COLOR" not in os.environ

    def run(self) -> int:
        """Run until SIGINT/SIGTERM (exit 130) or until a node exits.

        A second SIGINT/SIGTERM while the nodes stop kills them at once.

        Raises:
            NodeFailedError: a node exited on its own or could not be stopped.
            ProcessError: a node could not be started.
        """
        previous = {
            sig: signal.signal(sig, self._on_signal) for sig in (signal.SIGINT, signal.SIGTERM)
        }
        try:
            env = dict(os.environ, PYTHONUNBUFFERED="1")
            for index, name in enumerate(self.names):
                command = node_command(
                    name, params_file=self.params_file, use_sim_time=self.use_sim_time
                )
                self.nodes.start(Command(name, command, env=env, on_line=self._writer(index, name)))
            died = self.nodes.wait_any(self._stop)
            died_code = None if died is None else died.returncode
        finally:
            self.nodes.stop_all()
            for sig, handler in previous.items():
                signal.signal(sig, handler)
        if died is not None:
            raise NodeFailedError(f"node {died.name} exited with code {died_code}")
        unclean = [node.name for node in self.nodes.started if node.returncode != 0]
        if unclean:
            raise NodeFailedError(
                f"{counted(len(unclean), 'node')} did not stop cleanly: {', '.join(unclean)}"
            )
        return EXIT_INTERRUPTED

    def _on_signal(self, signum: int, frame: FrameType | None) -> None:
        if self._stop.is_set():
            # A second Ctrl-C while the nodes shut down: do not make the user wait.
            self.nodes.kill_all()
        self._stop.set()

    def _writer(self, index: int, name: str) -> Callable[[str], None]:
        prefix = f"[{name}] "
        if self._colour:
            prefix = f"{_COLOURS[index % len(_COLOURS)]}{prefix}{_RESET}"

        def write(line: str) -> None:
            with self._write_lock:
                self.output.write(f"{prefix}{line}\n")
                self.output.flush()

        return write
