"""The golden machinery on a fixture built in the test: update, check, failure artefacts."""

from __future__ import annotations

import hashlib
import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from bagkit.bag import BagReader
from bagkit.regression.artefacts import write_failure_artefacts
from bagkit.regression.golden import check_lockstep, update_golden
from bagkit.regression.spec import load_spec

REPO = Path(__file__).resolve().parents[2]
JSON = ["--format", "json"]
OUTPUTS = ["/alerts", "/logger/summary", "/fusion/odometry", "/fusion/baro_altitude"]


def make_fixture(directory: Path, inputs_bag: Path, **fusion_params: object) -> Path:
    directory.mkdir()
    shutil.copytree(inputs_bag, directory / "golden")
    (directory / "golden").joinpath(f"{inputs_bag.name}_0.mcap").rename(
        directory / "golden" / "golden_0.mcap"
    )
    spec = {
        "description": "simulated in-process",
        "duration": 20,
        "processor": "fusion.regression:make_processors",
        "processor_args": {
            "nodes": {"data_logger": {}, "alert_system": {}, "sensor_fusion": fusion_params}
        },
        "inputs": ["/imu/data", "/gps/fix", "/temperature", "/barometer/pressure"],
        "outputs": OUTPUTS,
        "compare": {"atol": 1e-9, "rtol": 1e-9},
    }
    (directory / "spec.yaml").write_text(yaml.safe_dump(spec))
    return directory


@pytest.fixture
def fixture_dir(tmp_path: Path, simulated_flight: Path) -> Path:
    directory = make_fixture(tmp_path / "sim", simulated_flight)
    # metadata.yaml names the old file: rewrite the bag once so it is consistent
    update_golden(load_spec(directory))
    return directory


def test_update_then_check_passes(fixture_dir: Path, tmp_path: Path) -> None:
    spec = load_spec(fixture_dir)
    with BagReader(spec.bag) as bag:
        assert set(OUTPUTS) <= set(bag.topics)
        assert "/sim/truth" in bag.topics  # topics that are not outputs are kept
    check = check_lockstep(spec, tmp_path / "work")
    assert check.passed, check.summary()
    assert check.lockstep is not None and check.lockstep.speedup > 1
    # accepting unchanged behaviour changes no byte: `git diff` shows only real changes
    # (once the golden holds outputs: the simulated one got its first ones in the fixture)
    before = {p.name: p.read_bytes() for p in spec.bag.iterdir()}
    assert not update_golden(spec).rewritten
    assert {p.name: p.read_bytes() for p in spec.bag.iterdir()} == before


def test_changed_constant_fails_with_report_and_plots(fixture_dir: Path, tmp_path: Path) -> None:
    spec_file = fixture_dir / "spec.yaml"
    spec_data = yaml.safe_load(spec_file.read_text())
    spec_data["processor_args"]["nodes"]["sensor_fusion"] = {
        "qnh": 101335.0
    }  # 10 Pa: about 0.8 m of altitude
    spec_file.write_text(yaml.safe_dump(spec_data))
    check = check_lockstep(load_spec(fixture_dir), tmp_path / "work")
    assert not check.passed
    failing = {t.topic for t in check.report.topics if not t.passed}
    assert "/fusion/baro_altitude" in failing
    assert "pose.pose.position.z" in check.summary()
    # How many messages differ against what the pass rate allows, at 80 columns.
    altitude = next(t for t in check.report.topics if t.topic == "/fusion/baro_altitude")
    failed = altitude.failed_messages
    assert 0 < failed <= altitude.golden_count
    assert (
        f"/fusion/baro_altitude: {failed} of {altitude.golden_count} messages differ (0 allowed)"
        in check.summary()
    )
    # The counts and the fields at 80 columns (the divergences below them are one line each).
    topic_lines = [
        line for line in check.summary().splitlines() if ": " in line and " t=" not in line
    ]
    assert all(len(line) <= 80 for line in topic_lines), topic_lines

    written = write_failure_artefacts(check, tmp_path / "failure")
    names = {p.name for p in written}
    assert {"report.json", "report.html", "fusion_baro_altitude.png"} <= names
    assert all(p.stat().st_size > 0 for p in written)
    report = json.loads((tmp_path / "failure" / "report.json").read_text())
    altitude = next(t for t in report["topics"] if t["topic"] == "/fusion/baro_altitude")
    assert "pose.pose.position.z" in altitude["failed_fields"]


