"""Message definitions and type hashes from the installed ROS 2 interface files.

The ROS wheels install ``share/<pkg>/msg/<Name>.msg`` (the definition) and ``<Name>.json`` (the
type description with its RIHS01 hashes) under ``sys.prefix``; a sourced ROS install lists its
prefixes in ``AMENT_PREFIX_PATH``.
"""

from __future__ import annotations

import functools
import json
import os
import re
import sys
from collections.abc import Callable
from pathlib import Path

from bagkit.bag.action_definitions import action_part_texts, split_action_part
from bagkit.bag.errors import UnknownMessageTypeError

# rosbag2 separates the definitions of dependencies with this line (80 '=').
DEFINITION_SEPARATOR = "=" * 80

INTEGER_TYPES = frozenset(
    {
        "bool",
        "byte",
        "char",
        "int8",
        "uint8",
        "int16",
        "uint16",
        "int32",
        "uint32",
        "int64",
        "uint64",
    }
)
"""The ROS 2 primitive types that hold integers (bool, byte and char included)."""
PRIMITIVES = INTEGER_TYPES | {"float32", "float64", "string", "wstring"}
"""Every ROS 2 primitive type name."""
# The type token of a field or constant line: strip bounds and array suffixes.
_TYPE_TOKEN = re.compile(r"^([A-Za-z_][A-Za-z0-9_/]*)")


def definition_encoding(text: str) -> str:
    """The MCAP schema encoding of a stored definition text: ``ros2idl`` when its sections are
    ``IDL:`` ones (the text opens with a separator line, then ``IDL: pkg/msg/Name``), else
    ``ros2msg`` (rosbag2 Kilted's ``SRV:``/``ACTION:`` texts included)."""
    lines = [line.strip() for line in text.lstrip().splitlines()[:2]]
    is_idl = len(lines) == 2 and lines[0] == DEFINITION_SEPARATOR and lines[1].startswith("IDL:")
    return "ros2idl" if is_idl else "ros2msg"


DEFINITION_ENCODINGS = ("ros2msg", "ros2idl")
"""The definition encodings bagkit reads; rosbag2 writes ``unknown`` (and no text) for a type
whose definition it did not find when recording (an action's status or cancel topic recorded
before its other topics, Kilted to 2026)."""

UNKNOWN_ENCODING = "unknown"
"""rosbag2's encoding of a definition it does not have (written with no text): bagkit writes it
too, where an input gives no definition for a type."""


def canonical_type_name(type_name: str) -> str:
    """Return ``pkg/msg/Name`` for ``pkg/Name`` (older writers) and leave other names alone."""
    parts = type_name.split("/")
    if len(parts) == 2 and all(parts):
        return f"{parts[0]}/msg/{parts[1]}"
    return type_name


def _split_type_name(type_name: str) -> tuple[str, str, str]:
    parts = canonical_type_name(type_name).split("/")
    if len(parts) != 3 or not all(parts):
        raise UnknownMessageTypeError(f"not a ROS 2 message type name: {type_name!r}")
    return parts[0], parts[1], parts[2]


def _share_dirs() -> list[Path]:
    dirs = [Path(sys.prefix) / "share"]
    for prefix in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep):
        if prefix:
            dirs.append(Path(prefix) / "share")
    return dirs


@functools.cache
def _interface_file(package: str, kind: str, name: str, suffix: str) -> Path | None:
    for share in _share_dirs():
        candidate = share / package / kind / f"{name}{suffix}"
        if candidate.is_file():
            return candidate
    return None


# A service-event type ``pkg/srv/Name_Event`` is generated from the service's ``.srv`` file.
_SERVICE_EVENT_SUFFIX = "_Event"


def _interface_source(type_name: str) -> tuple[str, str, str, str]:
    """(package, kind, file stem, suffix) of the interface file that defines ``type_name``."""
    package, kind, name = _split_type_name(type_name)
    if kind == "srv" and name.endswith(_SERVICE_EVENT_SUFFIX):
        return package, kind, name.removesuffix(_SERVICE_EVENT_SUFFIX), ".srv"
    action_part = split_action_part(name) if kind == "action" else None
    if action_part is not None:
        return package, kind, action_part[0], ".action"
    return package, kind, name, ".msg"


def interface_source(type_name: str) -> tuple[str, str, str, str]:
    """(package, kind, file stem, suffix) of the interface file that defines ``type_name``
    (``my_msgs/srv/Set_Event``: ``("my_msgs", "srv", "Set", ".srv")``).

    Raises:
        UnknownMessageTypeError: not a type name.
    """
    return _interface_source(type_name)


def interface_text(type_name: str) -> str:
    """The installed text of the interface file that defines ``type_name`` (no dependencies).

    Raises:
        UnknownMessageTypeError: it is not installed.
    """
    return _msg_text(type_name)


@functools.cache
def _msg_text(type_name: str) -> str:
    package, kind, name, suffix = _interface_source(type_name)
    path = _interface_file(package, kind, name, suffix)
    if path is None:
        raise UnknownMessageTypeError(
            f"message type {canonical_type_name(type_name)} is not installed "
            f"(no {package}/{kind}/{name}{suffix} under {', '.join(map(str, _share_dirs()))})"
        )
    return path.read_text(encoding="utf-8")


