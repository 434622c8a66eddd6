"""Small helpers on ROS message objects: rclpy's classes or rosbags' dataclasses (no rclpy)."""

from __future__ import annotations

import dataclasses
import functools
import math
import numbers
import operator
from collections.abc import Callable
from typing import Any

import numpy as np
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
    return _attribute_getter(path)(msg)


@functools.cache
def _attribute_getter(path: str) -> operator.attrgetter[Any]:
    return operator.attrgetter(path)


def field_names(msg: Any) -> list[str]:
    """Field names of an rclpy message or a rosbags message dataclass."""
    if hasattr(msg, "get_fields_and_field_types"):
        return list(msg.get_fields_and_field_types())
    if dataclasses.is_dataclass(msg):
        # rosbags keeps constants (upper case; ROS field names are lower case) and __msgtype__
        # as dataclass fields.
        return [f.name for f in dataclasses.fields(msg) if f.name.islower()]
    return []


def numeric_fields(msg: Any) -> dict[str, float]:
    """Every numeric scalar field of a message as dotted name -> float.

    Headers, (co)variances and their types, arrays and strings are left out: they describe the
    sensor, not the measurement. Works on rclpy messages and rosbags message dataclasses.
    """
    getter = _NUMERIC_GETTERS.get(type(msg))
    if getter is None:
        getter = _NUMERIC_GETTERS[type(msg)] = _numeric_getter(msg)
    names, values = getter
    return dict(zip(names, map(float, values(msg)), strict=True))


_NumericGetter = tuple[tuple[str, ...], Callable[[Any], tuple[Any, ...]]]
# Which fields are numeric depends on the message class only: walked once per class, then read
# with one C-level attrgetter per message (the data logger does this for every sample).
_NUMERIC_GETTERS: dict[type, _NumericGetter] = {}


def _numeric_getter(example: Any) -> _NumericGetter:
    names = tuple(_numeric_paths(example))
    if len(names) == 1:
        single = operator.attrgetter(names[0])
        return names, lambda msg: (single(msg),)
    if not names:
        return names, lambda _msg: ()
    return names, operator.attrgetter(*names)


def _numeric_paths(msg: Any, prefix: str = "") -> list[str]:
    paths: list[str] = []
    for name in field_names(msg):
        if name == "header" or "variance" in name:
            continue
        value = getattr(msg, name)
        if isinstance(value, bool | np.bool_):
            continue
        if isinstance(value, numbers.Real):
            paths.append(f"{prefix}{name}")
        elif field_names(value):
            paths.extend(_numeric_paths(value, f"{prefix}{name}."))
    return paths


def set_stamp(target: Any, now_ns: int) -> None:
    """Set a ``builtin_interfaces/Time`` in place (cheaper than building a new one)."""
    target.sec, target.nanosec = divmod(now_ns, 1_000_000_000)


def copy_quaternion(target: Any, source: Any) -> None:
    """Copy the values of any quaternion-like ``source`` into the message field ``target``."""
    target.x, target.y, target.z, target.w = (
        float(source.x),
        float(source.y),
        float(source.z),
        float(source.w),
    )


def copy_vector3(target: Any, source: Any) -> None:
    """Copy the values of any vector-like ``source`` into the message field ``target``."""
    target.x, target.y, target.z = float(source.x), float(source.y), float(source.z)
