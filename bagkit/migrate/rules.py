"""The rules file of ``bagkit migrate``: what the field-by-field defaults cannot know.

One YAML mapping, keyed by message type (the stored name, ``pkg/msg/Name`` or ``pkg/Name``)::

    my_robot_msgs/msg/BatteryReport:
      rename: {voltage: pack_voltage}          # old field -> new field
      compute:                                 # new field: expression over the old message
        temperature_k: temperature + 273.15
      drop: [legacy_flag]                      # old fields dropped knowingly
      function: my_migrations:battery_v2       # last resort: f(old, new) -> new (or None)

Expressions are :mod:`bagkit.selection.value_expressions` (the condition language with
arithmetic), parsed here, never eval'd. A function is imported only when a message of its
type is migrated.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from bagkit.bag.definitions import canonical_type_name
from bagkit.bag.safe_yaml import load as load_yaml
from bagkit.migrate.errors import RuleError
from bagkit.selection.errors import SelectionError
from bagkit.selection.value_expressions import ValueNode, parse_value_expression

_KEYS = ("rename", "compute", "drop", "function")
MAX_RULES_BYTES = 1024 * 1024


@dataclass(frozen=True, slots=True)
class TypeRules:
    """The rules of one message type.

    Attributes:
        source: where they were written (``rules.yaml: pkg/msg/Name``), for error messages.
        rename: old field name -> new field name.
        compute: new field name -> (expression text, its tree).
        drop: old fields whose values may be lost.
        function: ``module:function`` or "".
    """

    source: str
    rename: dict[str, str] = field(default_factory=dict)
    compute: dict[str, tuple[str, ValueNode]] = field(default_factory=dict)
    drop: tuple[str, ...] = ()
    function: str = ""

    def label(self, kind: str, name: str = "") -> str:
        """How a rule is named in messages: ``rules.yaml: pkg/msg/T compute x``."""
        return f"{self.source} {kind}{f' {name}' if name else ''}"

    def names(self) -> list[str]:
        """Every rule, named as :meth:`label` names it."""
        found = [self.label("rename", f"{old} -> {new}") for old, new in self.rename.items()]
        found += [self.label("compute", name) for name in self.compute]
        found += [self.label("drop", name) for name in self.drop]
        return found + ([self.label("function", self.function)] if self.function else [])


@dataclass(frozen=True, slots=True)
class Rules:
    """Every type's rules (none: field-by-field defaults only)."""

    types: Mapping[str, TypeRules] = field(default_factory=dict)

    def of(self, type_name: str) -> TypeRules | None:
        """The rules of ``type_name`` (canonical name), if any."""
        return self.types.get(canonical_type_name(type_name))


def load_rules(path: Path) -> Rules:
    """Parse the rules file at ``path``.

    Raises:
        RuleError: the file cannot be read, is not YAML, or a rule is malformed (an unknown
            key, an expression that does not parse, a function not written ``module:name``).
    """
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise RuleError(f"rules {path}: cannot be read ({exc})") from None
    try:
        document = load_yaml(text, max_bytes=MAX_RULES_BYTES)
    except yaml.YAMLError as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise RuleError(f"rules {path}: not YAML ({first})") from None
    if document is None:
        return Rules()
    if not isinstance(document, dict):
        raise RuleError(f"rules {path}: must be a mapping of message types to their rules")
    return Rules(
        {_type_name(path, key): _type_rules(path, key, value) for key, value in document.items()}
    )


def _type_name(path: Path, key: Any) -> str:
    if not isinstance(key, str) or key.count("/") not in (1, 2):
        raise RuleError(f"rules {path}: {key!r} is not a message type (pkg/msg/Name)")
    return canonical_type_name(key)


def _type_rules(path: Path, key: str, value: Any) -> TypeRules:
    source = f"{path.name}: {canonical_type_name(key)}"
    if not isinstance(value, dict):
        raise RuleError(f"{source}: its rules must be a mapping ({', '.join(_KEYS)})")
    unknown = [k for k in value if k not in _KEYS]
    if unknown:
        raise RuleError(f"{source}: unknown rule {unknown[0]!r} (known: {', '.join(_KEYS)})")
    rename = _names(source, "rename", value.get("rename") or {})
    compute: dict[str, tuple[str, ValueNode]] = {}
    for name, text in _names(source, "compute", value.get("compute") or {}, any_value=True).items():
        expression = str(text).lower() if isinstance(text, bool) else str(text)
        try:
            compute[name] = (expression, parse_value_expression(expression))
        except SelectionError as exc:
            raise RuleError(f"{source} compute {name}: {exc}") from None
    drop = value.get("drop") or []
    if isinstance(drop, str):
        drop = [drop]
    if not isinstance(drop, list) or not all(isinstance(d, str) for d in drop):
        raise RuleError(f"{source} drop: must be a list of field names")
    function = value.get("function") or ""
    if function and (not isinstance(function, str) or function.count(":") != 1):
        raise RuleError(f"{source} function: must read module.path:function, not {function!r}")
    return TypeRules(source, rename, compute, tuple(drop), function)


def _names(source: str, kind: str, value: Any, *, any_value: bool = False) -> dict[str, Any]:
    if not isinstance(value, dict) or not all(isinstance(k, str) for k in value):
        raise RuleError(f"{source} {kind}: must be a mapping of field names")
    if not any_value and not all(isinstance(v, str) for v in value.values()):
        raise RuleError(f"{source} {kind}: must map field names to field names")
    if not all(isinstance(v, str | int | float | bool) for v in value.values()):
        raise RuleError(f"{source} {kind}: each value must be an expression")
    return dict(value)


def load_function(rules: TypeRules) -> Callable[[Any, Any], Any]:
    """The function a type's ``function`` rule names.

    Raises:
        RuleError: it cannot be imported or is not callable.
    """
    module_name, _, attribute = rules.function.partition(":")
    label = rules.label("function", rules.function)
    try:
        module = importlib.import_module(module_name)
    except Exception as exc:  # the user's module: any failure on import is a bad rule
        raise RuleError(f"{label}: cannot import {module_name} ({exc})") from None
    found: Any = module
    for part in attribute.split("."):
        found = getattr(found, part, None)
    if not callable(found):
        raise RuleError(f"{label}: {module_name} has no function {attribute}")
    return found
