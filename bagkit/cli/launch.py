"""The ``bagkit`` console script: ``bagkit echo`` starts without importing the other commands.

``echo`` is what a user types to see one message at once; importing every command group
(comparison, recording, statistics) first would cost it more than reading the message.
"""

from __future__ import annotations

import sys

# Options that take several values after one flag, as ``ros2 bag record``'s ``nargs='+'``.
_MULTI_VALUE = {
    "record": frozenset(
        {"--topics", "--topic-types", "--exclude-topics", "--exclude-topic-types", "--custom-data"}
    ),
}


def run() -> None:
    """Console entry point of ``bagkit``."""
    command = sys.argv[1:2]
    if command == ["echo"]:
        from bagkit.cli.echo import run_alone

        run_alone()
    if command and command[0] in _MULTI_VALUE:
        from bagkit.cli.common import expand_multi_value_options

        sys.argv[2:] = expand_multi_value_options(sys.argv[2:], _MULTI_VALUE[command[0]])
    from bagkit.cli.main import run as run_all

    run_all()
