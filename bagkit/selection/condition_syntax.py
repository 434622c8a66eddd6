"""The condition language's syntax: tokens, the tree of a condition, and its parser.

Grammar (docs/cli.md)::

    condition  := or
    or         := and ("or" and)*
    and        := not ("and" not)*
    not        := "not" not | ("(" or ")" | term) ["for" DURATION]
    term       := path OP value                           OP: == != < <= > >=
                | "gap" OP DURATION
                | "rate" OP NUMBER "Hz" "over" DURATION
                | "unchanged" "(" path | "*" ")"
                | "delta" "(" path ")" OP NUMBER
                | ("isnan" | "isinf") "(" path | "*" ")"
                | "age" "(" path ")" OP DURATION
                | "latency" "(" TOPIC "->" TOPIC "," path ")" OP DURATION
    path       := NAME ("." NAME | "[" INDEX "]" | "[*]" | "[]")*
    value      := number | 'text' | "text" | true | false
    DURATION   := 2s, 500ms, 1m30s, 100ns (or "2 s")

``for`` applies to the term or parenthesized group just before it. ``gap`` and ``rate`` are
terms only with their unit (``rate > 5`` compares a field named ``rate``). Recursive descent,
bounded in length and depth; an error names the column of the first problem. Names start with
a letter: ``_private`` attributes cannot be named, so a condition can only read a message's
fields. The tree is :mod:`~.condition_terms`, evaluation :mod:`bagkit.selection.conditions`
(per message) and :mod:`bagkit.selection.temporal` (over time).
"""

from __future__ import annotations

import difflib
import math
import re
from collections.abc import Callable
from typing import NoReturn

from bagkit.selection.condition_terms import (
    ANY,
    Age,
    Check,
    Comparison,
    Delta,
    Expression,
    For,
    Gap,
    Latency,
    Node,
    Path,
    Rate,
    Step,
    Unchanged,
    Value,
    path_text,
)
from bagkit.selection.errors import SelectionError
from bagkit.selection.times import parse_duration

__all__ = ["ANY", "Comparison", "Expression", "Node", "Step", "parse_expression"]

MAX_LENGTH = 4096
MAX_DEPTH = 64

_TOKEN = re.compile(
    r"""\s*(?:
      (?P<number>[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?(?![\w.]))
    | (?P<quantity>(?:\d+\.?\d*|\.\d+)[A-Za-z]+(?:(?:\d+\.?\d*|\.\d+)[A-Za-z]+)*(?![\w.]))
    | (?P<string>'(?:[^'\\]|\\.)*'|"(?:[^"\\]|\\.)*")
    | (?P<arrow>->)
    | (?P<op>==|!=|<=|>=|<|>)
    | (?P<punct>[().\[\]*,])
    | (?P<topic>/[A-Za-z0-9_/~]*)
    | (?P<name>[A-Za-z][A-Za-z0-9_]*)
    )""",
    re.VERBOSE,
)
_KEYWORDS = {"and", "or", "not", "true", "false", "for"}
_FUNCTIONS = ("age", "delta", "isinf", "isnan", "latency", "unchanged")
_UNITS = {"Hz", "h", "m", "s", "ms", "ns"}
_DURATION_HELP = "a duration (500ms, 2s, 1m30s)"


