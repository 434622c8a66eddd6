"""Session-wide test setup: keep every ROS process on this machine, on a domain of its own."""

from __future__ import annotations

import os
import subprocess
import sys
import types
from collections.abc import Generator, Iterator
from pathlib import Path
from typing import Any

import domains
import pytest

from bagkit.processes import Command, StopPolicy, Supervisor

# Set before anything creates a ROS context: rclpy reads these when a context initializes, and
# every subprocess a test starts inherits them. Each test process (each xdist worker) holds
# domains of its own, so that no two running at once on this machine see each other.
os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
os.environ.setdefault("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp")
domains.assign()

REPO_ROOT = Path(__file__).resolve().parents[1]
# The rosbag2 test bags live outside the repository (CI and the developers' machines have them
# beside the clone); BAGKIT_INTEROP_DIR points elsewhere.
INTEROP_DIR = Path(
    os.environ.get("BAGKIT_INTEROP_DIR", REPO_ROOT.parent / "shared" / "interop" / "rosbag2_jazzy")
)


# Fixtures that start DDS participants, in this process or in subprocesses (`processes` starts
# `bagkit record/replay` and `fusion`): every test that uses one is a `ros` test.
DDS_FIXTURES = frozenset({"node", "context", "listener_factory", "processes"})
# Names whose presence in a test module means its tests create participants themselves.
_DDS_MODULE_NAMES = ("Recorder", "Player", "play")
# Tests that share session fixtures which build or record for tens of seconds (the colcon
# workspace, which test_user_package.py and test_user_package_drift.py both record from; the
# services' bags), by where they are (a path prefix): under `--dist loadgroup` each group runs
# on one xdist worker, which makes them once.
SHARED_FIXTURE_GROUPS = {"tests/ros/test_user_package": "colcon", "tests/services/": "services"}


def _starts_dds(module: types.ModuleType | None) -> bool:
    """Whether a test module imports rclpy itself or the library's participant-creating API."""
    if module is None:
        return False
    names = vars(module)
    if isinstance(names.get("rclpy"), types.ModuleType):
        return True
    return any(
        str(getattr(names.get(name), "__module__", "")).startswith(
            ("bagkit.ros", "bagkit.regression")
        )
        for name in _DDS_MODULE_NAMES
    )


# DDS tests that assert timings measured on this machine (replay pacing and its controls, a
# sim-time node's timer, the span of a recorded golden): `make test` runs them after the
# parallel part, one at a time, so that another test's load does not widen what they measure.
SERIAL_DDS_TESTS = (
    "tests/ros/test_replay.py::test_every_message_in_order_with_the_recorded_pacing",
    "tests/ros/test_replay_controls.py::test_keys_in_a_terminal_pause_step_and_resume",
    "tests/ros/test_replay_controls.py::test_services_pause_step_resume_and_set_the_rate",
    "tests/ros/test_replay_controls.py::test_ctrl_z_then_fg_does_not_burst",
    "tests/ros/test_replay_pipeline.py::test_sim_time_nodes_follow_the_clock",
    "tests/regression/test_stranger_package.py::test_record_a_golden_pass_then_fail",
)

# Under this mark expression (make test's last step) only the files that hold a serial test are
# collected: the others would be imported, and their assertions rewritten, only to be deselected.
SERIAL_ONLY = "ros and serial"


