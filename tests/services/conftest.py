"""A bag recorded from a real service over DDS, shared by the service tests of a session."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

NODE = Path(__file__).with_name("service_node.py")
BAGKIT = str(Path(sys.executable).with_name("bagkit"))
CALLS = 6


def start_node(*args: str) -> subprocess.Popen[str]:
    """Start ``service_node.py`` with ``args``; it prints ``ready`` then ``called N``."""
    return subprocess.Popen([sys.executable, str(NODE), *args], stdout=subprocess.PIPE, text=True)


def stop(process: subprocess.Popen[str], timeout: float = 15.0) -> None:
    if process.poll() is None:
        process.send_signal(signal.SIGINT)
    try:
        process.wait(timeout)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait()


def wait_line(process: subprocess.Popen[str], prefix: str, timeout: float = 30.0) -> str:
    assert process.stdout is not None
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        line = process.stdout.readline()
        if line.startswith(prefix):
            return line.strip()
        assert line or process.poll() is None, f"exited with {process.returncode}"
    raise AssertionError(f"no {prefix!r} line within {timeout} s")


def record_calls(
    bag: Path, record_args: list[str], node_args: list[str], *, events_recorded: bool = True
) -> str:
    """Record while a client makes ``CALLS`` calls; return the recorder's stderr.

    ``events_recorded``: the calls start once the recorder subscribed to the events; else
    after a delay."""
    recorder = subprocess.Popen(
        [BAGKIT, "record", *record_args, "-o", str(bag), "--log-level", "warn"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    wait = ["--wait-subscriber"] if events_recorded else ["--delay", "3"]
    node = start_node("--calls", str(CALLS), *wait, *node_args)
    try:
        wait_line(node, "called", timeout=60.0)
        time.sleep(0.5)
    finally:
        stop(node)
        stop(recorder)
    assert recorder.stderr is not None
    return recorder.stderr.read()


@pytest.fixture(scope="session")
def service_bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``bagkit record -a`` of ``CALLS`` calls, both sides introspected."""
    bag = tmp_path_factory.mktemp("services") / "calls"
    record_calls(bag, ["-a"], ["--client-introspection"])
    return bag


@pytest.fixture(scope="session")
def server_bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``bagkit record --services /svc/toggle`` of ``CALLS`` calls, the server's events only."""
    bag = tmp_path_factory.mktemp("services") / "server"
    record_calls(bag, ["--services", "/svc/toggle"], [])
    return bag