def test_cli_check_exit_codes_and_failure_folder(fixture_dir: Path, tmp_path: Path) -> None:
    bagkit = str(Path(sys.executable).with_name("bagkit"))
    failures = tmp_path / "failures"
    ok = subprocess.run(
        [bagkit, "golden", "check", str(fixture_dir), "--failures", str(failures)],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert ok.returncode == 0, ok.stdout + ok.stderr
    assert "sim (lockstep): pass" in ok.stdout and not failures.exists()

    spec_file = fixture_dir / "spec.yaml"
    spec_data = yaml.safe_load(spec_file.read_text())
    spec_data["processor_args"]["nodes"]["data_logger"] = {"summary_period": 4.0}
    spec_file.write_text(yaml.safe_dump(spec_data))
    changed = subprocess.run(
        [bagkit, "golden", "check", str(fixture_dir), "--failures", str(failures), *JSON],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert changed.returncode == 1, changed.stdout + changed.stderr
    (outcome,) = json.loads(changed.stdout)
    assert (outcome["fixture"], outcome["mode"], outcome["passed"]) == ("sim", "lockstep", False)
    assert "/logger/summary" in outcome["summary"] and outcome["error"] is None
    assert Path(outcome["report"]) == failures / "sim-lockstep" / "report.html"
    report = json.loads((failures / "sim-lockstep" / "report.json").read_text())
    (summary,) = [t for t in report["topics"] if t["topic"] == "/logger/summary"]
    assert summary["missing"] > 0 and summary["extra"] > 0

    bad = subprocess.run(
        [bagkit, "golden", "check", str(tmp_path / "nowhere")],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert bad.returncode == 2 and bad.stderr.startswith("error:")


def digest(directory: Path) -> dict[str, str]:
    return {
        str(p.relative_to(directory)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(directory.rglob("*"))
        if p.is_file()
    }


def test_accepting_unchanged_behaviour_rewrites_no_fixture(tmp_path: Path) -> None:
    """`bagkit golden update` on the committed fixtures: every file as it was, even where
    today's outputs differ from the golden's in the last bits (here: a QNH 1e-8 Pa higher,
    about 1e-9 m of altitude, as another CPU's libm would differ)."""
    fixtures = tmp_path / "fixtures"
    shutil.copytree(REPO / "fixtures", fixtures)
    nominal = fixtures / "nominal" / "spec.yaml"
    spec_data = yaml.safe_load(nominal.read_text())
    spec_data["processor_args"]["nodes"]["sensor_fusion"] = {"qnh": 101325.00000001}
    nominal.write_text(yaml.safe_dump(spec_data))
    # the candidate's bytes differ from the golden's, within the lockstep tolerance
    check = check_lockstep(load_spec(nominal.parent), tmp_path / "work")
    assert check.passed, check.summary()
    with BagReader(check.spec.bag) as golden, BagReader(check.candidate) as candidate:
        topic = ["/fusion/baro_altitude"]
        old = [m.data for m in golden.messages(topics=topic)]
        new = [m.data for m in candidate.messages(topics=topic)]
    assert len(old) == len(new) and old != new

    before = digest(fixtures)
    bagkit = str(Path(sys.executable).with_name("bagkit"))
    names = [str(fixtures / n) for n in ("fast", "faults", "nominal")]
    update = subprocess.run(
        [bagkit, "golden", "update", *names],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert update.returncode == 0, update.stdout + update.stderr
    assert update.stdout.count("unchanged, nothing rewritten") == 3, update.stdout
    assert digest(fixtures) == before


def test_update_keeps_the_goldens_custom_data(fixture_dir: Path) -> None:
    """A rewritten golden keeps metadata.yaml's custom_data (the recorder's loss figures)."""
    metadata_file = fixture_dir / "golden" / "metadata.yaml"
    metadata = yaml.safe_load(metadata_file.read_text())
    kept = {"bagkit.record.lost": "3", "site": "test field"}
    metadata["rosbag2_bagfile_information"]["custom_data"] = kept
    metadata_file.write_text(yaml.safe_dump(metadata, sort_keys=False))
    spec_file = fixture_dir / "spec.yaml"
    spec_data = yaml.safe_load(spec_file.read_text())
    spec_data["processor_args"]["nodes"]["sensor_fusion"] = {"qnh": 101335.0}
    spec_file.write_text(yaml.safe_dump(spec_data))
    assert update_golden(load_spec(fixture_dir)).rewritten
    with BagReader(fixture_dir / "golden") as bag:
        assert bag.metadata is not None and bag.metadata.custom_data == kept
