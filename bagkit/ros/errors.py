"""Errors raised by the ROS-facing parts of bagkit."""

from __future__ import annotations

from bagkit.errors import BagkitError


class RosError(BagkitError):
    """A ROS 2 runtime problem (graph, QoS, middleware)."""


class UnknownMessageTypeError(RosError):
    """A message type whose Python package is not installed."""
