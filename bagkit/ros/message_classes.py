"""Message types by name: ``"sensor_msgs/msg/Imu"`` <-> the generated Python class."""

from __future__ import annotations

import importlib
from typing import Any

from bagkit.ros.errors import MessageClassNotFoundError


def import_message_type(type_name: str) -> Any:
    """Return the generated Python class for ``pkg/msg/Name`` (``pkg/Name`` is accepted too).

    An action's part, ``pkg/action/Name_FeedbackMessage`` and the like, is found too.

    Raises:
        MessageClassNotFoundError: the package is not installed or has no such message.
    """
    parts = type_name.split("/")
    if len(parts) == 2:
        parts = [parts[0], "msg", parts[1]]
    if len(parts) != 3 or not all(parts):
        raise MessageClassNotFoundError(f"not a ROS 2 message type name: {type_name!r}")
    package, kind, name = parts
    try:
        module = importlib.import_module(f"{package}.{kind}")
        if kind == "action" and not hasattr(module, name):
            # pkg.action exports the actions only; their parts (Name_FeedbackMessage, ...)
            # live in the action's generated module.
            action = getattr(module, name.split("_", 1)[0])
            module = importlib.import_module(action.__module__)
        return getattr(module, name)
    except (ImportError, AttributeError) as exc:
        raise MessageClassNotFoundError(f"message type {type_name} is not installed") from exc


def message_type_name(message_class: Any) -> str:
    """Return ``pkg/msg/Name`` for a generated message class or instance."""
    cls = message_class if isinstance(message_class, type) else type(message_class)
    package = cls.__module__.split(".")[0]
    return f"{package}/msg/{cls.__name__}"
