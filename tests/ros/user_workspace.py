"""A user's own interface package built as ROS users build it (colcon, the rosidl wheels of
the dev extra, the CMake override of docs/install.md) and sourced: the helpers of the tests
that use it (tests/ros/test_user_package.py, test_user_package_drift.py; their fixtures are in
tests/ros/conftest.py).
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import sysconfig
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest

USER_PROJECT = Path(__file__).with_name("user_package")
CMAKE_OVERRIDE = USER_PROJECT / "wheel_python_includes.cmake"
BAGKIT = str(Path(sys.executable).with_name("bagkit"))
BUILD_TIMEOUT_S = 900
RUN_TIMEOUT_S = 120
REPORTS = 12
REPORT_TOPIC = "/battery/report"
EVENTS_TOPIC = "/battery/set_charge_limit/_service_event"
REPORT_TYPE = "my_robot_msgs/msg/BatteryReport"
EVENT_TYPE = "my_robot_msgs/srv/SetChargeLimit_Event"
# The user's subscriber: prints each of REPORTS reports it receives as a JSON line, then exits.
LISTENER = [sys.executable, "-m", "battery.listener", "--count", str(REPORTS)]


@dataclass(frozen=True)
class Workspace:
    """The built workspace and the environment of its sourced ``install/local_setup.bash``."""

    root: Path
    env: dict[str, str]


@dataclass(frozen=True)
class Recording:
    """A bag recorded from the battery monitor, what it published, the recorder's report."""

    bag: Path
    published: list[dict[str, Any]]
    report: str


def unavailable(reason: str) -> None:
    """Skip where the toolchain is missing; under CI a missing toolchain is a failure."""
    if os.environ.get("CI", "").lower() == "true":
        pytest.fail(reason)
    pytest.skip(reason)


def prepend(path: str, existing: str | None) -> str:
    return os.pathsep.join([path, existing]) if existing else path


def build_environment() -> dict[str, str]:
    """This environment as a user's activated venv holding the ROS wheels: its bin on PATH,
    its prefix on AMENT_PREFIX_PATH (where rosidl looks up the installed type supports)."""
    env = dict(os.environ)
    env["PATH"] = prepend(str(Path(sys.executable).parent), env.get("PATH"))
    env["AMENT_PREFIX_PATH"] = prepend(sys.prefix, env.get("AMENT_PREFIX_PATH"))
    return env


def cmake_args() -> list[str]:
    """The override of docs/install.md, with this interpreter's Python and NumPy headers."""
    include = sysconfig.get_paths()["include"]
    if not Path(include, "Python.h").is_file():
        unavailable(f"no Python headers at {include}: the interface package cannot be built")
    return [
        f"-DCMAKE_PROJECT_INCLUDE={CMAKE_OVERRIDE}",
        f"-DPython3_EXECUTABLE={sys.executable}",
        f"-DPython3_INCLUDE_DIR={include}",
        f"-DPython3_NumPy_INCLUDE_DIR={np.get_include()}",
    ]


def sourced(setup: Path, env: dict[str, str]) -> dict[str, str]:
    """The environment after ``source setup`` in bash, as a user's shell has it."""
    script = 'source "$1" >/dev/null && env -0'
    out = subprocess.run(
        ["bash", "-c", script, "bash", str(setup)],
        env=env,
        capture_output=True,
        timeout=60,
        check=False,
    )
    assert out.returncode == 0, out.stderr.decode()
    pairs = (entry.split("=", 1) for entry in out.stdout.decode().split("\0") if "=" in entry)
    return dict(pairs)


def build_workspace(root: Path, package: Path) -> Workspace:
    """``package`` (an interface package's sources) built by colcon in ``root``, and sourced."""
    colcon = Path(sys.executable).with_name("colcon")
    if not colcon.is_file():
        unavailable(f"{colcon} not installed: pip install -e '.[dev]' installs the toolchain")
    if shutil.which("cmake") is None or shutil.which("c++") is None:
        unavailable("cmake and a C++ compiler are needed to build an interface package")
    shutil.copytree(package, root / "src" / package.name)
    env = build_environment()
    env["COLCON_HOME"] = str(root / "colcon_home")  # no defaults or mixins of the developer's
    args = [str(colcon), "--log-base", "log", "build", "--cmake-args", *cmake_args()]
    built = subprocess.run(
        args,
        cwd=root,
        env=env,
        capture_output=True,
        text=True,
        timeout=BUILD_TIMEOUT_S,
        check=False,
    )
    assert built.returncode == 0, built.stdout[-4000:] + built.stderr[-4000:]
    user_env = sourced(root / "install" / "local_setup.bash", env)
    for variable in ("AMENT_PREFIX_PATH", "PYTHONPATH", "LD_LIBRARY_PATH"):
        assert str(root / "install" / package.name) in user_env.get(variable, ""), variable
    return Workspace(root, user_env)


def run(
    args: list[str], env: dict[str, str], cwd: Path, timeout: float = RUN_TIMEOUT_S
) -> subprocess.CompletedProcess[str]:
    """A command in ``env`` (the sourced environment, mostly); it must succeed."""
    result = subprocess.run(
        args,
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=timeout,
        check=False,
    )
    assert result.returncode == 0, f"{args}\n{result.stdout}\n{result.stderr}"
    return result


@contextmanager
def background(args: list[str], env: dict[str, str], cwd: Path) -> Iterator[subprocess.Popen[str]]:
    """``args`` running in a process group of its own, its output piped; the group is killed
    on leaving if the process still runs (a test that failed half-way)."""
    process = subprocess.Popen(
        args,
        cwd=cwd,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    try:
        yield process
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
            process.communicate()


def json_lines(text: str) -> list[Any]:
    """The JSON lines of ``text`` (Fast DDS may print its own log lines among them)."""
    return [json.loads(line) for line in text.splitlines() if line.startswith("{")]
