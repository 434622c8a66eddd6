"""Errors of the decoding layer: definitions that cannot be parsed, data that cannot be decoded."""

from __future__ import annotations

import struct

from bagkit.errors import BagkitError


class DecodeError(BagkitError):
    """A message type or a message that cannot be decoded from the bag's own definitions."""


class SchemaError(DecodeError):
    """A stored message definition that cannot be parsed (or none is stored for the type)."""


class DefinitionError(SchemaError):
    """A stored message definition that is not a valid ``.msg`` text."""


def undecodable(typename: str, exc: BaseException) -> DecodeError:
    """The error of a ``typename`` payload that a reader failed on with ``exc``, said as what
    is wrong with the bytes rather than as the reader's exception."""
    if isinstance(exc, (struct.error, IndexError)):
        problem = "it ends past the payload (a shorter or other type than its definition)"
    elif isinstance(exc, UnicodeDecodeError):
        problem = f"a string is not UTF-8 (byte {exc.start} of it)"
    elif type(exc) is ValueError:  # the readers' own words
        problem = str(exc)
    else:
        problem = f"{type(exc).__name__}: {exc}"
    return DecodeError(f"{typename} message does not decode: {problem}")
