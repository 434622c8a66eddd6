"""The packages that describe a recording or a replay without running one import no rclpy.

The layering test checks the import statements; this one imports the modules, so that an
import that pulls rclpy in indirectly (through another package) shows too.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
# Whole packages, and the modules of bagkit.ros that the recorder, the player and the CLI use
# before any node exists.
RCLPY_FREE_PACKAGES = ("recording", "playback", "selection")
RCLPY_FREE_ROS_MODULES = ("bagkit.ros.clock", "bagkit.ros.fastdds", "bagkit.ros.tuning")


def rclpy_free_modules() -> list[str]:
    names = list(RCLPY_FREE_ROS_MODULES)
    for package in RCLPY_FREE_PACKAGES:
        for path in sorted((REPO / "bagkit" / package).rglob("*.py")):
            parts = path.relative_to(REPO).with_suffix("").parts
            names.append(".".join(parts[:-1] if parts[-1] == "__init__" else parts))
    return names


def test_the_pure_packages_import_no_rclpy() -> None:
    modules = rclpy_free_modules()
    assert "bagkit.recording.options" in modules and "bagkit.playback.options" in modules
    code = (
        "import importlib, sys\n"
        f"for name in {modules!r}: importlib.import_module(name)\n"
        "print(sorted(m for m in sys.modules if m.split('.')[0] in ('rclpy', 'rpyutils')))\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=60
    )
    assert result.stdout.strip() == "[]", result.stdout
