"""The CI templates of examples/ci, parsed and run on a temporary copy of examples/thermostat.

What runs: the lockstep job of each template, its shell commands in the order the CI service
runs them, each step with ``bash -e`` in the copy as working directory, under a timeout:

- GitHub Actions (``jobs.lockstep``): every ``run:`` step, with the job's ``env:``. A step runs
  as GitHub decides from its ``if:``: none (or ``success()``) after every earlier step passed,
  ``failure()`` after one failed, ``always()`` in any case. ``uses:`` steps do not run (checkout:
  the copy is the checkout; setup-python: this venv is the Python; upload-artifact: its ``path``
  entries are checked to exist). ``GITHUB_STEP_SUMMARY`` is a temporary file.
- GitLab CI (``golden-lockstep``): ``before_script`` (the job's or ``default:``'s) and
  ``script`` in one shell, then ``after_script`` in another, whatever the script did; the global
  and the job's ``variables`` in the environment. The ``artifacts`` paths and the JUnit report
  are checked to exist.

The install rule: bagkit is already installed in this venv (its ``bin`` first on PATH), so a
command line starting with ``pip install`` or ``python -m pip install`` is left out; the test
checks that the template does install bagkit there.

The live jobs start DDS and do not run here: they are parsed and checked to be well-formed
(the ROS install, LOCALHOST discovery, the same pytest options as lockstep but live mode, valid
options of this pytest, the artifacts kept on failure).
"""

from __future__ import annotations

import os
import shlex
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path
from string import Template
from typing import Any

import pytest
import yaml

REPO = Path(__file__).resolve().parents[2]
TEMPLATES = REPO / "examples" / "ci"
EXAMPLE = REPO / "examples" / "thermostat"
KP = "KP = 0.35"
INSTALL_PREFIXES = ("pip install", "python -m pip install")
STEP_TIMEOUT_S = 600


@dataclass(frozen=True, slots=True)
class Step:
    """Shell commands the CI service runs in one shell, and when it runs them."""

    name: str
    commands: list[str]
    when: str  # "success", "failure" or "always", as after the steps before it


@dataclass(frozen=True, slots=True)
class StepRun:
    step: Step
    returncode: int | None  # None: not run
    output: str


def load(name: str) -> dict[str, Any]:
    loaded = yaml.safe_load((TEMPLATES / name).read_text())
    assert isinstance(loaded, dict)
    return loaded


GITHUB_WHEN = {
    None: "success",
    "success()": "success",
    "failure()": "failure",
    "always()": "always",
}


def github_when(condition: str | None) -> str:
    assert condition in GITHUB_WHEN, f"a step condition this test does not model: {condition}"
    return GITHUB_WHEN[condition]


def github_steps(job: dict[str, Any]) -> list[Step]:
    return [
        Step(s.get("name", s["run"]), [s["run"]], github_when(s.get("if")))
        for s in job["steps"]
        if "run" in s
    ]


def gitlab_steps(config: dict[str, Any], job: dict[str, Any]) -> list[Step]:
    before = job.get("before_script", config.get("default", {}).get("before_script", []))
    after = job.get("after_script", config.get("default", {}).get("after_script", []))
    return [Step("script", [*before, *job["script"]], "success"), Step("after", after, "always")]


def strip_installs(steps: list[Step]) -> tuple[list[Step], list[str]]:
    """The steps without their install lines (bagkit is in this venv), and those lines."""
    kept: list[Step] = []
    installs: list[str] = []
    for step in steps:
        lines = [line for text in step.commands for line in text.splitlines()]
        installs += [line for line in lines if line.strip().startswith(INSTALL_PREFIXES)]
        rest = [line for line in lines if not line.strip().startswith(INSTALL_PREFIXES)]
        kept.append(Step(step.name, rest, step.when))
    return kept, installs


def run_steps(steps: list[Step], cwd: Path, env: dict[str, str]) -> list[StepRun]:
    """Run ``steps`` in order with ``bash -e`` in ``cwd``, as the CI service would."""
    runs: list[StepRun] = []
    failed = False
    for step in steps:
        skipped = {"success": failed, "failure": not failed, "always": False}[step.when]
        if skipped:
            runs.append(StepRun(step, None, ""))
            continue
        for command in step.commands:
            assert "${{" not in command, f"an expression this test cannot evaluate: {command}"
        done = subprocess.run(
            ["bash", "-e", "-c", "\n".join(step.commands)],
            cwd=cwd,
            env=env,
            capture_output=True,
            text=True,
            timeout=STEP_TIMEOUT_S,
            check=False,
        )
        runs.append(StepRun(step, done.returncode, done.stdout + done.stderr))
        failed = failed or done.returncode != 0
    return runs


