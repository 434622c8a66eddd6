"""A definition text as a bag stores it for one type, parsed into the types it defines.

Sections are separated by a line of 80 ``=``; each after the first starts with a header line
naming its form and type. The forms rosbag2 writes:

- ``ros2msg``: the type's ``.msg`` text, then each dependency's after ``MSG: pkg/msg/Name``.
- ``ros2idl``: every type, the root included, after ``IDL: pkg/msg/Name`` (:mod:`~.idl`).
- A service event ``pkg/srv/Name_Event``: the ``.srv`` text (Jazzy: as the first section;
  Kilted on: after ``SRV: pkg/srv/Name``), then its dependencies; the event type is built as
  rosidl generates it (``ServiceEventInfo info``, ``Name_Request[<=1] request``, ...).
- The five topics of an action (Kilted on): the ``.action`` text after ``ACTION:
  pkg/action/Name``, then its dependencies, whatever the topic's type. The parts are built from
  it (:mod:`bagkit.bag.action_definitions`); the status and cancel topics' types are the same
  for every action (``action_msgs``): from the text's sections when it has them, else from
  :data:`COMMON_SERVICES` or rosbags' types (:class:`~.message_types.MessageTypes`).
"""

from __future__ import annotations

import re

from bagkit.bag.action_definitions import action_part_texts, split_action_part
from bagkit.decode.errors import DefinitionError
from bagkit.decode.msgdef import Nodetype, TypeDef, parse_message, type_name

_HEADER = re.compile(r"(MSG|IDL|SRV|ACTION):\s*(\S+)\s*\Z")
_SERVICE_EVENT_INFO = "service_msgs/msg/ServiceEventInfo"
COMMON_SERVICES = {
    "action_msgs/srv/CancelGoal": (
        "action_msgs/GoalInfo goal_info\n---\n"
        "int8 ERROR_NONE=0\nint8 ERROR_REJECTED=1\nint8 ERROR_UNKNOWN_GOAL_ID=2\n"
        "int8 ERROR_GOAL_TERMINATED=3\nint8 return_code\naction_msgs/GoalInfo[] goals_canceling\n"
    ),
}
"""The ``.srv`` text of services every action has (rosbags has no types for them)."""


def parse_stored(text: str, name: str) -> dict[str, TypeDef]:
    """The types that ``text``, stored for bag type ``name``, defines (``name`` among them
    unless the text leaves it to the common types).

    Raises:
        DefinitionError: a section that does not parse, an unknown header, a type defined
            twice differently.
    """
    root = type_name(name)
    types: dict[str, TypeDef] = {}
    for kind, header, lines in _sections(text):
        if kind == "":
            if header == "only" or any(line.strip() for line in lines):
                _add(types, _root_types(root, lines))
        elif kind == "MSG":
            typename = type_name(header)
            _add(types, {typename: parse_message(lines, typename)})
        elif kind == "IDL":
            from bagkit.decode.idl import parse_idl_section  # ros2idl texts only: rare

            _add(types, parse_idl_section("\n".join(lines), header))
        elif kind == "SRV":
            _add(types, _service_types(type_name(header), lines))
        else:
            _add(types, _action_types(type_name(header), lines))
    if root not in types:
        _add(types, _derived(root, types))
    return types


def _sections(text: str) -> list[tuple[str, str, list[str]]]:
    """``(form, type, lines)`` of each section; the first one's form is ``""`` (no header),
    its type ``"only"`` when it is the whole text.

    Raises:
        DefinitionError: a later section without a known header.
    """
    chunks: list[list[str]] = [[]]
    for line in text.splitlines():
        if line.strip() and set(line.strip()) == {"="}:
            chunks.append([])
        else:
            chunks[-1].append(line)
    sections: list[tuple[str, str, list[str]]] = []
    for index, lines in enumerate(chunks):
        first = next((i for i, line in enumerate(lines) if line.strip()), len(lines))
        match = _HEADER.match(lines[first].strip()) if first < len(lines) else None
        if match:
            sections.append((match[1], match[2], lines[first + 1 :]))
        elif index == 0:
            sections.append(("", "only" if len(chunks) == 1 else "", lines))
        else:
            header = lines[first][:60] if first < len(lines) else ""
            raise DefinitionError(
                f"a section starts with {header!r}, not 'MSG:', 'IDL:', 'SRV:' or 'ACTION:' "
                "and a type"
            )
    return sections


