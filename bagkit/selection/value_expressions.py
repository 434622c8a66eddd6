"""Value expressions: ``temperature + 273.15``, computed from a message's fields, never eval'd.

The condition language's paths, literals and comparisons (:mod:`~.condition_syntax`, whose
parser this one extends) with arithmetic and a few functions, for values a message does not
hold yet (``bagkit migrate``'s computed fields)::

    value    := or
    or       := and ("or" and)*
    and      := not ("and" not)*
    not      := "not" not | compare
    compare  := sum [OP sum]                         OP: == != < <= > >=
    sum      := product (("+" | "-") product)*
    product  := unary (("*" | "/" | "%") unary)*
    unary    := "-" unary | atom
    atom     := number | 'text' | true | false | path | "(" value ")"
              | FUNCTION "(" value ("," value)* ")"

Functions: ``abs``, ``round``, ``floor``, ``ceil``, ``int``, ``float``, ``str``, ``len``,
``min``, ``max`` and ``if(condition, then, else)``. A path through ``[*]`` gives a list, and
arithmetic on lists and arrays goes element by element.
"""

from __future__ import annotations

import math
import operator
import re
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from bagkit.selection.condition_syntax import _Parser
from bagkit.selection.condition_terms import ANY, Path, Value, path_text
from bagkit.selection.conditions import message_values
from bagkit.selection.errors import SelectionError
from bagkit.words import counted

_TOKEN = re.compile(
    r"""\s*(?:
      (?P<number>(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?(?![\w.]))
    | (?P<string>'(?:[^'\\]|\\.)*'|"(?:[^"\\]|\\.)*")
    | (?P<op>==|!=|<=|>=|<|>)
    | (?P<arith>[-+/%])
    | (?P<punct>[().\[\]*,])
    | (?P<name>[A-Za-z][A-Za-z0-9_]*)
    )""",
    re.VERBOSE,
)
_FUNCTIONS: dict[str, tuple[int, int]] = {  # name -> (fewest, most) arguments
    "abs": (1, 1),
    "round": (1, 2),
    "floor": (1, 1),
    "ceil": (1, 1),
    "int": (1, 1),
    "float": (1, 1),
    "str": (1, 1),
    "len": (1, 1),
    "min": (1, 16),
    "max": (1, 16),
    "if": (3, 3),
}
_COMPARE: dict[str, Callable[[Any, Any], Any]] = {
    "==": operator.eq,
    "!=": operator.ne,
    "<=": operator.le,
    ">=": operator.ge,
    "<": operator.lt,
    ">": operator.gt,
}
_ARITHMETIC: dict[str, Callable[[Any, Any], Any]] = {
    "+": operator.add,
    "-": operator.sub,
    "*": operator.mul,
    "/": operator.truediv,
    "%": operator.mod,
}


@dataclass(frozen=True, slots=True)
class Literal:
    value: Value


@dataclass(frozen=True, slots=True)
class Field:
    path: Path


@dataclass(frozen=True, slots=True)
class Operation:
    """A binary operator (``+``, ``==``, ``and`` ...), ``neg``/``not`` of one item, or a
    function call."""

    op: str
    items: tuple[ValueNode, ...]


ValueNode = Literal | Field | Operation


class _ValueParser(_Parser):
    """The condition parser's tokens, paths and literals, with arithmetic on top."""

    def _tokenize(self, text: str) -> list[tuple[str, str, int]]:
        tokens, at = [], 0
        while text[at:].strip():
            match = _TOKEN.match(text, at)
            if match is None or match.end() == at:
                position = len(text) - len(text[at:].lstrip()) + 1
                raise SelectionError(
                    f"bad expression {text!r}: unexpected {text[position - 1]!r} at column "
                    f"{position}"
                )
            kind = match.lastgroup or ""
            tokens.append((kind, match[kind], match.start(kind)))
            at = match.end()
        return tokens

    def parse_value(self) -> ValueNode:
        if not self.tokens:
            raise SelectionError("bad expression: it is empty")
        tree = self._either()
        if self.at < len(self.tokens):
            self._fail("expected an operator or the end")
        return tree

    def _either(self) -> ValueNode:
        return self._binary(("or",), self._both)

    def _both(self) -> ValueNode:
        return self._binary(("and",), self._negation)

    def _negation(self) -> ValueNode:
        if self._peek("not"):
            self.at += 1
            return Operation("not", (self._negation(),))
        left = self._sum()
        if self._kind() == "op":
            op = self._take()[1]
            return Operation(op, (left, self._sum()))
        return left

    def _sum(self) -> ValueNode:
        return self._binary(("+", "-"), self._product)

    def _product(self) -> ValueNode:
        return self._binary(("*", "/", "%"), self._unary)

    def _binary(self, ops: tuple[str, ...], item: Callable[[], ValueNode]) -> ValueNode:
        tree = item()
        while self._peek(*ops):
            op = self._take()[1]
            tree = Operation(op, (tree, item()))
        return tree

    def _unary(self) -> ValueNode:
        self.depth += 1
        if self.depth > 64:
            raise SelectionError("bad expression: nested deeper than 64")
        try:
            if self._peek("-"):
                self.at += 1
                return Operation("neg", (self._unary(),))
            return self._atom()
        finally:
            self.depth -= 1

    def _atom(self) -> ValueNode:
        if self._peek("("):
            self.at += 1
            inner = self._either()
            self._expect(")")
            return inner
        kind = self._kind()
        if kind == "name" and self._peek_at(1, "(") and not self._peek("not", "and", "or"):
            return self._call()
        if kind == "name" and not self._peek("true", "false"):
            return Field(self._path())
        if kind == "number":
            text = self._take()[1]
            return Literal(int(text) if text.isdigit() else float(text))
        if kind == "string":
            return Literal(re.sub(r"\\(.)", r"\1", self._take()[1][1:-1]))
        if self._peek("true", "false"):
            return Literal(self._take()[1] == "true")
        self._fail("expected a value, a field path or '('")

    def _call(self) -> ValueNode:
        _, name, position = self._take()
        if name not in _FUNCTIONS:
            raise SelectionError(
                f"bad expression {self.text!r}: unknown function {name!r} at column "
                f"{position + 1}; known: {', '.join(_FUNCTIONS)}"
            )
        self._expect("(")
        arguments = [self._either()]
        while self._peek(","):
            self.at += 1
            arguments.append(self._either())
        self._expect(")")
        fewest, most = _FUNCTIONS[name]
        if not fewest <= len(arguments) <= most:
            raise SelectionError(
                f"bad expression {self.text!r}: {name}() takes "
                f"{'' if fewest == most else f'{fewest} to '}{counted(most, 'argument')}, "
                f"not {len(arguments)}"
            )
        return Operation(name, tuple(arguments))


