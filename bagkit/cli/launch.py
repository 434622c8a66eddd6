"""The ``bagkit`` console script: ``bagkit echo`` starts without importing the other commands.

``echo`` is what a user types to see one message at once; importing every command group
(comparison, recording, statistics) first would cost it more than reading the message.
"""

from __future__ import annotations

import sys

from bagkit.own_environment import single_threaded_blas


def run() -> None:
    """Console entry point of ``bagkit``."""
    single_threaded_blas()
    command = sys.argv[1:2]
    if command == ["echo"]:
        from bagkit.cli.echo import run_alone

        run_alone()
    from bagkit.cli.main import run as run_all

    run_all()
