"""The root of bagkit's exceptions: the CLI prints these as one line, without a traceback."""

from __future__ import annotations


class BagkitError(Exception):
    """An error the user can act on; ``exit_code`` is what the CLI exits with."""

    exit_code: int = 2
