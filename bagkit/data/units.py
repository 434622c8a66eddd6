"""The unit of a leaf field, where its message definition says or its type implies one.

Two sources, in order: fields of well-known types whose unit REP 103 fixes (a Twist's
``linear`` is m/s wherever it is nested), then the comment on the field's line in the stored
definition (``float64 fluid_pressure  # Absolute pressure reading in Pascals.``).
"""

from __future__ import annotations

import re
from collections.abc import Mapping

from bagkit.decode.msgdef import Nodetype, TypeDefinitions

# (type, field) -> unit, for the leaves under that field.
TYPE_UNITS: dict[tuple[str, str], str] = {
    ("geometry_msgs/msg/Twist", "linear"): "m/s",
    ("geometry_msgs/msg/Twist", "angular"): "rad/s",
    ("geometry_msgs/msg/Accel", "linear"): "m/s²",
    ("geometry_msgs/msg/Accel", "angular"): "rad/s²",
    ("geometry_msgs/msg/Pose", "position"): "m",
    ("geometry_msgs/msg/Transform", "translation"): "m",
    ("geometry_msgs/msg/Wrench", "force"): "N",
    ("geometry_msgs/msg/Wrench", "torque"): "N·m",
    ("sensor_msgs/msg/Imu", "linear_acceleration"): "m/s²",
    ("sensor_msgs/msg/Imu", "angular_velocity"): "rad/s",
    ("sensor_msgs/msg/MagneticField", "magnetic_field"): "T",
    ("sensor_msgs/msg/NavSatFix", "latitude"): "°",
    ("sensor_msgs/msg/NavSatFix", "longitude"): "°",
    ("sensor_msgs/msg/NavSatFix", "altitude"): "m",
    ("sensor_msgs/msg/LaserScan", "ranges"): "m",
    ("sensor_msgs/msg/Range", "range"): "m",
    ("builtin_interfaces/msg/Time", "sec"): "s",
    ("builtin_interfaces/msg/Time", "nanosec"): "ns",
    ("builtin_interfaces/msg/Duration", "sec"): "s",
    ("builtin_interfaces/msg/Duration", "nanosec"): "ns",
}

# Words of a field's comment -> unit (first match wins; longer phrases first).
_COMMENT_UNITS: tuple[tuple[str, str], ...] = (
    (r"degrees? celsius|°c\b", "°C"),
    (r"\bkelvin\b", "K"),
    (r"\bpascals?\b|\[pa\]", "Pa"),
    (r"m/s\^?2|m/s²|meters? per second squared", "m/s²"),
    (r"rad/s|radians? per second", "rad/s"),
    (r"m/s\b|meters? per second|metres? per second", "m/s"),
    (r"\bradians?\b|\[rad\]", "rad"),
    (r"\bmeters?\b|\bmetres?\b|\[m\]", "m"),
    (r"\bvolts?\b|\[v\]", "V"),
    (r"\bamperes?\b|\bamps?\b|\[a\]", "A"),
    (r"\btesla\b", "T"),
    (r"\bhertz\b|\bhz\b", "Hz"),
    (r"\blux\b", "lx"),
    (r"\bseconds?\b|\[s\]", "s"),
)
_FIELD_LINE = re.compile(r"^\s*[\w/]+(?:\[[^\]]*\])?\s+(\w+)\s*(?:=[^#]*)?#(.*)$")


def field_unit(
    typestore: TypeDefinitions, typename: str, path: str, definitions: Mapping[str, str]
) -> str:
    """The unit of leaf ``path`` of ``typename``, or ``""`` when nothing says."""
    owners = _owners(typestore, typename, path)
    for owner, name in owners:
        unit = TYPE_UNITS.get((owner, name))
        if unit:
            return unit
    if owners:
        owner, name = owners[-1]
        return _comment_unit(_definition_of(owner, definitions), name)
    return ""


def _owners(typestore: TypeDefinitions, typename: str, path: str) -> list[tuple[str, str]]:
    """(message type, field name) from the outermost to the leaf along ``path``."""
    owners: list[tuple[str, str]] = []
    current: str | None = typename
    for part in path.split("."):
        name = part.split("[", 1)[0]
        if current is None or current not in typestore.fielddefs:
            break
        fields = dict(typestore.fielddefs[current][1])
        if name not in fields:
            break
        owners.append((current, name))
        desc = fields[name]
        while desc[0] in (Nodetype.ARRAY, Nodetype.SEQUENCE):
            desc = desc[1][0]
        current = desc[1] if desc[0] == Nodetype.NAME else None
    return owners


def _definition_of(typename: str, definitions: Mapping[str, str]) -> str:
    """The ``.msg`` text of ``typename`` from a bag's stored definitions (its own or a
    dependency's section), or ``""``."""
    short = typename.replace("/msg/", "/")
    for name, text in definitions.items():
        if name in (typename, short):
            return text.split("\n" + "=" * 80, 1)[0]
        for section in text.split("=" * 80)[1:]:
            head, _, body = section.strip("\n").partition("\n")
            if head.strip() in (f"MSG: {short}", f"MSG: {typename}"):
                return body
    return ""


def _comment_unit(text: str, field: str) -> str:
    for line in text.splitlines():
        match = _FIELD_LINE.match(line)
        if match and match[1] == field:
            comment = match[2].lower()
            for pattern, unit in _COMMENT_UNITS:
                if re.search(pattern, comment):
                    return unit
            return ""
    return ""
