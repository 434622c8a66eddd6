"""Decoding ROS 2 messages from the definitions stored in a bag, without a ROS install.

- :class:`MessageTypes`: a rosbags typestore built from a bag's ros2msg definitions.
- :func:`flatten_message` / :func:`leaf_fields`: messages as ``{dotted path: value}``, and the
  same paths from the schema alone.
- :mod:`bagkit.decode.layout`: CDR layouts as numpy dtypes, for bulk decoding.
"""

from __future__ import annotations

from bagkit.decode.errors import DecodeError, SchemaError
from bagkit.decode.flatten import (
    FlatValue,
    LeafField,
    field_getter,
    flatten_message,
    leaf_fields,
)
from bagkit.decode.types import MessageTypes

__all__ = [
    "DecodeError",
    "FlatValue",
    "LeafField",
    "MessageTypes",
    "SchemaError",
    "field_getter",
    "flatten_message",
    "leaf_fields",
]
