"""Small helpers on ROS message objects (no rclpy)."""

from __future__ import annotations

import math
from typing import Any

from builtin_interfaces.msg import Time
from geometry_msgs.msg import Quaternion


def stamp(now_ns: int) -> Time:
    """A ``builtin_interfaces/Time`` for ``now_ns``."""
    sec, nanosec = divmod(now_ns, 1_000_000_000)
    return Time(sec=sec, nanosec=nanosec)


def stamp_ns(time: Any) -> int:
    """Nanoseconds of a ``builtin_interfaces/Time``."""
    return int(time.sec) * 1_000_000_000 + int(time.nanosec)


def quaternion_from_euler(roll: float, pitch: float, yaw: float) -> Quaternion:
    """Quaternion of intrinsic Z-Y-X (yaw, pitch, roll) rotations, REP 103."""
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    return Quaternion(
        w=cr * cp * cy + sr * sp * sy,
        x=sr * cp * cy - cr * sp * sy,
        y=cr * sp * cy + sr * cp * sy,
        z=cr * cp * sy - sr * sp * cy,
    )


def field_value(msg: Any, path: str) -> Any:
    """The value at a dotted attribute ``path`` of ``msg`` (``"linear_acceleration.z"``)."""
    value = msg
    for part in path.split("."):
        value = getattr(value, part)
    return value


def numeric_fields(msg: Any, prefix: str = "") -> dict[str, float]:
    """Every numeric scalar field of a message as dotted name -> float.

    Headers, (co)variances and their types, and arrays are left out: they describe the sensor,
    not the measurement.
    """
    values: dict[str, float] = {}
    for name, type_name in msg.get_fields_and_field_types().items():
        if name == "header" or "variance" in name or "[" in type_name:
            continue
        if type_name.startswith("sequence") or type_name == "string":
            continue
        value = getattr(msg, name)
        if hasattr(value, "get_fields_and_field_types"):
            values.update(numeric_fields(value, f"{prefix}{name}."))
        elif isinstance(value, bool):
            continue
        elif isinstance(value, int | float):
            values[f"{prefix}{name}"] = float(value)
    return values
