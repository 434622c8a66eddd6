"""Errors raised by the ROS-facing parts of bagkit."""

from __future__ import annotations

from bagkit.errors import BagkitError


class RosError(BagkitError):
    """A ROS 2 runtime problem (graph, QoS, middleware)."""


class MessageClassNotFoundError(RosError):
    """A message type whose Python package is not installed."""


class PlayerError(RosError):
    """A replay that cannot start: bad options, nothing to replay."""


class SubscriberTimeoutError(PlayerError):
    """Subscribers known to the graph did not match the player's publishers in time."""

    exit_code = 1


class QosProfileError(RosError):
    """A QoS profile that cannot be read: bad offered_qos_profiles YAML or overrides file."""


class RecorderOptionsError(RosError):
    """A recording that cannot start: nothing selected, a bad option, an existing output."""


class RecordingFailedError(RosError):
    """A recording that stopped on an error (disk full); the bag keeps what was written."""

    exit_code = 1
