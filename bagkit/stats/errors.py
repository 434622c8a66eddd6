"""Errors of ``bagkit stats``."""

from __future__ import annotations

from bagkit.errors import BagkitError
from bagkit.selection.errors import UnknownTopicError

__all__ = ["NothingToSummarizeError", "StatsError", "UnknownTopicError"]


class StatsError(BagkitError):
    """A summary that cannot be computed from the given bags and options."""


class NothingToSummarizeError(StatsError):
    """No message of the selected topics in the selected time range (or an empty bag)."""
