"""Errors of a recording that are decided without ROS (its options)."""

from __future__ import annotations

from bagkit.errors import BagkitError, OptionError


class RecorderOptionsError(OptionError):
    """A recording that cannot start: nothing selected, a bad option, an existing output."""


class RecordingFailedError(BagkitError):
    """A recording that stopped on an error (disk full); the bag keeps what was written."""

    exit_code = 1


class TriggerError(BagkitError):
    """A trigger that cannot be evaluated: a field its topic's type lacks, an undecodable type."""

    exit_code = 2
