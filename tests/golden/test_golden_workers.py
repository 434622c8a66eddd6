"""``bagkit golden check`` over several fixtures on a local Dask cluster: the verdicts, summaries
and failure reports of the in-process run."""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
from pathlib import Path

import yaml
from test_golden_machinery import make_fixture

from bagkit.regression.golden import update_golden
from bagkit.regression.spec import load_spec

BAGKIT = str(Path(sys.executable).with_name("bagkit"))


def _check(fixtures: list[Path], failures: Path, workers: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [
            BAGKIT,
            "golden",
            "check",
            *map(str, fixtures),
            "--failures",
            str(failures),
            "--workers",
            workers,
        ],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )


def _verdicts(stdout: str) -> list[str]:
    """The output without what depends on the run: speeds and where reports went."""
    return [
        line for line in stdout.splitlines() if not line.startswith(("  lockstep (", "  report: "))
    ]


def test_workers_give_the_in_process_verdicts(tmp_path: Path, simulated_flight: Path) -> None:
    fixtures = [make_fixture(tmp_path / name, simulated_flight) for name in ("same", "changed")]
    for fixture in fixtures:
        update_golden(load_spec(fixture))
    spec_file = fixtures[1] / "spec.yaml"
    spec = yaml.safe_load(spec_file.read_text())
    spec["processor_args"]["nodes"]["data_logger"] = {"summary_period": 4.0}
    spec_file.write_text(yaml.safe_dump(spec))

    here = _check(fixtures, tmp_path / "here", "0")
    there = _check(fixtures, tmp_path / "there", "2")

    assert (here.returncode, there.returncode) == (1, 1), here.stderr + there.stderr
    assert "local Dask cluster of 2 workers" in there.stderr and "Dask" not in here.stderr
    assert _verdicts(there.stdout) == _verdicts(here.stdout)
    assert "same (lockstep): pass" in here.stdout and "changed (lockstep): FAIL" in here.stdout
    assert there.stdout.count("  lockstep (") == 2
    assert f"report: {tmp_path / 'there' / 'changed-lockstep' / 'report.html'}" in there.stdout
    reports = [
        json.loads((tmp_path / d / "changed-lockstep" / "report.json").read_text())
        for d in ("here", "there")
    ]
    for report in reports:  # the candidate bag was in each run's own temporary directory
        assert report.pop("candidate").startswith(tempfile.gettempdir())
    assert reports[0] == reports[1] and reports[0]["verdict"] == "fail"
    assert not (tmp_path / "there" / "same-lockstep").exists()
