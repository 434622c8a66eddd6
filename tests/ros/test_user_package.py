"""A user's own interface package, end to end.

my_robot_msgs (a report with a std_msgs/Header, fixed and variable arrays, an array of its own
nested message, a string; a service) is built once per session as ROS users build it: colcon
and the rosidl toolchain from the project's dev extra, into a temporary workspace, with the
CMake override that docs/install.md gives. Then, in the environment of its sourced
``install/local_setup.bash``: ``bagkit record`` of a node publishing that type and calling that
service, ``info``, ``echo``, ``export``, ``stats summary``, ``replay`` to a subscriber of that
type, and a golden fixture of it under the pytest plugin. Values are checked against what the
publisher printed it published.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from user_workspace import (
    BAGKIT,
    BUILD_TIMEOUT_S,
    CMAKE_OVERRIDE,
    EVENT_TYPE,
    EVENTS_TOPIC,
    LISTENER,
    REPORT_TOPIC,
    REPORT_TYPE,
    REPORTS,
    USER_PROJECT,
    Recording,
    Workspace,
    background,
    json_lines,
    run,
)

INSTALL_DOC = Path(__file__).resolve().parents[2] / "docs" / "install.md"

# The first test to ask for the workspace builds it within its own time limit.
pytestmark = pytest.mark.timeout(BUILD_TIMEOUT_S + 300)


@pytest.mark.ros
def test_record_keeps_every_report_and_the_service_events(recording: Recording) -> None:
    assert len(recording.published) == REPORTS
    # The whole type name, however the table lays it out.
    assert REPORT_TYPE in recording.report
    # At 80 columns the long type names make the table one record per row (cli/tables.py).
    for topic, count in ((REPORT_TOPIC, REPORTS), (EVENTS_TOPIC, 4)):
        record = rf"{topic}\n(?: +\S.*\n)*? +messages {count}, lost 0\b"
        assert re.search(record, recording.report), recording.report


@pytest.mark.ros
def test_info_names_the_users_types(recording: Recording, workspace: Workspace) -> None:
    out = run([BAGKIT, "info", str(recording.bag), "--format", "json"], workspace.env, Path.cwd())
    info = json.loads(out.stdout[out.stdout.index("{") :])
    topics = {t["topic"]: (t["type"], t["count"]) for t in info["topics"]}
    assert topics == {REPORT_TOPIC: (REPORT_TYPE, REPORTS), EVENTS_TOPIC: (EVENT_TYPE, 4)}
    assert info["problems"] == []


@pytest.mark.ros
def test_echo_prints_what_was_published(recording: Recording, workspace: Workspace) -> None:
    echo = [BAGKIT, "echo", str(recording.bag), REPORT_TOPIC, "--format", "json"]
    echoed = json_lines(run(echo, workspace.env, Path.cwd()).stdout)
    assert [m["data"] for m in echoed] == recording.published
    assert {m["topic"] for m in echoed} == {REPORT_TOPIC}
    # The offline tools need only the definitions stored in the bag: no sourced workspace.
    assert json_lines(run(echo, dict(os.environ), Path.cwd()).stdout) == echoed


@pytest.mark.ros
def test_echo_of_the_service_events(recording: Recording, workspace: Workspace) -> None:
    echo = [BAGKIT, "echo", str(recording.bag), EVENTS_TOPIC, "--format", "json"]
    events = [m["data"] for m in json_lines(run(echo, workspace.env, Path.cwd()).stdout)]
    # Request sent and received, response sent and received; each carries its half.
    assert sorted(e["info"]["event_type"] for e in events) == [0, 1, 2, 3]
    requests = [r for e in events for r in e["request"]]
    responses = [r for e in events for r in e["response"]]
    assert requests == [{"limit": float(np.float32(0.8))}] * 2
    assert responses == [{"accepted": True, "message": "charging stops at 80%"}] * 2


@pytest.mark.ros
def test_export_columns_hold_the_published_values(
    recording: Recording, workspace: Workspace
) -> None:
    out = recording.bag.parent / "report.parquet"
    export = [BAGKIT, "export", str(recording.bag), "-t", REPORT_TOPIC, "-o", str(out)]
    run(export, workspace.env, Path.cwd())
    table = pd.read_parquet(out)
    published = recording.published
    assert table["header.stamp.sec"].tolist() == [m["header"]["stamp"]["sec"] for m in published]
    assert table["header.frame_id"].tolist() == [m["header"]["frame_id"] for m in published]
    assert table["voltage"].tolist() == [m["voltage"] for m in published]
    for k in range(4):
        column = table[f"cell_voltages[{k}]"].tolist()
        assert column == [m["cell_voltages"][k] for m in published]
    cells = [[c["voltage"] for c in m["cells"]] for m in published]
    assert [list(v) for v in table["cells[].voltage"]] == cells
    codes = [m["error_codes"] for m in published]
    assert [list(v) for v in table["error_codes[]"]] == codes
    assert table["status"].tolist() == [m["status"] for m in published]


@pytest.mark.ros
def test_stats_summary_of_the_users_fields(recording: Recording, workspace: Workspace) -> None:
    stats = [BAGKIT, "stats", "summary", str(recording.bag), "-t", REPORT_TOPIC, "--format", "json"]
    out = run(stats, workspace.env, Path.cwd()).stdout
    (topic,) = json.loads(out[out.index("{") :])["topics"]
    assert (topic["type"], topic["count"], topic["undecodable"]) == (REPORT_TYPE, REPORTS, 0)
    fields = {f["field"]: f for f in topic["fields"]}
    expected = {
        "voltage": [m["voltage"] for m in recording.published],
        "cell_voltages[3]": [m["cell_voltages"][3] for m in recording.published],
        "cells[].temperature": [c["temperature"] for m in recording.published for c in m["cells"]],
        "error_codes[]": [code for m in recording.published for code in m["error_codes"]],
    }
    for name, values in expected.items():
        field = fields[name]
        assert field["count"] == len(values), name
        assert (field["min"], field["max"]) == (min(values), max(values)), name
        assert field["mean"] == pytest.approx(np.mean(values), rel=1e-12), name


@pytest.mark.ros
def test_replay_to_a_subscriber_of_the_users_type(
    recording: Recording, workspace: Workspace, project: Path
) -> None:
    with background(LISTENER, workspace.env, project) as listener:
        replay = [BAGKIT, "replay", str(recording.bag), "--topics", REPORT_TOPIC, "--rate", "4"]
        replay += ["--wait-for", REPORT_TOPIC, "--format", "json"]
        out = run(replay, workspace.env, project).stdout
        stdout, stderr = listener.communicate(timeout=60)
    assert listener.returncode == 0, stderr
    assert json_lines(stdout) == recording.published
    (topic,) = json.loads(out[out.index("{") :])["topics"]
    assert (topic["type"], topic["messages"], topic["unreadable"]) == (REPORT_TYPE, REPORTS, 0)


@pytest.mark.ros
def test_golden_fixture_under_the_pytest_plugin(workspace: Workspace, tmp_path: Path) -> None:
    """The user records a golden of the pack check, pytest passes on it; a changed threshold
    fails it, naming the topic and the fields."""
    project = tmp_path / "battery_project"
    shutil.copytree(USER_PROJECT, project, ignore=shutil.ignore_patterns("my_robot_msgs"))
    run([BAGKIT, "golden", "record", "fixtures/pack"], workspace.env, project, timeout=240)
    pytest_args = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-v"]
    passed = run(pytest_args, workspace.env, project, timeout=300)
    assert "fixtures/pack/spec.yaml::lockstep PASSED" in passed.stdout
    assert "fixtures/pack/spec.yaml::live PASSED" in passed.stdout

    core = project / "battery" / "core.py"
    assert core.read_text().count("LOW_CELL_V = 3.3\n") == 1
    core.write_text(core.read_text().replace("LOW_CELL_V = 3.3\n", "LOW_CELL_V = 3.2\n"))
    failed = subprocess.run(
        [*pytest_args, "--golden-mode", "lockstep"],
        cwd=project,
        env=workspace.env,
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert failed.returncode == 1, failed.stdout + failed.stderr
    assert "pack (lockstep): FAIL" in failed.stdout
    report = json.loads((project / "golden_failures" / "pack-lockstep" / "report.json").read_text())
    (checked,) = [t for t in report["topics"] if not t["passed"]]
    assert checked["topic"] == "/battery/checked"
    assert "status" in checked["failed_fields"]
    lengths = {d["field"] for d in checked["divergences"] if d["kind"] == "length"}
    assert lengths == {"error_codes[]"}


def test_the_install_doc_gives_the_cmake_override() -> None:
    """docs/install.md shows the override file the test builds with, verbatim."""
    doc = INSTALL_DOC.read_text()
    section = doc[doc.index("## Your own message packages") :]
    assert CMAKE_OVERRIDE.read_text() in section
