"""A wrong flag, command or value is bad input like any other: one line on stderr, exit 2."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["bagkit", "info", "--bogus", "x"], "No such option: --bogus"),
        (["bagkit", "nosuch"], "No such command 'nosuch'"),
        (["bagkit", "record", "--compression-format", "brotli", "/x"], "'--compression-format'"),
        (["bagkit", "replay", "--rate", "fast", "bag"], "'--rate'"),
        (["fusion", "launch", "--bogus"], "No such option: --bogus"),
    ],
)
def test_usage_error_is_one_line(args: list[str], expected: str) -> None:
    executable = str(Path(sys.executable).with_name(args[0]))
    result = subprocess.run(
        [executable, *args[1:]], capture_output=True, text=True, timeout=60, check=False
    )
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("error:") and expected in lines[0]
    assert f"'{args[0]} " in lines[0] and "--help'" in lines[0]
