"""Decoding ROS 2 messages from the definitions stored in a bag, without a ROS install.

- :class:`MessageTypes`: a rosbags typestore built from a bag's stored definitions (ros2msg,
  ros2idl, rosbag2's SRV:/ACTION: texts: :mod:`bagkit.decode.stored`), per topic where a bag
  holds several texts of one type.
- :func:`flatten_message` / :func:`leaf_fields`: messages as ``{dotted path: value}``, and the
  same paths from the schema alone.
- :mod:`bagkit.selection.fields`: the field-glob language (``[TOPIC_GLOB:]FIELD_GLOB``).
- :mod:`bagkit.decode.layout` and :mod:`bagkit.decode.bulk`: CDR layouts as numpy dtypes, and
  many payloads of one layout decoded at once into columns; :mod:`bagkit.decode.direct`: leaf
  values read from one payload (the general path).
- :mod:`bagkit.decode.typegraph`: the limits a type must keep before anything walks it.
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
from bagkit.decode.message_types import MessageTypes
from bagkit.selection.fields import FieldSelection

__all__ = [
    "DecodeError",
    "FieldSelection",
    "FlatValue",
    "LeafField",
    "MessageTypes",
    "SchemaError",
    "field_getter",
    "flatten_message",
    "leaf_fields",
]
