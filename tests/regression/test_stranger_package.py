"""Proof with a stranger's package: the thermostat of examples/ (its own node, Python core,
topics and message types; no fusion), copied without its golden into a temporary directory.
bagkit records a golden from its live system, as long as its spec asks (the example once got
9.8 s of 12: the processes' start-up came off it), and ``pytest`` there, with nothing but
bagkit's plugin and a pytest.ini naming the fixture root, passes; one changed constant fails
it, naming the topic and the field. The committed example passes as it stands."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

from bagkit.bag import BagReader
from bagkit.regression.spec import load_spec

REPO = Path(__file__).resolve().parents[2]
EXAMPLE = REPO / "examples" / "thermostat"
KP = "KP = 0.35"

pytestmark = pytest.mark.ros


def run(
    args: list[str], cwd: Path, timeout: float = 240, **env_vars: str
) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, PYTHONDONTWRITEBYTECODE="1", **env_vars)
    return subprocess.run(
        args, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout, check=False
    )


def pytest_in(project: Path, *args: str, **env_vars: str) -> subprocess.CompletedProcess[str]:
    return run(
        [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", *args], project, **env_vars
    )


@pytest.fixture
def stranger(tmp_path: Path) -> Path:
    """The thermostat package and its spec, without a golden."""
    project = tmp_path / "thermostat"
    ignore = shutil.ignore_patterns("golden", "golden_failures", "__pycache__")
    shutil.copytree(EXAMPLE, project, ignore=ignore)
    assert not (project / "fixtures" / "office" / "golden").exists()
    return project


def test_record_a_golden_pass_then_fail_on_a_changed_constant(stranger: Path) -> None:
    bagkit = str(Path(sys.executable).with_name("bagkit"))
    # A domain of its own: nothing of the tests before it, which run the same example's nodes on
    # the process's domain, reaches this recorder.
    domain = os.environ["BAGKIT_TEST_SPARE_DOMAIN_ID"]
    recorded = run([bagkit, "golden", "record", "fixtures/office"], stranger, ROS_DOMAIN_ID=domain)
    assert recorded.returncode == 0, recorded.stdout + recorded.stderr
    asked = load_spec(stranger / "fixtures" / "office").duration_s
    with BagReader(stranger / "fixtures" / "office" / "golden") as golden:
        counts = golden.topic_counts
        # On failure, record_golden's stderr names each topic's first and last second.
        assert (golden.end_ns - golden.start_ns) / 1e9 >= asked, recorded.stderr
    assert "asked" not in recorded.stderr  # no "the golden spans X s of the Y s asked"
    # The simulated sensor publishes at 10 Hz for the whole duration; one heater command per
    # reading (computed again by lockstep).
    assert counts["/thermostat/temperature"] / asked >= 9.5
    assert counts["/thermostat/heater"] == counts["/thermostat/temperature"]
    # The technician's status calls, every 2 s: the server's request and response events.
    events = counts["/thermostat/status/_service_event"]
    assert events >= 2 and events % 2 == 0

    # The package as recorded, and a copy with one changed constant: checked at once, each
    # copy's live run on a domain of its own.
    changed = stranger.with_name("changed")
    shutil.copytree(stranger, changed)
    core = changed / "thermostat" / "core.py"
    assert core.read_text().count(KP) == 1
    core.write_text(core.read_text().replace(KP, "KP = 0.37"))
    with ThreadPoolExecutor(2) as pool:
        passing = pool.submit(pytest_in, stranger, "-v")
        failing = pool.submit(pytest_in, changed, ROS_DOMAIN_ID=domain)
        passed, failed = passing.result(), failing.result()
    assert passed.returncode == 0, passed.stdout + passed.stderr
    assert "fixtures/office/spec.yaml::lockstep PASSED" in passed.stdout
    assert "fixtures/office/spec.yaml::live PASSED" in passed.stdout

    assert failed.returncode == 1, failed.stdout + failed.stderr
    for mode in ("lockstep", "live"):
        assert f"office ({mode}): FAIL" in failed.stdout
        report = json.loads(
            (changed / "golden_failures" / f"office-{mode}" / "report.json").read_text()
        )
        failing = {t["topic"]: t for t in report["topics"] if not t["passed"]}
        # The heater's power, and the status answers, which state the gain.
        assert set(failing) == {"/thermostat/heater", "/thermostat/status/_service_event"}
        assert failing["/thermostat/heater"]["failed_fields"] == ["data"]
    assert re.search(
        r"/thermostat/heater: [1-9]\d* of \d+ messages differ \(0 allowed\),"
        r" missing 0, extra 0\n +fields: data \(max \|err\| ",
        failed.stdout,
    ), failed.stdout


def test_the_committed_example_passes_without_a_warning(tmp_path: Path) -> None:
    """Also: lark-parser (rosidl_parser's, imported with a message's type support by the live
    item) warns on import; not the user's to fix, so not in the user's run."""
    result = pytest_in(EXAMPLE, "-v", "--golden-failures", str(tmp_path / "failures"))
    assert result.returncode == 0, result.stdout + result.stderr
    assert "2 passed" in result.stdout
    assert "warnings summary" not in result.stdout, result.stdout
    assert "DeprecationWarning" not in result.stdout