def step_env(service: dict[str, str], variables: dict[str, Any]) -> dict[str, str]:
    """This environment with this venv's Python first on PATH, the CI service's variables,
    then the template's (which may refer to the service's)."""
    venv_bin = str(Path(sys.executable).parent)
    env = dict(os.environ, PATH=f"{venv_bin}{os.pathsep}{os.environ['PATH']}", CI="true")
    env["PYTHONDONTWRITEBYTECODE"] = "1"  # the core is mutated within a second
    env.update(service)
    env.update({k: Template(str(v)).safe_substitute(env) for k, v in variables.items()})
    return env


def pytest_command(commands: list[str]) -> list[str]:
    """The one pytest command line among ``commands``, as words."""
    found = [shlex.split(line) for text in commands for line in text.splitlines()]
    (words,) = [w for w in found if w[:3] == ["python", "-m", "pytest"]]
    return words


def option(words: list[str], name: str) -> str:
    (value,) = [w.split("=", 1)[1] for w in words if w.startswith(f"{name}=")]
    return value


def option_value(words: list[str], name: str) -> str:
    return words[words.index(name) + 1]


def options(words: list[str]) -> set[str]:
    return {w.split("=", 1)[0] for w in words if w.startswith("--")}


@pytest.fixture
def project(tmp_path: Path) -> Path:
    """A copy of the thermostat example, golden included: the user's checkout."""
    copy = tmp_path / "thermostat"
    ignore = shutil.ignore_patterns("golden_failures", "__pycache__", ".pytest_cache")
    shutil.copytree(EXAMPLE, copy, ignore=ignore)
    return copy


def mutate(project: Path) -> None:
    """Change the controller's gain: lockstep's outputs then differ on /thermostat/heater."""
    core = project / "thermostat" / "core.py"
    assert core.read_text().count(KP) == 1
    core.write_text(core.read_text().replace(KP, "KP = 0.37"))


def junit_counts(path: Path) -> tuple[int, int]:
    """Tests and failures of pytest's JUnit XML (one testsuite)."""
    (suite,) = ET.parse(path).getroot().iter("testsuite")
    return int(suite.attrib["tests"]), int(suite.attrib["failures"])


def outputs(runs: list[StepRun]) -> str:
    return "\n".join(f"--- {r.step.name} ({r.returncode})\n{r.output}" for r in runs)


def test_github_lockstep_job_passes_then_fails_after_a_mutation(
    project: Path, tmp_path: Path
) -> None:
    job = load("github-actions.yml")["jobs"]["lockstep"]
    steps, installs = strip_installs(github_steps(job))
    assert any("bagkit" in line for line in installs), installs
    words = pytest_command([c for s in steps for c in s.commands])
    junit = project / option(words, "--junitxml")
    verdict_file = project / option(words, "--golden-summary")
    (upload,) = [s for s in job["steps"] if str(s.get("uses", "")).startswith("actions/upload")]
    assert upload.get("if") == "always()"
    kept = upload["with"]["path"].split()
    assert "golden_failures/" in kept and f"{verdict_file.parent.name}/" in kept
    summary = tmp_path / "step_summary.md"
    service = {"GITHUB_STEP_SUMMARY": str(summary), "GITHUB_WORKSPACE": str(project)}
    env = step_env(service, job.get("env", {}))

    passed = run_steps(steps, project, env)
    assert [r.returncode for r in passed] == [0] * len(steps), outputs(passed)
    assert "| office | lockstep | passed |" in summary.read_text()
    assert summary.read_text() == verdict_file.read_text()
    assert junit_counts(junit) == (1, 0)
    assert not (project / "golden_failures").exists()

    mutate(project)
    summary.write_text("")  # GitHub gives each step an empty summary file
    failed = run_steps(steps, project, env)
    codes = {r.step.name: r.returncode for r in failed}
    assert codes["Golden fixtures (lockstep)"] == 1, outputs(failed)
    assert codes["Verdict"] == 0, outputs(failed)  # runs after the failure: if: always()
    text = summary.read_text()
    assert "## Golden fixtures: FAIL (1 of 1)" in text
    assert "| office | lockstep | failed | /thermostat/heater: data (max \\|err\\|" in text
    assert "`golden_failures/office-lockstep/report.html`" in text
    assert junit_counts(junit) == (1, 1)
    for path in kept:  # what upload-artifact keeps, on failure
        assert (project / path).is_dir(), path
    assert (project / "golden_failures" / "office-lockstep" / "report.html").is_file()


