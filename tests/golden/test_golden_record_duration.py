"""``bagkit golden record`` writes a golden as long as its spec's ``duration``: the thermostat
example once wrote 9.8 s of the 12 asked (the processes' start-up came off the recording)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from bagkit.bag import BagReader
from bagkit.regression.spec import load_spec

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "thermostat"
BAGKIT = str(Path(sys.executable).with_name("bagkit"))


@pytest.mark.ros
def test_the_golden_spans_the_duration_asked(tmp_path: Path) -> None:
    project = tmp_path / "thermostat"
    shutil.copytree(EXAMPLE, project, ignore=shutil.ignore_patterns("__pycache__", "golden"))
    fixture = project / "fixtures" / "office"
    # A domain of its own: nothing of the tests before it, which run the same example's nodes on
    # the session's domain, reaches this recorder.
    domain = (int(os.environ["ROS_DOMAIN_ID"]) + 1) % 230
    recorded = subprocess.run(
        [BAGKIT, "golden", "record", str(fixture)],
        cwd=project,
        env=dict(os.environ, ROS_DOMAIN_ID=str(domain)),
        capture_output=True,
        text=True,
        timeout=180,
        check=False,
    )
    assert recorded.returncode == 0, recorded.stderr
    asked = load_spec(fixture).duration_s
    with BagReader(fixture / "golden") as golden:
        # On failure, record_golden's stderr names each topic's first and last second.
        assert (golden.end_ns - golden.start_ns) / 1e9 >= asked, recorded.stderr
        rate = golden.topic_counts["/thermostat/temperature"] / asked
    assert rate >= 9.5, "the simulated sensor publishes at 10 Hz for the whole duration"
    assert "asked" not in recorded.stderr  # no "the golden spans X s of the Y s asked"
