"""CDR (de)serialization of ROS 2 message objects with rclpy's type support."""

from __future__ import annotations

from typing import Any

from rclpy.serialization import deserialize_message, serialize_message

from bagkit.ros.message_classes import import_message_type, message_type_name


def serialize(msg: Any) -> bytes:
    """The CDR bytes of the message object ``msg``."""
    return bytes(serialize_message(msg))


def deserializer(type_name: str) -> Any:
    """A function from CDR bytes to a message object of ``type_name`` (``pkg/msg/Name``).

    Raises:
        MessageClassNotFoundError: the type's Python package is not installed.
    """
    cls = import_message_type(type_name)

    def decode(data: bytes) -> Any:
        return deserialize_message(data, cls)

    return decode


__all__ = ["deserializer", "message_type_name", "serialize"]