def _dependencies(package: str, text: str) -> list[str]:
    """Return the non-primitive types that the fields of a ``.msg`` text refer to, in order."""
    found: list[str] = []
    for raw_line in text.splitlines():
        line = raw_line.split("#", 1)[0].strip()
        if not line or line == "---":
            continue
        match = _TYPE_TOKEN.match(line)
        if match is None:
            continue
        token = match.group(1)
        if token in PRIMITIVES:
            continue
        if token == "Header":
            dependency = "std_msgs/msg/Header"
        elif "/" in token:
            dependency = canonical_type_name(token)
        else:
            dependency = f"{package}/msg/{token}"
        if dependency not in found:
            found.append(dependency)
    return found


@functools.cache
def message_definition(type_name: str) -> str:
    """Return the full ``ros2msg`` definition of a message type, as rosbag2 stores it.

    That is the type's ``.msg`` text followed, for each dependency (recursively, each once),
    by a line of 80 ``=``, a line ``MSG: pkg/Name`` and the dependency's text.

    A service-event type ``pkg/srv/Name_Event`` is defined as rosidl generates it
    (``ServiceEventInfo info``, ``Name_Request[<=1] request``, ``Name_Response[<=1] response``),
    the request and response as dependencies ``MSG: pkg/Name_Request`` and
    ``MSG: pkg/Name_Response``: rosbag2 Jazzy stores the bare ``.srv`` text, which rosbags
    cannot parse; this form every reader of ``ros2msg`` opens (docs/record.md, "Services").
    A type derived from an action, ``pkg/action/Name_FeedbackMessage`` and the others of
    :mod:`bagkit.bag.action_definitions`, is built from ``Name.action`` the same way, its
    sibling parts as dependencies ``MSG: pkg/Name_Feedback`` and so on.

    Args:
        type_name: ``pkg/msg/Name`` (``pkg/Name`` is accepted), ``pkg/srv/Name_Event`` or
            ``pkg/action/Name_Part``.

    Raises:
        UnknownMessageTypeError: the type or one of its dependencies is not installed.
    """
    return compose_definition(type_name, _msg_text)


def compose_definition(type_name: str, text_of: Callable[[str], str]) -> str:
    """:func:`message_definition` with the interface files' texts from ``text_of`` (type name
    -> the text of the ``.msg``, ``.srv`` or ``.action`` file that defines it), for a package
    that is not installed (``bagkit migrate --to-package``).

    Raises:
        UnknownMessageTypeError: what ``text_of`` raises for a type it does not have.
    """
    root = canonical_type_name(type_name)
    inline = _service_event_parts(root, text_of) or _action_parts(root, text_of)
    root_text = inline.pop(root) if inline else text_of(root)
    parts = [root_text]
    seen = {root}
    queue = _dependencies(_split_type_name(root)[0], root_text)
    while queue:
        dependency = queue.pop(0)
        if dependency in seen:
            continue
        seen.add(dependency)
        text = inline[dependency] if dependency in inline else text_of(dependency)
        package, _, name = _split_type_name(dependency)
        parts.append(f"{DEFINITION_SEPARATOR}\nMSG: {package}/{name}\n{text}")
        queue.extend(d for d in _dependencies(package, text) if d not in seen)
    return "\n".join(parts)


def _service_event_parts(type_name: str, text_of: Callable[[str], str]) -> dict[str, str]:
    """The texts of a ``pkg/srv/Name_Event`` and of its request and response; ``{}`` for others.

    Raises:
        UnknownMessageTypeError: the service's ``.srv`` is not installed.
    """
    package, kind, name = _split_type_name(type_name)
    if kind != "srv" or not name.endswith(_SERVICE_EVENT_SUFFIX):
        return {}
    base = name.removesuffix(_SERVICE_EVENT_SUFFIX)
    lines = text_of(type_name).splitlines(keepends=True)
    cut = next((i for i, line in enumerate(lines) if line.strip() == "---"), len(lines))
    request, response = f"{package}/msg/{base}_Request", f"{package}/msg/{base}_Response"
    return {
        type_name: (
            "service_msgs/ServiceEventInfo info\n"
            f"{package}/{base}_Request[<=1] request\n"
            f"{package}/{base}_Response[<=1] response\n"
        ),
        request: "".join(lines[:cut]),
        response: "".join(lines[cut + 1 :]),
    }


def _action_parts(type_name: str, text_of: Callable[[str], str]) -> dict[str, str]:
    """The texts of a ``pkg/action/Name_Part`` and of its sibling parts; ``{}`` for others.

    The root is keyed by its own name, the siblings as the ``pkg/msg/Name_Part`` its fields
    refer to.

    Raises:
        UnknownMessageTypeError: the action's ``.action`` is not installed.
    """
    package, kind, name = _split_type_name(type_name)
    action_part = split_action_part(name) if kind == "action" else None
    if action_part is None:
        return {}
    stem, suffix = action_part
    texts = action_part_texts(package, stem, text_of(type_name))
    parts = {f"{package}/msg/{stem}_{part}": text for part, text in texts.items()}
    parts[type_name] = texts[suffix]
    return parts


@functools.cache
def type_description_hash(type_name: str) -> str:
    """Return the RIHS01 type hash of an installed message type (``RIHS01_<hex>``).

    Raises:
        UnknownMessageTypeError: the type's ``.json`` type description is not installed.
    """
    canonical = canonical_type_name(type_name)
    package, kind, name, _ = _interface_source(canonical)
    path = _interface_file(package, kind, name, ".json")
    if path is None:
        raise UnknownMessageTypeError(f"no type description installed for {canonical}")
    description = json.loads(path.read_text(encoding="utf-8"))
    for entry in description.get("type_hashes", []):
        if entry.get("type_name") == canonical:
            return str(entry["hash_string"])
    raise UnknownMessageTypeError(f"{path} holds no hash for {canonical}")