def parse_value_expression(text: str) -> ValueNode:
    """The tree of ``text``.

    Raises:
        SelectionError: naming the column of the first problem.
    """
    parser = _ValueParser(text)
    return parser.parse_value()


def expression_paths(node: ValueNode) -> list[Path]:
    """Every field path ``node`` reads, in the order written."""
    if isinstance(node, Field):
        return [node.path]
    if isinstance(node, Operation):
        return [path for item in node.items for path in expression_paths(item)]
    return []


def evaluate_value(node: ValueNode, message: Any) -> Any:
    """The value of ``node`` for a decoded message (a path through ``[*]`` gives a list).

    Raises:
        SelectionError: a path the message does not have, or operands that do not go together
            (text plus a number, a division by zero).
    """
    if isinstance(node, Literal):
        return node.value
    if isinstance(node, Field):
        values = message_values(message, node.path)
        if ANY in node.path[1:] or node.path[0] == ANY:
            return _as_array(values)
        if not values:
            raise SelectionError(f"{path_text(node.path)}: the index is past the array's end")
        return values[0]
    op = node.op
    if op == "if":
        condition = evaluate_value(node.items[0], message)
        return evaluate_value(node.items[1 if condition else 2], message)
    if op in ("and", "or"):
        left = evaluate_value(node.items[0], message)
        if bool(left) == (op == "or"):
            return bool(left)
        return bool(evaluate_value(node.items[1], message))
    values = [evaluate_value(item, message) for item in node.items]
    try:
        return _apply(op, values)
    except (TypeError, ValueError, ZeroDivisionError, OverflowError) as exc:
        raise SelectionError(f"{_describe(node)}: {exc}") from None


def _apply(op: str, values: list[Any]) -> Any:
    if op in _ARITHMETIC:
        left, right = (_as_array(v) if isinstance(v, list) else v for v in values)
        if op == "/" and not hasattr(right, "dtype") and right == 0:
            raise ZeroDivisionError("division by zero")
        return _ARITHMETIC[op](left, right)
    if op in _COMPARE:
        return _COMPARE[op](values[0], values[1])
    if op == "neg":
        return -_as_array(values[0]) if isinstance(values[0], list) else -values[0]
    if op == "not":
        return not values[0]
    if op in ("min", "max"):
        found = values[0] if len(values) == 1 else values
        return (min if op == "min" else max)(found)
    if op == "round":
        return round(values[0], int(values[1])) if len(values) == 2 else round(values[0])
    if op == "len":
        return len(values[0])
    functions: dict[str, Callable[[Any], Any]] = {
        "abs": abs,
        "floor": math.floor,
        "ceil": math.ceil,
        "int": int,
        "float": float,
        "str": str,
    }
    return functions[op](values[0])


def _as_array(values: Any) -> Any:
    import numpy as np

    return np.asarray(values)


def _describe(node: ValueNode) -> str:
    if isinstance(node, Field):
        return path_text(node.path)
    if isinstance(node, Literal):
        return repr(node.value)
    if node.op in _FUNCTIONS:
        return f"{node.op}({', '.join(map(_describe, node.items))})"
    if node.op in ("neg", "not"):
        return f"{'-' if node.op == 'neg' else 'not '}{_describe(node.items[0])}"
    return f"{_describe(node.items[0])} {node.op} {_describe(node.items[1])}"