def pytest_ignore_collect(collection_path: Path, config: pytest.Config) -> bool | None:
    """Only ``SERIAL_DDS_TESTS``' files under ``-m "ros and serial"``."""
    if " ".join(config.getoption("markexpr").split()) != SERIAL_ONLY or collection_path.is_dir():
        return None
    relative = collection_path.relative_to(config.rootpath).as_posix()
    return relative not in {prefix.partition("::")[0] for prefix in SERIAL_DDS_TESTS}


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Mark every test that starts DDS `ros`, from the fixtures it uses or its module's imports,
    so that `pytest -m "not ros"` is the fast loop without a middleware; and the timing ones
    `serial`."""
    for item in items:
        fixtures = set(getattr(item, "fixturenames", ()))
        if fixtures & DDS_FIXTURES or _starts_dds(getattr(item, "module", None)):
            item.add_marker(pytest.mark.ros)
        if item.nodeid.startswith(SERIAL_DDS_TESTS):
            item.add_marker(pytest.mark.serial)


@pytest.hookimpl(wrapper=True)
def pytest_collection() -> Generator[None, object, object]:
    """Collect with bytecode written, also where PYTHONDONTWRITEBYTECODE is set (as in CI).

    Every pytest process (each xdist worker) imports every test module, whose assertions pytest
    rewrites: the rewritten code it keeps (checked by the source's hash) is then read by the
    processes after the first instead of made again. The tests themselves run as set.
    """
    writes = sys.dont_write_bytecode
    sys.dont_write_bytecode = False
    try:
        return (yield)
    finally:
        sys.dont_write_bytecode = writes


def pytest_xdist_make_scheduler(config: pytest.Config, log: Any) -> Any:
    """``--dist loadgroup`` that also groups by ``SHARED_FIXTURE_GROUPS`` (named by path, not
    by an ``xdist_group`` mark: xdist 3.8 sends a mark's group to the scheduler in the node id,
    and pytest 9.2 no longer lets it change one, pytest-xdist#1386). This scheduler comes
    before the bagkit plugin's, which it extends: a golden fixture's run stays one group.
    """
    if config.getvalue("dist") != "loadgroup":
        return None
    from bagkit.pytest_plugin.scheduling import GoldenRunScheduling

    class SharedFixtureScheduling(GoldenRunScheduling):
        def _split_scope(self, nodeid: str) -> str:
            for prefix, group in SHARED_FIXTURE_GROUPS.items():
                if nodeid.startswith(prefix):
                    return group
            return super()._split_scope(nodeid)

    return SharedFixtureScheduling(config, log)


@pytest.fixture(scope="session")
def interop_dir() -> Path:
    """The rosbag2 Jazzy test bags (``BAGKIT_INTEROP_DIR``, or beside the repository).

    Skipped where they are absent, as in a user's clone; under CI (``CI=true``) their absence is
    a failure, so that CI never passes by skipping them.
    """
    if not INTEROP_DIR.is_dir():
        reason = f"rosbag2 interop bags not found at {INTEROP_DIR} (set BAGKIT_INTEROP_DIR)"
        if os.environ.get("CI", "").lower() == "true":
            pytest.fail(reason)
        pytest.skip(reason)
    return INTEROP_DIR


class ProcessesFixture:
    """Subprocesses started by one test through bagkit's ``Supervisor``, stopped on teardown."""

    def __init__(self) -> None:
        self.supervisor = Supervisor(StopPolicy(interrupt_s=10.0, terminate_s=5.0))

    def start(self, args: list[str], **popen: Any) -> subprocess.Popen[Any]:
        """Start ``args`` (``bagkit``/``fusion``/``python`` resolve to this environment);
        ``popen``: the ``Command`` fields (``stdout``, ``stderr``, ``stdin``, ``text``, ``env``,
        ``cwd``; ``preexec_fn`` is ``preexec``)."""
        if args[0] in {"bagkit", "fusion"}:
            args = [str(Path(sys.executable).with_name(args[0])), *args[1:]]
        elif args[0] == "python":
            args = [sys.executable, *args[1:]]
        if "preexec_fn" in popen:
            popen["preexec"] = popen.pop("preexec_fn")
        return self.supervisor.start(Command(Path(args[0]).name, args, **popen)).process


@pytest.fixture
def node(request: pytest.FixtureRequest) -> Iterator[Any]:
    """A node of the test (``<test module>_node``) in a context of its own, shut down after."""
    import rclpy
    from rclpy.context import Context
    from rclpy.node import Node

    context = Context()
    rclpy.init(context=context)
    test_node = Node(f"{request.module.__name__.rsplit('.', 1)[-1]}_node", context=context)
    try:
        yield test_node
    finally:
        test_node.destroy_node()
        context.try_shutdown()


@pytest.fixture
def processes() -> Iterator[ProcessesFixture]:
    """Start subprocesses that are stopped (SIGINT, SIGTERM, SIGKILL) after the test."""
    group = ProcessesFixture()
    with group.supervisor:
        yield group
