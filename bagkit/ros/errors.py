"""Errors raised by the ROS-facing parts of bagkit."""

from __future__ import annotations

from bagkit.errors import BagkitError
from bagkit.playback.errors import PlayerError
from bagkit.recording.errors import RecorderOptionsError, RecordingFailedError

__all__ = [
    "ControlError",
    "MessageClassNotFoundError",
    "PlayerError",
    "QosProfileError",
    "RecorderOptionsError",
    "RecordingFailedError",
    "RosError",
    "SubscriberTimeoutError",
]


class RosError(BagkitError):
    """A ROS 2 runtime problem (graph, QoS, middleware)."""


class ControlError(RosError):
    """A control of a running recorder or player that cannot be used: unknown, not offered,
    offered by several nodes, or not answered."""


class MessageClassNotFoundError(RosError):
    """A message type whose Python package is not installed."""


class SubscriberTimeoutError(PlayerError):
    """Subscribers known to the graph did not match the player's publishers in time."""

    exit_code = 1


class QosProfileError(RosError):
    """A QoS profile that cannot be read: bad offered_qos_profiles YAML or overrides file."""
