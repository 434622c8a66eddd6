"""Fixtures of the ROS tests: a known-stamp bag, listeners closed after each test, a user's
interface package built and sourced (once per session) and a bag recorded from its nodes."""

from __future__ import annotations

import os
import shutil
import signal
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from replay_harness import (
    Listener,
    write_test_bag,
)
from user_workspace import (
    BAGKIT,
    EVENTS_TOPIC,
    REPORT_TOPIC,
    REPORTS,
    USER_PROJECT,
    Recording,
    Workspace,
    background,
    build_workspace,
    json_lines,
    run,
)


@pytest.fixture
def listener_factory() -> Iterator[type[Listener]]:
    listeners: list[Listener] = []

    class Tracked(Listener):
        def __init__(self, topics: dict[str, type]) -> None:
            super().__init__(topics)
            listeners.append(self)

    yield Tracked
    for listener in listeners:
        listener.close()


@pytest.fixture(scope="module")
def test_bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_test_bag(tmp_path_factory.mktemp("replay") / "known")


@pytest.fixture(scope="session")
def workspace(tmp_path_factory: pytest.TempPathFactory) -> Workspace:
    """my_robot_msgs built by colcon into a temporary workspace, and sourced."""
    root = tmp_path_factory.mktemp("colcon_ws")
    return build_workspace(root, USER_PROJECT / "my_robot_msgs")


@pytest.fixture(scope="session")
def project(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The user's nodes (package ``battery``), without the interface sources."""
    path = tmp_path_factory.mktemp("user_project") / "battery_project"
    shutil.copytree(USER_PROJECT, path, ignore=shutil.ignore_patterns("my_robot_msgs", "*.cmake"))
    return path


@pytest.fixture(scope="session")
def recording(workspace: Workspace, project: Path) -> Recording:
    """``bagkit record`` while the monitor publishes REPORTS reports and calls its service."""
    bag = project.parent / "battery_bag"
    record = [BAGKIT, "record", REPORT_TOPIC, EVENTS_TOPIC, "-o", str(bag)]
    with background(record, workspace.env, project) as recorder:
        try:
            # The monitor waits for the recorder's subscriptions and for its reports' acks.
            monitor = [sys.executable, "-m", "battery.monitor", "--count", str(REPORTS)]
            published = json_lines(run(monitor, workspace.env, project).stdout)
        finally:
            os.killpg(recorder.pid, signal.SIGINT)
            stdout, stderr = recorder.communicate(timeout=60)
    assert recorder.returncode == 130, stderr
    return Recording(bag, published, stdout)
