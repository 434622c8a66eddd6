"""``--golden-summary FILE``: the markdown verdict of a pytest run over golden fixtures, written by
a nested pytest on a temporary copy of examples/thermostat (lockstep only: no DDS)."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from bagkit.bag import BagReader
from bagkit.regression.spec import load_spec

REPO = Path(__file__).resolve().parents[2]
EXAMPLE = REPO / "examples" / "thermostat"
KP = "KP = 0.35"
SUMMARY = "verdict/golden.md"
HEADER = ["fixture", "mode", "result", "verdict", "report"]


def pytest_in(project: Path, *args: str) -> subprocess.CompletedProcess[str]:
    # the core is mutated within a second: no bytecode cache that could hide the change
    env = dict(os.environ, PYTHONDONTWRITEBYTECODE="1")
    command = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "--golden-mode"]
    return subprocess.run(
        [*command, "lockstep", "--golden-summary", SUMMARY, *args],
        cwd=project,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )


def table(markdown: str) -> tuple[str, list[list[str]]]:
    """The headline and the rows of the verdict, cells split on unescaped pipes."""
    lines = markdown.splitlines()
    rows = [re.split(r"(?<!\\)\|", line)[1:-1] for line in lines if line.startswith("|")]
    cells = [[c.strip() for c in row] for row in rows]
    assert cells[0] == HEADER and set(cells[1][0]) <= {"-"}
    assert all(len(row) == len(HEADER) for row in cells), markdown
    return lines[0], cells[2:]


@pytest.fixture
def project(tmp_path: Path) -> Path:
    """A copy of the thermostat example, golden included."""
    copy = tmp_path / "thermostat"
    ignore = shutil.ignore_patterns("golden_failures", "__pycache__", ".pytest_cache")
    shutil.copytree(EXAMPLE, copy, ignore=ignore)
    return copy


def golden_output_counts(project: Path) -> tuple[int, int]:
    """The spec's compared topics (outputs, service events among them) and their messages."""
    spec = load_spec(project / "fixtures" / "office")
    with BagReader(spec.bag) as golden:
        return len(spec.outputs), sum(golden.topic_counts[t] for t in spec.outputs)


def test_a_pass_then_a_mutation_that_fails_lockstep(project: Path) -> None:
    passed = pytest_in(project)
    assert passed.returncode == 0, passed.stdout + passed.stderr
    head, rows = table((project / SUMMARY).read_text())
    assert head == "## Golden fixtures: pass (1)"
    topics, messages = golden_output_counts(project)
    matched = f"{topics} topics, {messages:,} messages match the golden"
    assert rows == [["office", "lockstep", "passed", matched, ""]]

    core = project / "thermostat" / "core.py"
    assert core.read_text().count(KP) == 1
    core.write_text(core.read_text().replace(KP, "KP = 0.37"))
    failed = pytest_in(project)
    assert failed.returncode == 1, failed.stdout + failed.stderr
    head, rows = table((project / SUMMARY).read_text())
    assert head == "## Golden fixtures: FAIL (1 of 1)"
    ((fixture, mode, result, verdict, report),) = rows
    assert (fixture, mode, result) == ("office", "lockstep", "failed")
    folder = project / "golden_failures" / "office-lockstep"
    topics = {t["topic"]: t for t in json.loads((folder / "report.json").read_text())["topics"]}
    (data,) = topics["/thermostat/heater"]["fields"]
    # The heater's power, then the status answers (they state the gain) of the service.
    heater, status = verdict.split("; ")
    assert heater == f"/thermostat/heater: data (max \\|err\\| {data['max_abs_error']:.3g})"
    assert status.startswith("/thermostat/status/_service_event: response[].message")
    assert set(topics) == {"/thermostat/heater", "/thermostat/status/_service_event"}
    assert report == "`golden_failures/office-lockstep/report.html`"
    assert (project / report.strip("`")).is_file()


def test_fixtures_that_cannot_run_are_errors_in_the_table(project: Path) -> None:
    fixtures = project / "fixtures"
    shutil.copytree(fixtures / "office", fixtures / "renamed")
    spec = fixtures / "renamed" / "spec.yaml"
    spec.write_text(spec.read_text().replace(":make_processors", ":make_controllers"))
    (fixtures / "garbled").mkdir()
    (fixtures / "garbled" / "spec.yaml").write_text("inputs: [/a\n")

    # a spec that does not load: pytest stops after collection, the verdict says so
    interrupted = pytest_in(project)
    assert interrupted.returncode == pytest.ExitCode.INTERRUPTED, interrupted.stdout
    markdown = (project / SUMMARY).read_text()
    head, rows = table(markdown)
    assert head == "## Golden fixtures: FAIL (1 of 1)"
    assert "pytest was interrupted: not every fixture ran." in markdown
    ((fixture, mode, result, verdict, report),) = rows
    assert (fixture, mode, result, report) == ("garbled", "-", "error", "")
    assert verdict.startswith("error: ") and "garbled/spec.yaml is not valid YAML" in verdict

    # a processor factory that is not there: an error (not compared), the others run
    shutil.rmtree(fixtures / "garbled")
    failed = pytest_in(project)
    assert failed.returncode == 1, failed.stdout + failed.stderr
    markdown = (project / SUMMARY).read_text()
    head, rows = table(markdown)
    assert head == "## Golden fixtures: FAIL (1 of 2)" and "interrupted" not in markdown
    by_fixture = {row[0]: row for row in rows}
    assert by_fixture["office"][1:3] == ["lockstep", "passed"]
    fixture, mode, result, verdict, report = by_fixture["renamed"]
    assert (mode, result, report) == ("lockstep", "error", "")
    assert "thermostat.core:make_controllers" in verdict and "no callable" in verdict


def test_the_verdict_gathers_xdist_workers(project: Path) -> None:
    fixtures = project / "fixtures"
    shutil.copytree(fixtures / "office", fixtures / "lobby")
    result = pytest_in(project, "-n", "2")
    assert result.returncode == 0, result.stdout + result.stderr
    head, rows = table((project / SUMMARY).read_text())
    assert head == "## Golden fixtures: pass (2)"
    assert sorted(row[:3] for row in rows) == [
        ["lobby", "lockstep", "passed"],
        ["office", "lockstep", "passed"],
    ]


def test_a_summary_that_cannot_be_written_is_one_error_line(project: Path) -> None:
    (project / "verdict").mkdir()
    (project / "verdict" / "golden.md").mkdir()  # SUMMARY names a directory
    refused = pytest_in(project)
    assert refused.returncode == pytest.ExitCode.USAGE_ERROR
    assert refused.stderr.strip() == f"ERROR: --golden-summary {SUMMARY}: a directory, not a file"

    (project / "verdict" / "golden.md").rmdir()
    (project / "verdict").rmdir()
    (project / "verdict").write_text("")  # a file where the verdict's folder should be
    unwritable = pytest_in(project)
    assert unwritable.returncode == pytest.ExitCode.USAGE_ERROR, unwritable.stdout
    assert f"\nerror: --golden-summary {SUMMARY}: File exists\n" in unwritable.stdout
    assert "1 passed" in unwritable.stdout  # the fixtures ran
    assert "Traceback" not in unwritable.stdout + unwritable.stderr
