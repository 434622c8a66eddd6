"""Errors of the fusion system: all derive from ``BagkitError`` so the CLIs print one line."""

from __future__ import annotations

from bagkit.errors import BagkitError


class FusionError(BagkitError):
    """A problem of the fusion system the user can act on."""


class ConfigError(FusionError):
    """A parameter is missing, of the wrong type or out of its valid range."""


class FaultScheduleError(ConfigError):
    """The ``faults`` parameter cannot be parsed."""


class UnknownNodeError(FusionError):
    """A node name that is not one of ``fusion.processors.NODE_NAMES``."""


class NodeFailedError(FusionError):
    """A node started by ``fusion launch`` exited on its own or with an error."""

    exit_code = 1
