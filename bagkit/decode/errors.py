"""Errors of the decoding layer: definitions that cannot be parsed, data that cannot be decoded."""

from __future__ import annotations

from bagkit.errors import BagkitError


class DecodeError(BagkitError):
    """A message type or a message that cannot be decoded from the bag's own definitions."""


class SchemaError(DecodeError):
    """A stored message definition that cannot be parsed (or none is stored for the type)."""


class DefinitionError(SchemaError):
    """A stored message definition that is not a valid ``.msg`` text."""
