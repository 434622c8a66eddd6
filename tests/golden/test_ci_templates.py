"""The CI templates of examples/ci, parsed and run on a temporary copy of examples/thermostat.

What runs: a job of each template, its shell commands in the order the CI service runs them,
each step with ``bash -e`` in the copy as working directory, under a timeout:

- GitHub Actions (``jobs.lockstep``, ``jobs.live``): every ``run:`` step, with the job's
  ``env:``. A step runs as GitHub decides from its ``if:``: none (or ``success()``) after every
  earlier step passed, ``failure()`` after one failed, ``always()`` in any case. ``uses:``
  steps do not run (checkout: the copy is the checkout; setup-python: this venv is the Python;
  upload-artifact: its ``path`` entries are checked to exist). ``GITHUB_STEP_SUMMARY`` is a
  temporary file, emptied before each run.
- GitLab CI (``golden-lockstep``, ``golden-live``): ``before_script`` (the job's or
  ``default:``'s) and ``script`` in one shell, then ``after_script`` in another, whatever the
  script did; the global and the job's ``variables`` in the environment (``CI_PROJECT_DIR``:
  the copy). The ``artifacts`` paths and the JUnit report are checked to exist.

The install rule: bagkit is already installed in this venv (its ``bin`` first on PATH), so a
command line starting with ``pip install`` or ``python -m pip install`` is left out; the test
checks that the template does install ``bagkit[ros]`` there.

Each job runs on the example as it is (passes), then after ``KP = 0.37`` (fails, the verdict
naming /thermostat/heater, the report kept). The lockstep jobs always run. The live jobs start
DDS: they run only with the ``ros`` marker, on this session's ``ROS_DOMAIN_ID`` (set by
tests/conftest.py) in place of the template's, which would meet other runs on a shared
machine; without DDS they are still parsed and checked (the lockstep job's pytest options in
live mode, which this pytest takes: ``--collect-only`` collects the live item).
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
    """Change the controller's gain: the heater's outputs then differ from the golden's."""
    core = project / "thermostat" / "core.py"
    assert core.read_text().count(KP) == 1
    core.write_text(core.read_text().replace(KP, "KP = 0.37"))


def junit_counts(path: Path) -> tuple[int, int]:
    """Tests and failures of pytest's JUnit XML (one testsuite)."""
    (suite,) = ET.parse(path).getroot().iter("testsuite")
    return int(suite.attrib["tests"]), int(suite.attrib["failures"])


def outputs(runs: list[StepRun]) -> str:
    return "\n".join(f"--- {r.step.name} ({r.returncode})\n{r.output}" for r in runs)


@dataclass(frozen=True, slots=True)
class Job:
    """A template's job, ready to run on the copy: its steps, environment and products."""

    steps: list[Step]
    env: dict[str, str]
    pytest_words: list[str]
    kept: list[str]  # the artifact's paths, kept on failure too
    junit: str  # where the CI service reads the JUnit XML
    summary: Path | None  # GitHub's step summary file; GitLab: the verdict is in the log

    def run(self, project: Path) -> tuple[list[StepRun], str]:
        """Run the job; its step results and the verdict as the CI service shows it."""
        if self.summary is not None:
            self.summary.write_text("")
        runs = run_steps(self.steps, project, self.env)
        return runs, (self.summary.read_text() if self.summary else runs[-1].output)


def installs_bagkit(installs: list[str], variables: dict[str, Any]) -> None:
    """One install line, of the requirement the template's ``BAGKIT`` names (with ``ros``)."""
    assert [line.strip() for line in installs] == ['python -m pip install "$BAGKIT"']
    assert str(variables["BAGKIT"]).startswith("bagkit[ros] @ git+https://")


def github_job(name: str, project: Path, summary: Path) -> Job:
    workflow = load("github-actions.yml")
    job = workflow["jobs"][name]
    steps, installs = strip_installs(github_steps(job))
    installs_bagkit(installs, workflow["env"])
    (upload,) = [s for s in job["steps"] if str(s.get("uses", "")).startswith("actions/upload")]
    assert upload["if"] == "always()"
    (verdict,) = [s for s in steps if "GITHUB_STEP_SUMMARY" in "\n".join(s.commands)]
    assert verdict.when == "always"
    service = {"GITHUB_STEP_SUMMARY": str(summary), "GITHUB_WORKSPACE": str(project)}
    words = pytest_command([c for s in steps for c in s.commands])
    kept = upload["with"]["path"].split()
    return Job(steps, step_env(service, job.get("env", {})), words, kept, "", summary)


