"""Errors of a replay that are decided without ROS (its options, its window)."""

from __future__ import annotations

from bagkit.errors import OptionError


class PlayerError(OptionError):
    """A replay that cannot start: bad options, nothing to replay."""
