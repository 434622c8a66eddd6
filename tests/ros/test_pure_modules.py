"""The parts of bagkit.ros documented as pure import no rclpy (unit-testable without ROS)."""

from __future__ import annotations

import subprocess
import sys

PURE = [
    "bagkit.ros.clock",
    "bagkit.ros.fastdds",
    "bagkit.ros.handoff",
    "bagkit.ros.lateness",
    "bagkit.ros.loss",
    "bagkit.ros.memory",
    "bagkit.ros.play_options",
    "bagkit.ros.playback_report",
    "bagkit.ros.record_report",
    "bagkit.selection.topics",
    "bagkit.ros.timing",
    "bagkit.ros.write_loop",
]


def test_pure_modules_import_no_rclpy() -> None:
    code = (
        "import importlib, sys\n"
        f"for name in {PURE!r}: importlib.import_module(name)\n"
        "print(sorted(m for m in sys.modules if m.split('.')[0] in ('rclpy', 'rpyutils')))\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=60
    )
    assert result.stdout.strip() == "[]", result.stdout
