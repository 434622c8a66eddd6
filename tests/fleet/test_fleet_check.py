"""``bagkit check`` over many bags on Dask: what one process gives, an unreadable bag
reported among the others."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
from distributed import Client

from bagkit.health import HealthSpec, check_bags

FIXTURES = Path(__file__).parents[2] / "fixtures"
BAGKIT = str(Path(sys.executable).with_name("bagkit"))
SPEC = """\
topics:
  /imu/data:
    max_gap: 300ms
    never: ["unchanged(linear_acceleration) for 1s"]
  /gps/fix: {never: [isnan(*)]}
  /temperature: {values: {temperature: {max: 50}}}
"""


def bags(tmp_path: Path) -> list[str]:
    broken = tmp_path / "broken.mcap"
    broken.write_bytes(b"\x89MCAP0\r\n" + b"\x00" * 64)
    return [str(FIXTURES / name / "golden") for name in ("nominal", "faults", "fast")] + [
        str(broken)
    ]


def test_dask_gives_what_one_process_gives(client: Client, tmp_path: Path) -> None:
    spec = HealthSpec.parse(SPEC)
    here = check_bags(bags(tmp_path), spec)
    done: list[int] = []
    there = check_bags(bags(tmp_path), spec, client=client, done=done.append)
    assert sorted(done) == [0, 1, 2, 3]
    assert [r.bag for r in there.reports] == [r.bag for r in here.reports]
    for mine, theirs in zip(here.reports, there.reports, strict=True):
        assert (mine.error is None) == (theirs.error is None)
        assert [(a.what, a.passed) for a in mine.assertions] == [
            (a.what, a.passed) for a in theirs.assertions
        ]
        for a, b in zip(mine.assertions, theirs.assertions, strict=True):
            assert np.array_equal(a.spans, b.spans)
    assert here.reports[3].error is not None and here.exit_code == 2


def test_cli_workers_report_the_unreadable_bag_among_the_others(tmp_path: Path) -> None:
    spec = tmp_path / "health.yaml"
    spec.write_text(SPEC)
    done = subprocess.run(
        [BAGKIT, "check", *bags(tmp_path), "--spec", spec, "--workers", "2", "--format", "json"],
        check=False,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 2, done.stderr
    reports = json.loads(done.stdout)
    assert [r["passed"] for r in reports] == [True, False, True, False]  # faults; unread
    assert reports[3]["error"] and reports[1]["error"] is None
    assert "Traceback" not in done.stderr
    assert done.stderr.strip().splitlines()[-1] == "error: 1 of 4 bags could not be read"
