"""The ``bagkit`` console script: ``bagkit echo`` starts without importing the other commands.

``echo`` is what a user types to see one message at once; importing every command group
(comparison, recording, statistics) first would cost it more than reading the message.
"""

from __future__ import annotations

import gc
import sys

from bagkit.own_environment import single_threaded_blas


def run() -> None:
    """Console entry point of ``bagkit``."""
    single_threaded_blas()
    try:
        command = sys.argv[1:2]
        if command == ["echo"]:
            from bagkit.cli.echo import run_alone

            run_alone()
        from bagkit.cli.main import run as run_all

        run_all()
    finally:
        # The process ends here: the collector's last pass over every object of numpy, typer
        # and bagkit's modules at interpreter exit would find nothing to free, but costs a quick
        # command a noticeable part of its run. Frozen objects are left out of that pass; the
        # modules are still torn down, so every object still goes when its references do.
        gc.freeze()
