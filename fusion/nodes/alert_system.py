"""The alert_system node: `python -m fusion.nodes.alert_system [--ros-args ...]`."""

from __future__ import annotations

import sys

from fusion.nodes.shell import run_node


def main() -> None:
    """Run the node until SIGINT/SIGTERM."""
    sys.exit(run_node("alert_system"))


if __name__ == "__main__":
    main()
