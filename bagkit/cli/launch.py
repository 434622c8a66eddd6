"""The ``bagkit`` console script: ``bagkit echo`` starts without importing the other commands.

``echo`` is what a user types to see one message at once; importing every command group
(comparison, recording, statistics) first would cost it more than reading the message.

numpy's OpenBLAS starts a thread per core when numpy is imported, and bagkit calls no BLAS
routine (no matrix products, no linear algebra): the command runs it on one thread, unless
the user set ``OPENBLAS_NUM_THREADS`` (benchmarks/README.md, start-up).
"""

from __future__ import annotations

import os
import sys


def run() -> None:
    """Console entry point of ``bagkit``."""
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    command = sys.argv[1:2]
    if command == ["echo"]:
        from bagkit.cli.echo import run_alone

        run_alone()
    from bagkit.cli.main import run as run_all

    run_all()