def gitlab_job(name: str, project: Path) -> Job:
    config = load("gitlab-ci.yml")
    job = config[name]
    steps, installs = strip_installs(gitlab_steps(config, job))
    installs_bagkit(installs, config["variables"])
    artifacts = job["artifacts"]
    assert artifacts["when"] == "always"
    variables = {**config.get("variables", {}), **job.get("variables", {})}
    env = step_env({"CI_PROJECT_DIR": str(project)}, variables)
    assert env["PIP_CACHE_DIR"] == f"{project}/.cache/pip"  # in the project: GitLab caches it
    words = pytest_command(steps[0].commands)
    return Job(steps, env, words, artifacts["paths"], artifacts["reports"]["junit"], None)


def make_job(template: str, mode: str, project: Path, tmp_path: Path) -> Job:
    if template == "github":
        return github_job(mode, project, tmp_path / "step_summary.md")
    return gitlab_job(f"golden-{mode}", project)


def check_pass_then_fail(job: Job, project: Path, mode: str) -> None:
    """The job passes on the example, then fails on the mutated one with a verdict and a report."""
    junit = option(job.pytest_words, "--junitxml")
    assert job.junit in {"", junit}  # GitLab reads the file pytest writes
    verdict_file = project / option(job.pytest_words, "--golden-summary")
    assert "golden_failures/" in job.kept and f"{verdict_file.parent.name}/" in job.kept
    pytest_step = next(i for i, s in enumerate(job.steps) if "pytest" in "\n".join(s.commands))

    runs, shown = job.run(project)
    assert [r.returncode for r in runs] == [0] * len(runs), outputs(runs)
    assert shown == verdict_file.read_text()
    assert f"| office | {mode} | passed |" in shown
    assert junit_counts(project / junit) == (1, 0)
    assert not (project / "golden_failures").exists()

    mutate(project)
    runs, shown = job.run(project)
    codes = [r.returncode for r in runs]
    assert codes[pytest_step] == 1, outputs(runs)
    # every later step runs: they keep the verdict and the artifacts after the failure
    assert codes[pytest_step + 1 :] == [0] * (len(runs) - pytest_step - 1), outputs(runs)
    assert shown == verdict_file.read_text()
    assert "## Golden fixtures: FAIL (1 of 1)" in shown
    assert f"| office | {mode} | failed | /thermostat/heater: data (max \\|err\\|" in shown
    assert f"`golden_failures/office-{mode}/report.html`" in shown
    assert junit_counts(project / junit) == (1, 1)
    for path in job.kept:
        assert (project / path).is_dir(), path
    assert (project / "golden_failures" / f"office-{mode}" / "report.html").is_file()


@pytest.mark.parametrize("template", ["github", "gitlab"])
def test_lockstep_job_passes_then_fails_after_a_mutation(
    template: str, project: Path, tmp_path: Path
) -> None:
    check_pass_then_fail(make_job(template, "lockstep", project, tmp_path), project, "lockstep")


@pytest.mark.ros
@pytest.mark.parametrize("template", ["github", "gitlab"])
def test_live_job_passes_then_fails_after_a_mutation(
    template: str, project: Path, tmp_path: Path
) -> None:
    job = make_job(template, "live", project, tmp_path)
    assert job.env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"
    job.env["ROS_DOMAIN_ID"] = os.environ["ROS_DOMAIN_ID"]  # this session's, not the template's
    check_pass_then_fail(job, project, "live")


@pytest.mark.parametrize("template", ["github", "gitlab"])
def test_live_job_is_the_lockstep_job_in_live_mode(
    template: str, project: Path, tmp_path: Path
) -> None:
    """Without DDS: the live job passes the lockstep job's options in live mode, and pytest
    with bagkit's plugin takes them (``--collect-only`` collects the live item)."""
    lockstep = make_job(template, "lockstep", project, tmp_path).pytest_words
    live_job = make_job(template, "live", project, tmp_path)
    live = live_job.pytest_words
    assert live_job.env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"
    assert options(live) == options(lockstep)
    assert option_value(lockstep, "--golden-mode") == "lockstep"
    assert option_value(live, "--golden-mode") == "live"
    assert live[3:5] == ["-m", "golden"]  # only the fixtures run live
    assert option(live, "--junitxml") != option(lockstep, "--junitxml")
    collected = subprocess.run(
        [sys.executable, *live[1:], "--collect-only", "-q"],
        cwd=project,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert collected.returncode == 0, collected.stdout + collected.stderr
    assert collected.stdout.splitlines()[0] == "fixtures/office/spec.yaml::live"
