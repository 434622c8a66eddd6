"""Errors of a recording that are decided without ROS (its options)."""

from __future__ import annotations

from bagkit.errors import BagkitError


class RecorderOptionsError(BagkitError):
    """A recording that cannot start: nothing selected, a bad option, an existing output."""
