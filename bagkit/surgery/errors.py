"""Errors of bag surgery (all exit code 2: the input or the output path is unusable)."""

from __future__ import annotations

from bagkit.errors import BagkitError


class SurgeryError(BagkitError):
    """A bag cannot be rewritten as asked (bad option, output exists, nothing to write)."""

    exit_code = 2
