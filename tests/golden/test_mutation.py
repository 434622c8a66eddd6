"""Mutation proof: the golden fixtures (collected by bagkit's pytest plugin) catch a 1% change
of a fusion constant and a changed alert threshold, with a report naming the topic and field.

Each mutation is made in a temporary copy of the repository, whose golden lockstep tests then
run in a pytest subprocess importing the copy (PYTHONPATH), plugin included.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[2]
EXPONENT = "_EXPONENT = 0.190263"
PRESSURE_ERROR_BOUNDS = "error: [70000.0, 108000.0]"
SUMMARY_ANSWER = 'f"{t}: {m.messages}"'
SUMMARY_ANSWER_MUTATED = 'f"{t}: {m.messages + 1}"'


def mutated_copy(tmp_path: Path, file: str, old: str, new: str) -> Path:
    copy = tmp_path / "repo"
    # The bytecode caches come along (copytree keeps the sources' times, so each stays valid; the
    # mutated file's does not): the subprocesses do not compile bagkit again, each of them, under
    # PYTHONDONTWRITEBYTECODE.
    ignore = shutil.ignore_patterns("golden_failures", ".*")
    for name in ("bagkit", "fusion", "fixtures"):
        shutil.copytree(REPO / name, copy / name, ignore=ignore)
    shutil.copy2(REPO / "pyproject.toml", copy / "pyproject.toml")
    target = copy / file
    text = target.read_text()
    assert text.count(old) == 1, f"{old!r} not found once in {file}: the mutation is stale"
    target.write_text(text.replace(old, new))
    return copy


def run_golden(copy: Path, fixture: str) -> tuple[subprocess.CompletedProcess[str], dict[str, Any]]:
    env = dict(os.environ, PYTHONPATH=str(copy))
    result = subprocess.run(
        [
            sys.executable,
            "-m",
            "pytest",
            "-q",
            "-p",
            "no:cacheprovider",
            f"fixtures/{fixture}",
            "--golden-mode",
            "lockstep",
        ],
        cwd=copy,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    report_file = copy / "golden_failures" / f"{fixture}-lockstep" / "report.json"
    report = json.loads(report_file.read_text()) if report_file.exists() else {}
    return result, report


def failing(report: dict[str, Any]) -> dict[str, dict[str, Any]]:
    return {t["topic"]: t for t in report.get("topics", []) if not t["passed"]}


def test_barometric_exponent_off_by_one_percent_fails(tmp_path: Path) -> None:
    copy = mutated_copy(
        tmp_path, "fusion/estimation/isa.py", EXPONENT, f"_EXPONENT = {0.190263 * 1.01!r}"
    )
    result, report = run_golden(copy, "nominal")
    assert result.returncode == 1, result.stdout + result.stderr
    assert "golden_failures/nominal-lockstep" in result.stdout
    topics = failing(report)
    assert "pose.pose.position.z" in topics["/fusion/baro_altitude"]["failed_fields"]
    assert "pose.pose.position.z" in topics["/fusion/odometry"]["failed_fields"]
    assert "/alerts" not in topics
    assert (
        copy / "golden_failures" / "nominal-lockstep" / "fusion_baro_altitude.png"
    ).stat().st_size > 0
    # the pytest failure message itself names the topic and the field
    assert "/fusion/baro_altitude" in result.stdout and "pose.pose.position.z" in result.stdout


def test_changed_alert_threshold_fails(tmp_path: Path) -> None:
    # 110 kPa spikes now stay below the error bound: the pressure alert drops to WARN.
    copy = mutated_copy(
        tmp_path, "fusion/config/params.yaml", PRESSURE_ERROR_BOUNDS, "error: [70000.0, 112000.0]"
    )
    result, report = run_golden(copy, "faults")
    assert result.returncode == 1, result.stdout + result.stderr
    topics = failing(report)
    assert set(topics) == {"/alerts"}
    kinds = {
        (d["kind"], d["field"], d["golden"] or d["candidate"])
        for d in topics["/alerts"]["divergences"]
    }
    assert ("missing_event", "alert_system: pressure", "ERROR") in kinds
    assert ("extra_event", "alert_system: pressure", "WARN") in kinds
    assert "alert_system: pressure" in result.stdout


def test_changed_summary_service_handler_fails(tmp_path: Path) -> None:
    # The data logger's /logger/get_summary answers count one message too many: the
    # recorded calls, answered again in lockstep, differ in the response.
    copy = mutated_copy(
        tmp_path, "fusion/processors/data_logger.py", SUMMARY_ANSWER, SUMMARY_ANSWER_MUTATED
    )
    result, report = run_golden(copy, "fast")
    assert result.returncode == 1, result.stdout + result.stderr
    topics = failing(report)
    assert set(topics) == {"/logger/get_summary/_service_event"}
    assert topics["/logger/get_summary/_service_event"]["failed_fields"] == ["response[].message"]


def test_unmutated_copy_passes(tmp_path: Path) -> None:
    """The control: the same harness on an unchanged copy passes, so the failures above are
    the mutations' doing."""
    copy = mutated_copy(tmp_path, "fusion/estimation/isa.py", EXPONENT, EXPONENT)
    result, _ = run_golden(copy, "nominal")
    assert result.returncode == 0, result.stdout + result.stderr
