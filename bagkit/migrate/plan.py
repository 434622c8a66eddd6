"""Where each field of the new definition comes from, per type: the converters of a migration.

For a pair of types (stored -> new) every new field is, in this order of precedence, computed
by a ``compute`` rule, copied from the old field a ``rename`` names, copied from the old field
of the same name (made to fit: :mod:`~bagkit.migrate.values`), or given its default. Nested
message fields are converted the same way with their own type's rules; a type whose
definition did not change and has no rules is passed through as decoded. Old fields that no
rule reads, renames or drops are the data a migration would lose: :class:`Planner` lists them
and refuses them unless ``allow_drop``. A type's ``function`` rule then gets the old message
and the new one and may change or replace the latter; what it returns must fit as well.
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from bagkit.bag.definitions import canonical_type_name
from bagkit.decode.msgdef import Nodetype, TypeDefinitions
from bagkit.migrate.errors import DataLossError, MigrateError, RuleError
from bagkit.migrate.rules import Rules, TypeRules, load_function
from bagkit.migrate.values import (
    NUMPY_TYPES,
    ValueMismatchError,
    check_length,
    default_value,
    describe,
    fit_numbers,
    fit_scalar,
)
from bagkit.selection.condition_terms import ANY, path_text
from bagkit.selection.errors import SelectionError
from bagkit.selection.value_expressions import evaluate_value, expression_paths

Convert = Callable[[Any], Any]
_TEXT = ("string", "wstring")


def _identity(value: Any) -> Any:
    return value


@dataclass
class Planner:
    """Converters from ``old`` types to ``new`` types (two typestores), built once per pair.

    Attributes:
        rules_run: the labels of every rule a converter applies, in the order planned.
        dropped: ``Type: field (type)`` of every old field whose values are not carried over.
    """

    old: TypeDefinitions
    new: TypeDefinitions
    rules: Rules = field(default_factory=Rules)
    allow_drop: bool = False
    rules_run: list[str] = field(default_factory=list)
    dropped: list[str] = field(default_factory=list)
    _converters: dict[tuple[str, str], Convert] = field(default_factory=dict)
    _unchanged: dict[tuple[str, str], bool] = field(default_factory=dict)

    def converter(self, old_type: str, new_type: str) -> Convert:
        """old message object -> new message object, for ``old_type`` -> ``new_type``.

        Raises:
            RuleError: a rule names a field that does not exist.
            DataLossError: fields would be lost without a rule (and not ``allow_drop``).
            MigrateError: a field changed type with no way to convert it and no rule.
        """
        key = (old_type, new_type)
        found = self._converters.get(key)
        if found is None:
            if self.unchanged(old_type, new_type):
                found = _identity
            else:
                # Placeholder first: a type graph is checked acyclic, but be safe.
                self._converters[key] = _identity
                found = self._build(old_type, new_type)
            self._converters[key] = found
        return found

    def unchanged(self, old_type: str, new_type: str) -> bool:
        """Whether the two definitions (and those they nest) are the same and have no rules."""
        key = (old_type, new_type)
        if key not in self._unchanged:
            self._unchanged[key] = False  # cut cycles
            same = (
                old_type == new_type
                and self.rules.of(new_type) is None
                and list(self.old.fielddefs[old_type][1]) == list(self.new.fielddefs[new_type][1])
                and all(
                    self.unchanged(nested, nested)
                    for nested in _nested_types(self.old.fielddefs[old_type][1])
                )
            )
            self._unchanged[key] = same
        return self._unchanged[key]

    def _build(self, old_type: str, new_type: str) -> Convert:
        old_fields = dict(self.old.fielddefs[old_type][1])
        rules = self.rules.of(new_type) or self.rules.of(old_type)
        if rules is not None:
            self._check(rules, old_type, old_fields, dict(self.new.fielddefs[new_type][1]))
            self.rules_run.extend(rules.names())
        parts, read = self._parts(old_fields, new_type, rules)
        kept = read | set(rules.drop if rules else ())
        lost = [f"{old_type}: {n} ({describe(d)})" for n, d in old_fields.items() if n not in kept]
        if lost and not (rules and rules.function):
            if not self.allow_drop:
                raise DataLossError(
                    f"{'; '.join(lost)}: the migration would drop these values; name them "
                    "under drop: (or rename/compute) in a rules file",
                    "allow_drop",
                )
            self.dropped.extend(lost)
        make = self.new.types[new_type]
        if rules is None or not rules.function:
            return lambda old: make(*(part(old) for part in parts))
        function = _function_step(rules)
        refit = self._refitter(new_type, rules.label("function", rules.function))
        return lambda old: refit(function(old, make(*(part(old) for part in parts))))

    def _parts(
        self, old_fields: dict[str, Any], new_type: str, rules: TypeRules | None
    ) -> tuple[list[Convert], set[str]]:
        """A value maker per new field (old message -> value), and the old fields read."""
        renames = rules.rename if rules else {}
        renamed = {new: old for old, new in renames.items()}
        read = set(renamed.values())
        parts: list[Convert] = []
        for name, desc in self.new.fielddefs[new_type][1]:
            if rules is not None and name in rules.compute:
                tree = rules.compute[name][1]
                read |= {str(p[0]) for p in expression_paths(tree)}
                parts.append(self._computed(tree, desc, rules.label("compute", name)))
                continue
            source = renamed.get(name, None if name in renames else name)
            if source is not None and source in old_fields:
                convert = self._field(old_fields[source], desc, f"{new_type}.{name}")
                if convert is not None:
                    read.add(source)
                    parts.append(_getter(source, convert, f"{new_type}.{name}"))
                    continue
            parts.append(_constant(default_value(desc, self._default_message)))
        return parts, read

    def _field(self, old: Any, new: Any, where: str) -> Convert | None:
        """The converter of one copied field; None when the types do not convert (the old
        field is then lost, and the new one takes its default), or raise MigrateError."""
        convert = self._convertible(old, new)
        if convert is not None:
            return convert
        problem = f"{where} changed type ({describe(old)} -> {describe(new)})"
        if not self.allow_drop:
            raise MigrateError(
                f"{problem} and cannot be converted: give it a compute rule", "allow_drop"
            )
        return None

    def _convertible(self, old: Any, new: Any) -> Convert | None:
        old_kind, old_rest = old
        new_kind, new_rest = new
        if old_kind == Nodetype.BASE and new_kind == Nodetype.BASE:
            text = old_rest[0] in _TEXT
            if text != (new_rest[0] in _TEXT):
                return None
            if describe(old) == describe(new):
                return _identity
            base, bound = new_rest
            return lambda value: fit_scalar(value, base, bound or 0)
        if old_kind == Nodetype.NAME and new_kind == Nodetype.NAME:
            return self.converter(old_rest, new_rest)
        arrays = (Nodetype.ARRAY, Nodetype.SEQUENCE)
        if old_kind not in arrays or new_kind not in arrays:
            return None
        element = self._convertible(old_rest[0], new_rest[0])
        if element is None:
            return None
        if element is _identity and describe(old) == describe(new):
            return _identity
        sub, size = new_rest
        if sub[0] == Nodetype.BASE and sub[1][0] in NUMPY_TYPES:
            base = sub[1][0]

            def numbers(value: Any) -> Any:
                array = fit_numbers(value, base)
                check_length(len(array), new_kind, size)
                return array

            return numbers

        def items(value: Any) -> Any:
            check_length(len(value), new_kind, size)
            return [element(item) for item in value]

        return items

    def _computed(self, tree: Any, desc: Any, label: str) -> Convert:
        fit = self._fitter(desc)

        def compute(old: Any) -> Any:
            try:
                return fit(evaluate_value(tree, old))
            except (SelectionError, ValueMismatchError) as exc:
                raise RuleError(f"{label}: {exc}") from None

        return compute

    def _fitter(self, desc: Any) -> Convert:
        """Any value (an expression's, a function's) made to fit a field of ``desc``."""
        kind, rest = desc
        if kind == Nodetype.BASE:
            base, bound = rest
            return lambda value: fit_scalar(value, base, bound or 0)
        if kind == Nodetype.NAME:
            return lambda value: self._message(value, rest)
        sub, size = rest
        if sub[0] == Nodetype.BASE and sub[1][0] in NUMPY_TYPES:
            base = sub[1][0]

            def numbers(value: Any) -> Any:
                array = fit_numbers(value, base)
                check_length(len(array), kind, size)
                return array

            return numbers
        element = self._fitter(sub)

        def items(value: Any) -> Any:
            if isinstance(value, str | bytes) or not hasattr(value, "__len__"):
                raise ValueMismatchError(f"{value!r} is not an array ({describe(desc)})")
            check_length(len(value), kind, size)
            return [element(item) for item in value]

        return items

    def _message(self, value: Any, new_type: str) -> Any:
        old_type = getattr(value, "__msgtype__", None)
        if old_type is None:
            raise ValueMismatchError(f"{value!r} is not a {new_type} message")
        old_type = canonical_type_name(old_type)
        if isinstance(value, self.new.types.get(new_type, ())):
            return value
        if old_type not in self.old.fielddefs:
            raise ValueMismatchError(f"a {old_type} message is not a {new_type}")
        return self.converter(old_type, new_type)(value)

    def _refitter(self, new_type: str, label: str) -> Convert:
        fields = [(name, self._fitter(desc)) for name, desc in self.new.fielddefs[new_type][1]]
        make = self.new.types[new_type]

        def refit(message: Any) -> Any:
            try:
                return make(*(fit(getattr(message, name)) for name, fit in fields))
            except AttributeError as exc:
                raise RuleError(f"{label}: returned no {new_type} ({exc})") from None
            except ValueMismatchError as exc:
                raise RuleError(f"{label}: {exc}") from None

        return refit

    def _default_message(self, type_name: str) -> Any:
        fields = self.new.fielddefs[type_name][1]
        return self.new.types[type_name](
            *(default_value(desc, self._default_message) for _, desc in fields)
        )

    def _check(
        self, rules: TypeRules, old_type: str, old: dict[str, Any], new: dict[str, Any]
    ) -> None:
        """Raise RuleError for a rule naming a field that does not exist."""
        for old_name, new_name in rules.rename.items():
            label = rules.label("rename", f"{old_name} -> {new_name}")
            _require(old_name in old, label, f"stored {old_type} has no field {old_name!r}")
            _require(new_name in new, label, f"the new {old_type} has no field {new_name!r}")
        for name in rules.drop:
            _require(
                name in old, rules.label("drop", name), f"stored {old_type} has no field {name!r}"
            )
        for name, (_, tree) in rules.compute.items():
            label = rules.label("compute", name)
            _require(name in new, label, f"the new {old_type} has no field {name!r}")
            for path in expression_paths(tree):
                problem = self._path_problem(old_type, path)
                _require(problem is None, label, problem or "")

    def _path_problem(self, type_name: str, path: tuple[Any, ...]) -> str | None:
        """Why ``path`` names no field of stored ``type_name`` (None: it does)."""
        fields = dict(self.old.fielddefs[type_name][1])
        desc: Any = None
        for step in path:
            if isinstance(step, str):
                if desc is not None:
                    if desc[0] != Nodetype.NAME:
                        return f"{path_text(path)}: {step!r} is inside no message"
                    fields = dict(self.old.fielddefs[desc[1]][1])
                if step not in fields:
                    return f"stored {type_name} has no field {path_text(path)!r}"
                desc = fields[step]
            elif desc is None or desc[0] not in (Nodetype.ARRAY, Nodetype.SEQUENCE):
                return f"{path_text(path)}: indexes what is not an array"
            else:
                desc = desc[1][0]
                if step != ANY and desc is None:
                    return f"{path_text(path)}: bad index"
        return None


def _require(condition: bool, label: str, problem: str) -> None:
    if not condition:
        raise RuleError(f"{label}: {problem}")


def _getter(name: str, convert: Convert, where: str) -> Convert:
    if convert is _identity:
        return lambda old: getattr(old, name)

    def get(old: Any) -> Any:
        try:
            return convert(getattr(old, name))
        except ValueMismatchError as exc:
            raise MigrateError(f"{where}: the old value does not fit: {exc}") from None

    return get


def _constant(value: Any) -> Convert:
    """A default for every message, copied so that no two share a mutable one."""
    if hasattr(value, "copy"):
        return lambda _old: value.copy()
    if isinstance(value, list):
        return lambda _old: copy.deepcopy(value)
    return lambda _old: value


def _function_step(rules: TypeRules) -> Callable[[Any, Any], Any]:
    label = rules.label("function", rules.function)
    loaded: list[Callable[[Any, Any], Any]] = []

    def run(old: Any, new: Any) -> Any:
        if not loaded:
            loaded.append(load_function(rules))
        try:
            result = loaded[0](old, new)
        except Exception as exc:  # the user's code: any failure is the rule's
            raise RuleError(f"{label}: {type(exc).__name__}: {exc}") from None
        return new if result is None else result

    return run


def _nested_types(fields: list[tuple[str, Any]]) -> list[str]:
    found = []
    for _, desc in fields:
        element = desc
        while element[0] in (Nodetype.ARRAY, Nodetype.SEQUENCE):
            element = element[1][0]
        if element[0] == Nodetype.NAME:
            found.append(element[1])
    return found
