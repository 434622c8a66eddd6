"""Every size option reads the one grammar (``2GiB``, ``500MB``, ``1.5G``); too small a split
size is refused with the reason; a free-space floor already passed fails before a bag exists."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest
from bagkit_runs import bagkit_in_process, bagkit_subprocess

from bagkit.bag import BagReader

BAG = Path(__file__).resolve().parents[2] / "fixtures" / "faults" / "golden"


def _bagkit(*args: str | Path, cwd: Path) -> subprocess.CompletedProcess[str]:
    """``record`` in a process of its own (it loads rclpy); the bag commands in this one."""
    run = bagkit_subprocess if args[0] == "record" else bagkit_in_process
    return run(list(args), cwd)


@pytest.mark.parametrize("command", ["filter", "merge"])
def test_a_split_size_in_units_splits_there(command: str, tmp_path: Path) -> None:
    inputs = [BAG] if command == "filter" else [BAG, BAG]
    args = [command, *inputs, "-o", tmp_path / "out", "-b", "64KiB", "--compression", "none"]
    result = _bagkit(*args, cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    files = sorted((tmp_path / "out").glob("*.mcap"))
    assert len(files) > 2
    # Files end on the first chunk that reaches the size (chunks are at most a quarter of it).
    assert all(f.stat().st_size < 64 * 1024 * 1.25 + 60_000 for f in files[:-1])
    with BagReader(BAG) as original, BagReader(tmp_path / "out") as split:
        assert split.message_count == original.message_count * len(inputs)


@pytest.mark.parametrize("command", ["filter", "record"])
def test_a_split_size_below_the_minimum_is_refused_with_the_reason(
    command: str, tmp_path: Path
) -> None:
    args = [command, *([BAG] if command == "filter" else ["--topics", "/x"])]
    result = _bagkit(*args, "-o", tmp_path / "out", "-b", "1", cwd=tmp_path)
    assert result.returncode == 2
    assert result.stderr.startswith("error: ") and result.stderr.count("\n") == 1
    assert "a split size of 1 bytes is below" in result.stderr
    assert not (tmp_path / "out").exists()


def test_record_takes_the_readme_size_and_checks_free_space_before_starting(
    tmp_path: Path,
) -> None:
    """``-b 2GiB`` parses (the error is the free space); no empty bag is left behind."""
    args = ["record", "--topics", "/x", "-o", tmp_path / "out", "-b", "2GiB"]
    result = _bagkit(*args, "--min-free-space", "99%", cwd=tmp_path)
    assert result.returncode == 2
    assert result.stderr == f"error: {tmp_path}: less than 99% free: not started\n"
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("option", ["-b", "--max-cache-size"])
def test_a_bad_size_is_a_usage_error_naming_the_grammar(option: str, tmp_path: Path) -> None:
    result = _bagkit("record", "--topics", "/x", "-o", tmp_path / "o", option, "1.5x", cwd=tmp_path)
    assert result.returncode == 2
    assert "'1.5x': expected a size (2GiB, 500MB, 1.5G" in result.stderr
    assert result.stderr.count("\n") == 1
