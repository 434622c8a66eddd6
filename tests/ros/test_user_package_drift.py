"""A user's message changes: my_robot_msgs version 2 installed, bags and a golden of version 1.

Version 2 (built here with colcon, as version 1 in conftest.py) adds ``float32
max_temperature`` to BatteryReport and ``float32 applied_limit`` to SetChargeLimit's response.
In version 2's sourced environment: the golden check of a fixture recorded with version 1
fails naming the drift, ``bagkit golden migrate`` makes it pass; ``bagkit migrate`` with a
rules file computes the new field from the old ones (the service events migrated too); ``play
--on-drift migrate`` delivers every report to a subscriber of version 2, ``skip`` none.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from user_workspace import (
    BAGKIT,
    BUILD_TIMEOUT_S,
    EVENTS_TOPIC,
    LISTENER,
    REPORT_TOPIC,
    REPORT_TYPE,
    REPORTS,
    USER_PROJECT,
    Recording,
    Workspace,
    background,
    build_workspace,
    json_lines,
    run,
)

pytestmark = [pytest.mark.ros, pytest.mark.timeout(2 * BUILD_TIMEOUT_S + 300)]
ADDED = "added: max_temperature (float32)"


@pytest.fixture(scope="module")
def workspace_v2(tmp_path_factory: pytest.TempPathFactory) -> Workspace:
    """my_robot_msgs version 2, built and sourced."""
    sources = tmp_path_factory.mktemp("v2_sources") / "my_robot_msgs"
    shutil.copytree(USER_PROJECT / "my_robot_msgs", sources)
    report = sources / "msg" / "BatteryReport.msg"
    report.write_text(report.read_text() + "float32 max_temperature  # the warmest cell\n")
    service = sources / "srv" / "SetChargeLimit.srv"
    service.write_text(service.read_text() + "float32 applied_limit\n")
    return build_workspace(tmp_path_factory.mktemp("colcon_ws_v2"), sources)


def _bagkit(args: list[str], env: dict[str, str], cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [BAGKIT, *args], cwd=cwd, env=env, capture_output=True, text=True, timeout=300, check=False
    )


def test_golden_check_names_the_drift_and_migrate_makes_it_pass(
    workspace: Workspace, workspace_v2: Workspace, recording: Recording, tmp_path: Path
) -> None:
    project = tmp_path / "battery_project"
    shutil.copytree(USER_PROJECT, project, ignore=shutil.ignore_patterns("my_robot_msgs"))
    # A golden of version 1: the recording's reports, outputs from lockstep under version 1.
    add = [
        "golden",
        "add",
        "fixtures/pack_v1",
        "--from",
        str(recording.bag),
        "--like",
        "fixtures/pack",
    ]
    run([BAGKIT, *add], workspace.env, project)
    pytest_args = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "--golden-mode",
                   "lockstep", "fixtures/pack_v1"]  # fmt: skip
    run(pytest_args, workspace.env, project, timeout=300)

    failed = subprocess.run(pytest_args, cwd=project, env=workspace_v2.env, capture_output=True,
                            text=True, timeout=300, check=False)  # fmt: skip
    assert failed.returncode == 1, failed.stdout + failed.stderr
    # The failure summary keeps to 80 columns: a longer line goes on, indented, on the next.
    assert (
        f"{REPORT_TOPIC} ({REPORT_TYPE}): the golden's definition differs from the installed "
        f"one: {ADDED}" in " ".join(failed.stdout.split())
    )
    assert "max |err|" not in failed.stdout

    migrated = _bagkit(["golden", "migrate", "fixtures/pack_v1"], workspace_v2.env, project)
    assert migrated.returncode == 0, migrated.stdout + migrated.stderr
    assert f"pack_v1: {REPORT_TOPIC} migrated ({REPORTS} messages: {ADDED})" in migrated.stdout
    assert "pack_v1 (lockstep): pass" in migrated.stdout
    passed = run(pytest_args, workspace_v2.env, project, timeout=300)
    assert "1 passed" in passed.stdout


def test_migrate_with_rules_and_the_service_events(
    workspace_v2: Workspace, recording: Recording, tmp_path: Path
) -> None:
    rules = tmp_path / "v2.yaml"
    rules.write_text(
        "my_robot_msgs/msg/BatteryReport:\n"
        "  compute:\n"
        "    max_temperature: if(len(cells) > 0, max(cells[*].temperature), 0)\n"
    )
    out = tmp_path / "v2_bag"
    done = _bagkit(["migrate", str(recording.bag), "-o", str(out), "--rules", str(rules),
                    "--format", "json"], workspace_v2.env, tmp_path)  # fmt: skip
    assert done.returncode == 0, done.stderr
    migrated = {m["topic"]: m for m in json.loads(done.stdout)["migrated"]}
    assert migrated[REPORT_TOPIC]["changes"] == [ADDED]
    assert migrated[EVENTS_TOPIC]["changes"] == ["added: response[*].applied_limit (float32)"]
    assert migrated[REPORT_TOPIC]["rules"] == [
        "v2.yaml: my_robot_msgs/msg/BatteryReport compute max_temperature"
    ]

    echo = [BAGKIT, "echo", str(out), REPORT_TOPIC, "--format", "json"]
    reports = [m["data"] for m in json_lines(run(echo, workspace_v2.env, tmp_path).stdout)]
    expected = [
        float(np.float32(max((c["temperature"] for c in p["cells"]), default=0)))
        for p in recording.published
    ]
    assert [r["max_temperature"] for r in reports] == expected
    assert [{k: v for k, v in r.items() if k != "max_temperature"} for r in reports] == (
        recording.published
    )
    events = [BAGKIT, "echo", str(out), EVENTS_TOPIC, "--format", "json"]
    responses = [
        r for m in json_lines(run(events, workspace_v2.env, tmp_path).stdout)
        for r in m["data"]["response"]
    ]  # fmt: skip
    assert (
        responses
        == [{"accepted": True, "message": "charging stops at 80%", "applied_limit": 0.0}] * 2
    )
    doctor = _bagkit(["doctor", str(out), "--against-installed"], workspace_v2.env, tmp_path)
    assert doctor.returncode == 0, doctor.stdout


def test_play_on_drift_to_a_subscriber_of_version_2(
    workspace_v2: Workspace, recording: Recording
) -> None:
    play = [BAGKIT, "play", str(recording.bag), "--topics", REPORT_TOPIC, "--rate", "4",
            "--disable-keyboard-controls"]  # fmt: skip
    skipped = _bagkit([*play[1:]], workspace_v2.env, recording.bag.parent)
    assert skipped.returncode == 2
    assert f"{REPORT_TOPIC}: its definition drifted from the installed one ({ADDED}" in (
        skipped.stderr
    )

    project = USER_PROJECT
    with background(LISTENER, workspace_v2.env, project) as listener:
        migrated = run([*play, "--on-drift", "migrate", "--wait-for", REPORT_TOPIC],
                       workspace_v2.env, project)  # fmt: skip
        stdout, stderr = listener.communicate(timeout=60)
    assert listener.returncode == 0, stderr
    assert "each message migrated to the installed definition" in migrated.stderr
    received = json_lines(stdout)
    assert [r.pop("max_temperature") for r in received] == [0.0] * REPORTS
    assert received == recording.published
