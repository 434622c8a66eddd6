"""Errors of the selection vocabulary: topics, times, windows, field paths and conditions."""

from __future__ import annotations

from bagkit.errors import BagkitError


class SelectionError(BagkitError):
    """A selection that cannot be understood: a bad regex, time, window or condition."""
