"""One rule for a fleet in which a bag cannot be read (docs/fleet.md, "Bags that cannot be
read"): every fleet command (catalog, find, stats summary, export, golden check) does the
others, warns of each unreadable one (``BAG: not read: why``) and ends with one ``error:``
line and exit 2, in this process as on Dask. Runs in this process (tests/bagkit_runs.py); Dask
through the shared cluster's scheduler."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pandas as pd
import pytest
from bagkit_runs import bagkit_in_process
from distributed import Client

FIXTURE = Path(__file__).parents[2] / "fixtures" / "fast"
NOT_A_BAG = b"\x89MCAP0\r\n" + b"\x00" * 64


@pytest.fixture
def listing(fleet_bags: list[Path], tmp_path: Path) -> tuple[Path, Path]:
    """(a listing of two bags with an unreadable one between them, that one)."""
    broken = tmp_path / "bags" / "broken.mcap"
    broken.parent.mkdir()
    broken.write_bytes(NOT_A_BAG)
    listing = tmp_path / "bags.txt"
    listing.write_text("\n".join(map(str, [fleet_bags[0], broken, fleet_bags[1]])) + "\n")
    return listing, broken


def _fixtures(tmp_path: Path) -> tuple[list[Path], Path]:
    """(two golden fixtures, the first of whose bag cannot be read; that bag)."""
    fixtures = [tmp_path / "fixtures" / name for name in ("broken", "fast")]
    for fixture in fixtures:
        shutil.copytree(FIXTURE, fixture)
    broken = fixtures[0] / "golden" / "golden_0.mcap"
    broken.write_bytes(NOT_A_BAG)
    return fixtures, broken


COMMANDS = {
    "catalog": ["catalog", "{bags}", "-o", "{out}/fleet.parquet"],
    "find": ["find", "{bags}", "--when", "/imu/data: linear_acceleration.z > 0"],
    "stats": ["stats", "summary", "{bags}", "--format", "json"],
    "export": ["export", "{bags}", "-t", "/temperature", "-o", "{out}/parquet"],
}


def _unread(stderr: str, broken: Path, of: str, name: str = "", undone: str = "read") -> None:
    """The rule's lines: one warning naming the bag (once), and the error line, last."""
    warnings = [line for line in stderr.splitlines() if line.startswith("warning:")]
    assert len(warnings) == 1, stderr
    assert warnings[0].startswith(f"warning: {name or broken}: not {undone}: "), warnings
    assert warnings[0].count(str(broken)) == 1, warnings  # not named twice
    errors = [line for line in stderr.splitlines() if line.startswith("error:")]
    assert errors == [f"error: 1 of {of} could not be {undone}"], stderr
    assert stderr.strip().splitlines()[-1] == errors[0]


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_every_fleet_command_reports_the_unreadable_bag_and_exits_2(
    client: Client, listing: tuple[Path, Path], tmp_path: Path, command: str
) -> None:
    bags, broken = listing
    outcomes = {}
    for where in ("here", "dask"):
        out = tmp_path / where
        out.mkdir()
        args = [a.format(bags=bags, out=out) for a in COMMANDS[command]]
        run = ["--workers", "0"] if where == "here" else ["--scheduler", client.scheduler.address]
        done = bagkit_in_process([*args, *run])
        assert done.returncode == 2, done.stderr
        assert "Traceback" not in done.stderr and "internal error" not in done.stderr
        _unread(done.stderr, broken, "3 bags", undone="exported" if command == "export" else "read")
        outcomes[where] = done.stdout.replace(str(out), "OUT")
    if command == "stats":  # Dask's means and stds are within 1e-12 (test_fleet_stats.py)
        here, dask = (json.loads(outcomes[where]) for where in ("here", "dask"))
        assert here["bags"] == dask["bags"] and len(here["bags"]) == 3
        assert here["unread"] == dask["unread"] == [str(broken)]  # which of them, for scripts
        assert [t["count"] for t in here["topics"]] == [t["count"] for t in dask["topics"]]
    else:
        assert outcomes["here"] == outcomes["dask"]
    here = tmp_path / "here"
    if command == "catalog":  # the others are catalogued, the unreadable bag has its row
        frame = pd.read_parquet(here / "fleet.parquet")
        assert frame["path"].nunique() == 3 and frame["topic"].notna().sum() == 4
    elif command == "export":
        assert len(list((here / "parquet").rglob("*.parquet"))) == 2
    else:
        assert outcomes["here"].strip()


def test_golden_check_reports_the_unreadable_fixture_and_checks_the_others(
    client: Client, tmp_path: Path
) -> None:
    fixtures, broken = _fixtures(tmp_path)
    outcomes = []
    for run in (["--workers", "0"], ["--scheduler", client.scheduler.address]):
        done = bagkit_in_process(["golden", "check", *fixtures, *run], tmp_path)
        assert done.returncode == 2, done.stderr
        assert "Traceback" not in done.stderr and "internal error" not in done.stderr
        _unread(done.stderr, broken, "2 fixtures", name="broken (lockstep)")
        assert "fast (lockstep): pass" in done.stdout
        outcomes.append([line for line in done.stdout.splitlines() if "real time" not in line])
    assert outcomes[0] == outcomes[1]
