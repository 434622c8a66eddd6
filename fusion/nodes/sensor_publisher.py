"""The sensor_publisher node: `python -m fusion.nodes.sensor_publisher [--ros-args ...]`."""

from __future__ import annotations

import sys

from fusion.nodes.shell import run_node


def main() -> None:
    """Run the node until SIGINT/SIGTERM."""
    sys.exit(run_node("sensor_publisher"))


if __name__ == "__main__":
    main()
