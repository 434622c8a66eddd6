"""The sensor_fusion node: `python -m fusion.nodes.sensor_fusion [--ros-args ...]`."""

from __future__ import annotations

import sys

from fusion.nodes.shell import run_node


def main() -> None:
    """Run the node until SIGINT/SIGTERM."""
    sys.exit(run_node("sensor_fusion"))


if __name__ == "__main__":
    main()