def test_gitlab_lockstep_job_passes_then_fails_after_a_mutation(project: Path) -> None:
    config = load("gitlab-ci.yml")
    job = config["golden-lockstep"]
    steps, installs = strip_installs(gitlab_steps(config, job))
    assert any("bagkit" in line for line in installs), installs
    words = pytest_command(steps[0].commands)
    artifacts = job["artifacts"]
    assert artifacts["when"] == "always"
    assert artifacts["reports"]["junit"] == option(words, "--junitxml")
    verdict_file = project / option(words, "--golden-summary")
    assert f"{verdict_file.parent.name}/" in artifacts["paths"]
    assert "golden_failures/" in artifacts["paths"]
    variables = {**config.get("variables", {}), **job.get("variables", {})}
    env = step_env({"CI_PROJECT_DIR": str(project)}, variables)
    assert env["PIP_CACHE_DIR"] == f"{project}/.cache/pip"  # what the cache keeps

    passed = run_steps(steps, project, env)
    assert [r.returncode for r in passed] == [0, 0], outputs(passed)
    assert "| office | lockstep | passed |" in passed[1].output  # the verdict, in the log
    assert junit_counts(project / artifacts["reports"]["junit"]) == (1, 0)

    mutate(project)
    failed = run_steps(steps, project, env)
    assert [r.returncode for r in failed] == [1, 0], outputs(failed)
    assert "| office | lockstep | failed | /thermostat/heater: data" in failed[1].output
    assert failed[1].output == verdict_file.read_text()
    assert junit_counts(project / artifacts["reports"]["junit"]) == (1, 1)
    for path in artifacts["paths"]:
        assert (project / path).is_dir(), path
    assert (project / "golden_failures" / "office-lockstep" / "report.html").is_file()


def live_and_lockstep_commands() -> list[tuple[str, list[str], list[str]]]:
    """Per template: its name, the pytest words of its lockstep job and of its live job."""
    github = load("github-actions.yml")["jobs"]
    gitlab = load("gitlab-ci.yml")
    return [
        (
            "github-actions.yml",
            pytest_command([s["run"] for s in github["lockstep"]["steps"] if "run" in s]),
            pytest_command([s["run"] for s in github["live"]["steps"] if "run" in s]),
        ),
        (
            "gitlab-ci.yml",
            pytest_command(gitlab["golden-lockstep"]["script"]),
            pytest_command(gitlab["golden-live"]["script"]),
        ),
    ]


def test_live_jobs_are_well_formed(project: Path) -> None:
    """The live jobs (not run: DDS) pass the lockstep job's options in live mode, and pytest
    with bagkit's plugin takes them: ``--collect-only`` with them collects the live item."""
    for name, lockstep, live in live_and_lockstep_commands():
        assert options(live) == options(lockstep), name
        assert option_value(lockstep, "--golden-mode") == "lockstep", name
        assert option_value(live, "--golden-mode") == "live", name
        assert live[3:5] == ["-m", "golden"], name  # only the fixtures run live
        assert option(live, "--junitxml") != option(lockstep, "--junitxml"), name
        collected = subprocess.run(
            [sys.executable, *live[1:], "--collect-only", "-q"],
            cwd=project,
            capture_output=True,
            text=True,
            timeout=120,
            check=False,
        )
        assert collected.returncode == 0, collected.stdout + collected.stderr
        assert collected.stdout.splitlines()[0] == "fixtures/office/spec.yaml::live", name

    github = load("github-actions.yml")["jobs"]["live"]
    assert github["env"]["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"
    runs = [s["run"] for s in github["steps"] if "run" in s]
    assert "python -m pip install 'bagkit[ros]'" in runs
    (upload,) = [s for s in github["steps"] if str(s.get("uses", "")).startswith("actions/upload")]
    assert upload["if"] == "always()" and "golden_failures/" in upload["with"]["path"].split()
    assert any(
        s.get("if") == "always()" and "GITHUB_STEP_SUMMARY" in s.get("run", "")
        for s in github["steps"]
    )

    config = load("gitlab-ci.yml")
    gitlab = config["golden-live"]
    assert gitlab["variables"]["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"
    assert "python -m pip install 'bagkit[ros]'" in config["default"]["before_script"]
    assert gitlab["artifacts"]["when"] == "always"
    assert "golden_failures/" in gitlab["artifacts"]["paths"]
    assert gitlab["artifacts"]["reports"]["junit"] == option(
        pytest_command(gitlab["script"]), "--junitxml"
    )
