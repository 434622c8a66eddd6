"""The condition language's syntax: tokens, the tree of a condition, and its parser.

Grammar (docs/cli.md)::

    condition  := or
    or         := and ("or" and)*
    and        := not ("and" not)*
    not        := "not" not | "(" or ")" | comparison
    comparison := path OP value           OP: == != < <= > >=
    path       := NAME ("." NAME | "[" INDEX "]" | "[*]" | "[]")*
    value      := number | 'text' | "text" | true | false

Recursive descent, bounded in length and depth; an error names the column of the first
problem. Names start with a letter: ``_private`` attributes cannot be named, so a condition
can only read a message's fields. Evaluation is :mod:`bagkit.selection.conditions`.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass
from typing import NoReturn

from bagkit.selection.errors import SelectionError

ANY = -1
"""A path step meaning "any element" (``[*]``, ``[]``)."""

MAX_LENGTH = 4096
MAX_DEPTH = 64

_TOKEN = re.compile(
    r"""\s*(?:
      (?P<number>[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?(?![\w.]))
    | (?P<string>'(?:[^'\\]|\\.)*'|"(?:[^"\\]|\\.)*")
    | (?P<op>==|!=|<=|>=|<|>)
    | (?P<punct>[().\[\]*])
    | (?P<name>[A-Za-z][A-Za-z0-9_]*)
    )""",
    re.VERBOSE,
)
_KEYWORDS = {"and", "or", "not", "true", "false"}

Step = str | int
Value = float | int | str | bool


@dataclass(frozen=True, slots=True)
class Comparison:
    """``path OP value``."""

    path: tuple[Step, ...]
    op: str
    value: Value

    @property
    def text(self) -> str:
        """The path as written in the leaf-path language (``status[*].level``)."""
        out = ""
        for step in self.path:
            if isinstance(step, str):
                out += f".{step}" if out else step
            else:
                out += "[*]" if step == ANY else f"[{step}]"
        return out


@dataclass(frozen=True, slots=True)
class Node:
    """``and``/``or`` of its items, or ``not`` of its one item."""

    kind: str
    items: tuple[Node | Comparison, ...]


Expression = Node | Comparison


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
            self._fail("expected 'and', 'or' or the end")
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

    def _take(self) -> tuple[str, str, int]:
        token = self.tokens[self.at]
        self.at += 1
        return token

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
                if not self._peek(")"):
                    self._fail("expected ')'")
                self.at += 1
                return inner
            return self._comparison()
        finally:
            self.depth -= 1

    def _comparison(self) -> Comparison:
        path = self._path()
        if self.at >= len(self.tokens) or self.tokens[self.at][0] != "op":
            self._fail("expected an operator (== != < <= > >=)")
        op = self._take()[1]
        return Comparison(path, op, self._value())

    def _path(self) -> tuple[Step, ...]:
        if (
            self.at >= len(self.tokens)
            or self.tokens[self.at][0] != "name"
            or self._peek(*_KEYWORDS)
        ):
            self._fail("expected a field path")
        steps: list[Step] = [self._take()[1]]
        while self._peek(".", "["):
            if self._take()[1] == ".":
                if self.at >= len(self.tokens) or self.tokens[self.at][0] != "name":
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
        if not self._peek("]"):
            self._fail("expected ']'")
        self.at += 1
        return index

    def _value(self) -> Value:
        if self.at >= len(self.tokens):
            self._fail("expected a value")
        kind, text, _ = self.tokens[self.at]
        if kind == "number":
            self.at += 1
            number = float(text)
            return int(text) if re.fullmatch(r"[+-]?\d+", text) else number
        if kind == "string":
            self.at += 1
            return re.sub(r"\\(.)", r"\1", text[1:-1])
        if text in ("true", "false"):
            self.at += 1
            return text == "true"
        self._fail("expected a value (a number, 'text', true or false)")


def parse_expression(text: str) -> Expression:
    """The tree of ``text``.

    Raises:
        SelectionError: naming the column of the first problem.
    """
    return _Parser(text).parse()
