"""A golden spec's ``health:`` contract: checked on the golden and on each run's outputs, one
pytest item per assertion, on a copy of the repository's faults fixture whose contract bounds
the altitude below what the flight climbs to."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from rosbags.highlevel import AnyReader

from bagkit.regression.errors import SpecError
from bagkit.regression.spec import load_spec

pytest_plugins = ["pytester"]

FAULTS = Path(__file__).parents[2] / "fixtures" / "faults"
BAGKIT = str(Path(sys.executable).with_name("bagkit"))
CEILING_M = 550.0
BROKEN = f"/fusion/odometry: pose.pose.position.z < 300 or pose.pose.position.z > {CEILING_M:g}"


@pytest.fixture
def project(pytester: pytest.Pytester) -> Path:
    """A project holding a copy of fixtures/faults whose contract puts a ceiling at 550 m."""
    root = pytester.path
    (root / "pytest.ini").write_text("[pytest]\ngolden_roots = fixtures\n")
    fixture = root / "fixtures" / "faults"
    shutil.copytree(FAULTS, fixture)
    spec = fixture / "spec.yaml"
    text = spec.read_text()
    assert "{min: 300, max: 1000}" in text
    spec.write_text(text.replace("{min: 300, max: 1000}", f"{{min: 300, max: {CEILING_M:g}}}"))
    return root


def first_above_ceiling_s(bag: Path) -> float:
    """Seconds from the bag's start to the first odometry above the ceiling (rosbags)."""
    with AnyReader([bag]) as reader:
        start = reader.start_time
        for connection, log_time, raw in reader.messages():
            if connection.topic != "/fusion/odometry":
                continue
            z = reader.deserialize(raw, connection.msgtype).pose.pose.position.z
            if z > CEILING_M:
                return (log_time - start) / 1e9
    raise AssertionError("the flight never climbs above the ceiling")


def outcomes(output: str) -> dict[str, str]:
    """Item -> PASSED/FAILED from ``pytest -v``'s lines."""
    found = re.findall(r"spec\.yaml::(\S.*?) (PASSED|FAILED|SKIPPED)", output)
    return dict(found)


def test_each_assertion_is_an_item_on_golden_and_lockstep(
    project: Path, pytester: pytest.Pytester
) -> None:
    # -rN: no short summary, whose lines repeat the failures' text unless the terminal is narrow.
    result = pytester.runpytest_subprocess(
        "-v", "-rN", "--golden-mode", "lockstep", "-p", "no:randomly"
    )
    seen = outcomes(result.stdout.str())
    spec = load_spec(project / "fixtures" / "faults")
    assert spec.health is not None
    # Golden: every topic of the contract; lockstep: those among the outputs.
    golden = [k for k in seen if k.startswith("golden-health[")]
    lockstep = [k for k in seen if k.startswith("lockstep-health[")]
    assert len(golden) == 11 and len(lockstep) == 8
    assert all("/imu/data" not in k for k in lockstep)  # an input: not in the outputs
    failed = {k for k, v in seen.items() if v == "FAILED"}
    assert failed == {f"golden-health[{BROKEN}]", f"lockstep-health[{BROKEN}]"}
    assert seen["lockstep"] == "PASSED"  # the outputs match the golden's
    first = first_above_ceiling_s(spec.bag)
    said = re.findall(
        rf"{re.escape(BROKEN)}: broken 1 time, first at ([\d.]+) s", result.stdout.str()
    )
    assert len(said) == 2
    # The golden's and the candidate's outputs are the same (lockstep is bit-reproducible).
    assert all(abs(float(s) - first) < 1e-3 for s in said), (said, first)


def test_golden_check_fails_naming_the_assertion(project: Path) -> None:
    done = subprocess.run(
        [BAGKIT, "golden", "check", str(project / "fixtures" / "faults"), "--workers", "0",
         "--failures", str(project / "failures")],
        capture_output=True, text=True, timeout=300, check=False,
    )  # fmt: skip
    assert done.returncode == 1, done.stderr
    said = " ".join(done.stdout.split())  # wrapped at 80 columns
    assert f"health (golden): {BROKEN}: broken" in said
    assert f"health (candidate): {BROKEN}: broken" in said


def test_a_bad_health_section_names_its_line(tmp_path: Path) -> None:
    fixture = tmp_path / "faults"
    shutil.copytree(FAULTS, fixture)
    spec = fixture / "spec.yaml"
    lines = spec.read_text().replace("max_gap: 1s", "max_gapp: 1s").splitlines()
    (line,) = [n for n, text in enumerate(lines, 1) if "max_gapp" in text]
    spec.write_text("\n".join(lines) + "\n")
    with pytest.raises(SpecError, match=rf"spec.yaml:{line}: unknown key 'max_gapp' \(did you"):
        load_spec(fixture)


@pytest.mark.ros
def test_the_live_outputs_keep_the_contract(project: Path, pytester: pytest.Pytester) -> None:
    result = pytester.runpytest_subprocess("-v", "--golden-mode", "live", "-p", "no:randomly")
    seen = outcomes(result.stdout.str())
    live = {k: v for k, v in seen.items() if k.startswith("live-health[")}
    assert len(live) == 8
    assert {k for k, v in live.items() if v == "FAILED"} == {f"live-health[{BROKEN}]"}
