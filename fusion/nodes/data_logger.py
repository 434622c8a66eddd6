"""The data_logger node: `python -m fusion.nodes.data_logger [--ros-args ...]`."""

from __future__ import annotations

import sys

from fusion.nodes.shell import run_node


def main() -> None:
    """Run the node until SIGINT/SIGTERM."""
    sys.exit(run_node("data_logger"))


if __name__ == "__main__":
    main()
