"""Preloaded into each worker process of a local cluster (a Dask preload module).

A terminal's Ctrl-C reaches every process of its group: the workers ignore it, and the driver,
which gets it too, shuts the cluster down. Left to themselves the workers would die at once,
each printing a traceback, while the driver still talks to them.
"""

from __future__ import annotations

import signal


def dask_setup(worker: object) -> None:
    """Called by Dask in the worker process when it starts."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
