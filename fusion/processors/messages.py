"""Small helpers on ROS message objects: rclpy's classes or rosbags' dataclasses (no rclpy)."""

from __future__ import annotations

import dataclasses
import math
import numbers
from typing import Any

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import Quaternion, Vector3


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


def field_names(msg: Any) -> list[str]:
    """Field names of an rclpy message or a rosbags message dataclass."""
    if hasattr(msg, "get_fields_and_field_types"):
        return list(msg.get_fields_and_field_types())
    if dataclasses.is_dataclass(msg):
        # rosbags keeps constants (upper case; ROS field names are lower case) and __msgtype__
        # as dataclass fields.
        return [f.name for f in dataclasses.fields(msg) if f.name.islower()]
    return []


def numeric_fields(msg: Any, prefix: str = "") -> dict[str, float]:
    """Every numeric scalar field of a message as dotted name -> float.

    Headers, (co)variances and their types, arrays and strings are left out: they describe the
    sensor, not the measurement. Works on rclpy messages and rosbags message dataclasses.
    """
    values: dict[str, float] = {}
    for name in field_names(msg):
        if name == "header" or "variance" in name:
            continue
        value = getattr(msg, name)
        if isinstance(value, bool | np.bool_):
            continue
        if isinstance(value, numbers.Real):
            values[f"{prefix}{name}"] = float(value)
        elif field_names(value):
            values.update(numeric_fields(value, f"{prefix}{name}."))
    return values


def copy_quaternion(q: Any) -> Quaternion:
    """An rclpy ``Quaternion`` with the values of any quaternion-like object."""
    return Quaternion(x=float(q.x), y=float(q.y), z=float(q.z), w=float(q.w))


def copy_vector3(v: Any) -> Vector3:
    """An rclpy ``Vector3`` with the values of any vector-like object."""
    return Vector3(x=float(v.x), y=float(v.y), z=float(v.z))