def _add(types: dict[str, TypeDef], found: dict[str, TypeDef]) -> None:
    for typename, definition in found.items():
        # Some writers repeat a dependency used twice: harmless when it is the same.
        if types.setdefault(typename, definition) != definition:
            raise DefinitionError(f"{typename} is defined twice, differently")


def _root_types(root: str, lines: list[str]) -> dict[str, TypeDef]:
    """The first section's types: ``root``'s ``.msg``, or for a service event its ``.srv``
    (rosbag2 Jazzy), from which the event is built."""
    base = root.removesuffix("_Event")
    if "/srv/" in root and base != root and any(line.strip() == "---" for line in lines):
        types = _service_types(base, lines)
        types[root] = _event(base)
        return types
    return {root: parse_message(lines, root)}


def _service_types(service: str, lines: list[str]) -> dict[str, TypeDef]:
    """``pkg/srv/Name_Request`` and ``_Response`` from a ``.srv`` text.

    Raises:
        DefinitionError: no ``---`` line.
    """
    cut = next((i for i, line in enumerate(lines) if line.strip() == "---"), None)
    if cut is None:
        raise DefinitionError(f"SRV {service} has no '---' line between request and response")
    return {
        f"{service}_Request": parse_message(lines[:cut], f"{service}_Request"),
        f"{service}_Response": parse_message(lines[cut + 1 :], f"{service}_Response"),
    }


def _event(service: str) -> TypeDef:
    """``pkg/srv/Name_Event`` as rosidl generates it."""
    return (
        [],
        [
            ("info", (Nodetype.NAME, _SERVICE_EVENT_INFO)),
            ("request", (Nodetype.SEQUENCE, ((Nodetype.NAME, f"{service}_Request"), 1))),
            ("response", (Nodetype.SEQUENCE, ((Nodetype.NAME, f"{service}_Response"), 1))),
        ],
    )


def _action_types(action: str, lines: list[str]) -> dict[str, TypeDef]:
    """Every part rosidl derives from an ``.action`` text, as ``pkg/msg/Name_Part``.

    Raises:
        DefinitionError: not three sections (goal, result, feedback).
    """
    separators = sum(line.strip() == "---" for line in lines)
    if separators != 2:
        raise DefinitionError(
            f"ACTION {action} has {separators + 1} sections, not 3 (goal, result, feedback)"
        )
    package, _, stem = action.split("/")
    texts = action_part_texts(package, stem, "\n".join(lines))
    return {
        f"{package}/msg/{stem}_{part}": parse_message(
            text.splitlines(), f"{package}/msg/{stem}_{part}"
        )
        for part, text in texts.items()
    }


def _derived(root: str, types: dict[str, TypeDef]) -> dict[str, TypeDef]:
    """``root`` from what the sections defined: an action's part (defined as ``pkg/msg/``), a
    service event around its request and response; ``{}`` when the text leaves it to the
    common types (``action_msgs/msg/GoalStatusArray`` under an ``ACTION:`` text)."""
    package, kind, name = root.split("/")
    part = split_action_part(name) if kind == "action" else None
    if part is not None and f"{package}/msg/{name}" in types:
        return {root: types[f"{package}/msg/{name}"]}
    base = root.removesuffix("_Event")
    if kind != "srv" or base == root:
        return {}
    found = {base + "_Event": _event(base)}
    if f"{base}_Request" not in types and base in COMMON_SERVICES:
        found.update(_service_types(base, COMMON_SERVICES[base].splitlines()))
    return found