class _Parser:
    """Recursive descent over the tokens of one condition, depth bounded."""

    def __init__(self, text: str) -> None:
        if len(text) > MAX_LENGTH:
            raise SelectionError(f"bad condition: longer than {MAX_LENGTH} characters")
        self.text = text
        self.tokens = self._tokenize(text)
        self.at = 0
        self.depth = 0

    def parse(self) -> Expression:
        if not self.tokens:
            raise SelectionError("bad condition: it is empty")
        tree = self._or()
        if self.at < len(self.tokens):
            self._fail("expected 'and', 'or', 'for' or the end")
        return tree

    def _tokenize(self, text: str) -> list[tuple[str, str, int]]:
        tokens, at = [], 0
        while text[at:].strip():
            match = _TOKEN.match(text, at)
            if match is None or match.end() == at:
                position = len(text) - len(text[at:].lstrip()) + 1
                character = text[position - 1]
                raise SelectionError(
                    f"bad condition {text!r}: unexpected {character!r} at column {position}"
                )
            kind = match.lastgroup or ""
            tokens.append((kind, match[kind], match.start(kind)))
            at = match.end()
        return tokens

    def _fail(self, expected: str) -> NoReturn:
        if self.at < len(self.tokens):
            _, value, position = self.tokens[self.at]
            found = f"{value!r} at column {position + 1}"
        else:
            found = "the end"
        raise SelectionError(f"bad condition {self.text!r}: {expected}, found {found}")

    def _peek(self, *values: str) -> bool:
        return self.at < len(self.tokens) and self.tokens[self.at][1] in values

    def _peek_at(self, offset: int, value: str) -> bool:
        at = self.at + offset
        return at < len(self.tokens) and self.tokens[at][1] == value

    def _kind(self, offset: int = 0) -> str:
        at = self.at + offset
        return self.tokens[at][0] if at < len(self.tokens) else ""

    def _take(self) -> tuple[str, str, int]:
        token = self.tokens[self.at]
        self.at += 1
        return token

    def _expect(self, value: str) -> None:
        if not self._peek(value):
            self._fail(f"expected {value!r}")
        self.at += 1

    def _or(self) -> Expression:
        return self._chain("or", self._and)

    def _and(self) -> Expression:
        return self._chain("and", self._not)

    def _chain(self, word: str, item: Callable[[], Expression]) -> Expression:
        items = [item()]
        while self._peek(word):
            self.at += 1
            items.append(item())
        return items[0] if len(items) == 1 else Node(word, tuple(items))

    def _not(self) -> Expression:
        self.depth += 1
        if self.depth > MAX_DEPTH:
            raise SelectionError(f"bad condition: nested deeper than {MAX_DEPTH}")
        try:
            if self._peek("not"):
                self.at += 1
                return Node("not", (self._not(),))
            if self._peek("("):
                self.at += 1
                inner = self._or()
                self._expect(")")
            else:
                inner = self._term()
            if self._peek("for"):
                self.at += 1
                inner = For(inner, self._duration("'for'"))
            return inner
        finally:
            self.depth -= 1

    def _term(self) -> Expression:
        if (
            self._kind() == "name"
            and self._kind(1) == "punct"
            and self.tokens[self.at + 1][1] == "("
        ):
            return self._function()
        if self._kind() == "topic":
            self._fail("expected a field path (topics go in latency(SOURCE -> TARGET, path))")
        path = self._path()
        op = self._op()
        value, unit = self._value()
        if path == ("gap",) and unit is not None:
            if unit == "Hz":
                self._unit_error("gap", value, unit, _DURATION_HELP)
            return Gap(op, self._as_duration(value))
        if path == ("rate",) and unit is not None:
            if unit != "Hz":
                self._unit_error("rate", value, unit, "a frequency (8 Hz)")
            self._expect("over")
            window = self._duration("'over'")
            if window <= 0:  # no window holds a message: the term could never hold
                raise SelectionError(
                    f"bad condition {self.text!r}: 'over' takes a window longer than 0 (1s)"
                )
            return Rate(op, float(value), window)
        if unit is not None:
            self._unit_error(
                path_text(path),
                value,
                unit,
                "a plain value (units go with gap, rate, age, latency)",
            )
        return Comparison(path, op, value)

    def _function(self) -> Expression:
        _, name, position = self._take()
        if name not in _FUNCTIONS:
            close = difflib.get_close_matches(name, _FUNCTIONS, n=1)
            hint = f" (did you mean {close[0]}?)" if close else ""
            raise SelectionError(
                f"bad condition {self.text!r}: unknown function {name!r} at column "
                f"{position + 1}{hint}; known: {', '.join(_FUNCTIONS)}"
            )
        self._expect("(")
        if name == "latency":
            source = self._topic()
            if self._kind() != "arrow":
                self._fail("expected '->'")
            self.at += 1
            target = self._topic()
            self._expect(",")
            path = self._path()
            self._expect(")")
            op = self._op()
            return Latency(source, target, path, op, self._duration(f"{name}()"))
        if name in ("isnan", "isinf", "unchanged"):
            leaves: Path | None = None
            if self._peek("*"):
                self.at += 1
            else:
                leaves = self._path()
            self._expect(")")
            return Unchanged(leaves) if name == "unchanged" else Check(name, leaves)
        path = self._path()
        self._expect(")")
        op = self._op()
        if name == "age":
            return Age(path, op, self._duration("age()"))
        value, unit = self._value()
        if unit is not None or isinstance(value, str | bool):
            self._unit_error("delta()", value, unit, "a plain number")
        return Delta(path, op, float(value))

    def _topic(self) -> str:
        if self._kind() != "topic":
            self._fail("expected a topic (/imu/data)")
        return self._take()[1]

    def _op(self) -> str:
        if self._kind() != "op":
            self._fail("expected an operator (== != < <= > >=)")
        return self._take()[1]

    def _duration(self, what: str) -> int:
        start = self.at
        value, unit = self._value()
        if unit is None or unit == "Hz":
            self.at = start
            self._fail(f"{what} takes {_DURATION_HELP}")
        return self._as_duration(value)

    def _as_duration(self, value: Value) -> int:
        """ns of a quantity kept as text (``2s``, ``1m30s``)."""
        try:
            return parse_duration(str(value))
        except SelectionError:
            raise SelectionError(
                f"bad condition {self.text!r}: {value!r} is not {_DURATION_HELP}"
            ) from None

    def _unit_error(self, what: str, value: Value, unit: str | None, expected: str) -> NoReturn:
        given = f"{value}{' ' + unit if unit and unit != 'duration' else ''}"
        raise SelectionError(f"bad condition {self.text!r}: {what} takes {expected}, not {given!r}")

    def _path(self) -> Path:
        if self._kind() != "name" or self._peek(*_KEYWORDS):
            self._fail("expected a field path")
        steps: list[Step] = [self._take()[1]]
        while self._peek(".", "["):
            if self._take()[1] == ".":
                if self._kind() != "name":
                    self._fail("expected a field name after '.'")
                steps.append(self._take()[1])
                continue
            steps.append(self._index())
        return tuple(steps)

    def _index(self) -> int:
        if self._peek("*"):
            self.at += 1
            index = ANY
        elif self._peek("]"):
            index = ANY
        elif self.at < len(self.tokens) and re.fullmatch(r"\d+", self.tokens[self.at][1]):
            index = int(self._take()[1])
        else:
            self._fail("expected an index, '*' or ']'")
        self._expect("]")
        return index

    def _value(self) -> tuple[Value, str | None]:
        """A value and its unit (``2s``, ``2 s``, ``8 Hz``; None without one)."""
        if self.at >= len(self.tokens):
            self._fail("expected a value")
        kind, text, _ = self.tokens[self.at]
        if kind == "quantity":
            self.at += 1
            if text.endswith("Hz") and text[:-2].replace(".", "", 1).isdigit():
                return text[:-2], "Hz"
            return text, "duration"
        if kind == "number":
            number = float(text)
            if math.isinf(number):  # as a float column compares it: 1e999, 400 digits
                self._fail("a number within float64 (at most about 1.8e308)")
            self.at += 1
            value: Value = int(text) if re.fullmatch(r"[+-]?\d+", text) else number
            if self._kind() == "name" and self.tokens[self.at][1] in _UNITS:
                unit = self._take()[1]
                return (text, unit) if unit == "Hz" else (text + unit, "duration")
            return value, None
        if kind == "string":
            self.at += 1
            return re.sub(r"\\(.)", r"\1", text[1:-1]), None
        if text in ("true", "false"):
            self.at += 1
            return text == "true", None
        self._fail("expected a value (a number, 'text', true or false)")


def parse_expression(text: str) -> Expression:
    """The tree of ``text``.

    Raises:
        SelectionError: naming the column of the first problem.
    """
    return _Parser(text).parse()
