"""Environment variables that the ``bagkit`` command sets for its own process only.

numpy's OpenBLAS starts a thread per core when numpy is imported, and bagkit calls no BLAS
routine (no matrix products, no linear algebra): the command runs it on one thread, unless the
user set ``OPENBLAS_NUM_THREADS`` (benchmarks/README.md, start-up). The programs bagkit starts
(the user's nodes under a live golden check, fusion's) get the user's environment without it:
they run as they would alone. Standard library only: the console script imports it first.
"""

from __future__ import annotations

import os
from collections.abc import Mapping

_SET_FOR_BAGKIT: set[str] = set()


def single_threaded_blas() -> None:
    """Run numpy's OpenBLAS on one thread in this process (before numpy is imported)."""
    if "OPENBLAS_NUM_THREADS" not in os.environ:
        os.environ["OPENBLAS_NUM_THREADS"] = "1"
        _SET_FOR_BAGKIT.add("OPENBLAS_NUM_THREADS")


def for_programs(env: Mapping[str, str]) -> dict[str, str]:
    """``env`` without the variables set for bagkit's own process: a started program's."""
    return {name: value for name, value in env.items() if name not in _SET_FOR_BAGKIT}
