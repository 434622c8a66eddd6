"""Errors of ``bagkit.data`` (echo, export, DataFrames, plots)."""

from __future__ import annotations

from bagkit.errors import BagkitError


class DataError(BagkitError):
    """A selection of messages or fields that cannot be read as asked."""


class UnknownTopicError(DataError):
    """A topic the bag does not have; the message names those it has."""


class UnknownFieldError(DataError):
    """A field (path or glob) the topic's type does not have; the message names its fields."""


class UndecodableTopicError(DataError):
    """The topic's messages cannot be decoded (no or a broken definition, not CDR)."""
