"""Errors of ``bagkit.data`` (echo, export, DataFrames, plots)."""

from __future__ import annotations

from bagkit.errors import BagkitError
from bagkit.selection.errors import UnknownFieldError, UnknownTopicError

__all__ = [
    "DataError",
    "DataLossWarning",
    "UndecodableTopicError",
    "UnknownFieldError",
    "UnknownTopicError",
]


class DataLossWarning(UserWarning):
    """Part of the bag could not be read (a salvaged file, messages that do not decode)."""


class DataError(BagkitError):
    """A selection of messages or fields that cannot be read as asked."""


class UndecodableTopicError(DataError):
    """The topic's messages cannot be decoded (no or a broken definition, not CDR)."""
