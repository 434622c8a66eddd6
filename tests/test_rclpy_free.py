"""The packages that describe a recording or a replay without running one import no rclpy, and
bagkit/ros/ holds only the adapters to ROS.

The layering test checks the import statements (no rclpy outside bagkit/ros/); this one imports
the modules, so that an import that pulls rclpy in indirectly (through another package) shows
too, and lists bagkit/ros/'s modules: each imports rclpy or is a thin adapter named here.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
# Whole packages, and the modules of bagkit.ros that the recorder, the player and the CLI use
# before any node exists.
RCLPY_FREE_PACKAGES = ("bag", "recording", "playback", "selection")
# (and the pytest plugin at pytest's start: bagkit.ros.domains).
RCLPY_FREE_ROS_MODULES = (
    "bagkit.native",
    "bagkit.ros.domains",
    "bagkit.ros.fastdds",
    "bagkit.ros.tuning",
)

# Every module of bagkit/ros/. Logic that needs no rclpy lives in bagkit/recording/ or
# bagkit/playback/; what stays here without importing rclpy is an adapter, each for a reason.
ROS_ADAPTERS = {
    "bagkit/ros/__init__.py": "package",
    "bagkit/ros/control.py": "rclpy",
    "bagkit/ros/domains.py": "holds the middleware's domains (their ports) before a participant",
    "bagkit/ros/errors.py": "the errors of the adapters here",
    "bagkit/ros/fastdds.py": "configures the middleware (Fast DDS) before a participant exists",
    "bagkit/ros/graph.py": "rclpy",
    "bagkit/ros/graph_wait.py": "rclpy",
    "bagkit/ros/message_classes.py": "imports the installed ROS message packages",
    "bagkit/ros/participants.py": "rclpy",
    "bagkit/ros/qos.py": "rclpy",
    "bagkit/ros/record/__init__.py": "package",
    "bagkit/ros/record/control_services.py": "rclpy",
    "bagkit/ros/record/recorded_topic.py": "rclpy",
    "bagkit/ros/record/recorder.py": "rclpy",
    "bagkit/ros/record/subscriptions.py": "rclpy",
    "bagkit/ros/record/take.py": "rclpy",
    "bagkit/ros/record/take_loop.py": "rclpy",
    "bagkit/ros/record/triggers.py": "rclpy",
    "bagkit/ros/replay/__init__.py": "package",
    "bagkit/ros/replay/endpoints.py": "rclpy",
    "bagkit/ros/replay/player.py": "rclpy",
    "bagkit/ros/replay/publishers.py": "rclpy",
    "bagkit/ros/replay/seek_services.py": "rclpy",
    "bagkit/ros/replay/service_requests.py": "rclpy",
    "bagkit/ros/replay/services.py": "rclpy",
    "bagkit/ros/replay/subscriber_waits.py": "rclpy",
    "bagkit/ros/replay/topics.py": "finds the installed message class of each replayed topic",
    "bagkit/ros/serialization.py": "rclpy",
    "bagkit/ros/trigger_service.py": "serves std_srvs/srv/Trigger (a ROS message package)",
    "bagkit/ros/tuning.py": "opens the middleware's profile around a node's creation",
}


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


def imports_rclpy(path: Path) -> bool:
    """Whether ``path`` has an ``import rclpy...`` or ``from rclpy... import`` anywhere."""
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import) and any(
            a.name.split(".")[0] == "rclpy" for a in node.names
        ):
            return True
        if isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] == "rclpy":
            return True
    return False


def test_bagkit_ros_holds_the_listed_modules() -> None:
    found = {str(p.relative_to(REPO)) for p in (REPO / "bagkit" / "ros").rglob("*.py")}
    assert found == ROS_ADAPTERS.keys(), (
        f"new in bagkit/ros/: {sorted(found - ROS_ADAPTERS.keys())} (rclpy-free logic goes to "
        f"bagkit/recording/ or bagkit/playback/; list an adapter here); "
        f"gone: {sorted(ROS_ADAPTERS.keys() - found)}"
    )


@pytest.mark.parametrize("name", sorted(ROS_ADAPTERS))
def test_each_ros_module_imports_rclpy_or_is_a_named_adapter(name: str) -> None:
    path = REPO / name
    if not path.is_file():
        pytest.skip(f"{name} is gone (the listing test names it)")
    reason = ROS_ADAPTERS[name]
    if reason == "rclpy":
        assert imports_rclpy(path), f"{name} no longer imports rclpy: move it out or say why"
    elif reason == "package":
        assert path.name == "__init__.py" and not ast.parse(path.read_text()).body[1:], name
    else:
        assert not imports_rclpy(path), f"{name} imports rclpy: list it as such"
