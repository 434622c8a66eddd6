"""The tree of a condition: comparisons, ``and``/``or``/``not``, and the terms over time.

A *per-message* term (a comparison, ``delta``, ``isnan``/``isinf``, ``age``, ``latency``) says
something about each message of the topic. A *stream* term (``gap``, ``rate``, ``unchanged``,
``for``) says something about the topic's stream over time. Both mean a set of intervals of
log time (:mod:`bagkit.selection.temporal`); the parser is :mod:`~.condition_syntax`.
"""

from __future__ import annotations

from typing import NamedTuple

ANY = -1
"""A path step meaning "any element" (``[*]``, ``[]``)."""

Step = str | int
Value = float | int | str | bool
Path = tuple[Step, ...]


# The terms are NamedTuples, not frozen dataclasses: `find`, `check` and every `--where` import
# this module at start, where a dataclass costs far more to create than a NamedTuple. Being
# tuples, two terms of different kinds with equal fields compare equal; no code mixes kinds in
# one set or dict (the columns a term reads are keyed by comparisons and checks only, tuples of
# different lengths).


def path_text(path: Path | None) -> str:
    """A path as written in the leaf-path language (``status[*].level``); None is ``*``."""
    if path is None:
        return "*"
    out = ""
    for step in path:
        if isinstance(step, str):
            out += f".{step}" if out else step
        else:
            out += "[*]" if step == ANY else f"[{step}]"
    return out


class Comparison(NamedTuple):
    """``path OP value``."""

    path: Path
    op: str
    value: Value

    @property
    def text(self) -> str:
        """The path as written (``status[*].level``)."""
        return path_text(self.path)


class Delta(NamedTuple):
    """``delta(path) OP value``: the size of the change since the topic's previous message."""

    path: Path
    op: str
    value: float


class Check(NamedTuple):
    """``isnan(path)``/``isinf(path)`` (``kind``); path None (``*``): any numeric leaf."""

    kind: str
    path: Path | None


class Age(NamedTuple):
    """``age(path) OP duration``: log time minus the stamp at ``path`` (a Time message)."""

    path: Path
    op: str
    ns: int


class Latency(NamedTuple):
    """``latency(SOURCE -> TARGET, path) OP duration``: a TARGET message's log time minus
    that of the SOURCE message with the same value at ``path`` (a stamp carried through)."""

    source: str
    target: str
    path: Path
    op: str
    ns: int


class Gap(NamedTuple):
    """``gap OP duration``: a silence between consecutive messages (and after the last)."""

    op: str
    ns: int


class Rate(NamedTuple):
    """``rate OP HZ Hz over duration``: messages in a sliding window of ``window_ns``."""

    op: str
    hz: float
    window_ns: int


class Unchanged(NamedTuple):
    """``unchanged(path)``: runs of two or more consecutive messages with equal values (path
    None: every numeric leaf)."""

    path: Path | None


class For(NamedTuple):
    """``CONDITION for duration``: its intervals lasting at least ``ns``."""

    item: Expression
    ns: int


class Node(NamedTuple):
    """``and``/``or`` of its items, or ``not`` of its one item."""

    kind: str
    items: tuple[Expression, ...]


PerMessage = Comparison | Delta | Check | Age | Latency
Stream = Gap | Rate | Unchanged | For
Expression = Node | PerMessage | Stream

PER_MESSAGE = (Comparison, Delta, Check, Age, Latency)


def is_per_message(node: Expression) -> bool:
    """Whether ``node`` holds only per-message terms (evaluated message by message)."""
    if isinstance(node, Node):
        return all(is_per_message(item) for item in node.items)
    return isinstance(node, PER_MESSAGE)


def is_stateless(node: Expression) -> bool:
    """Whether ``node`` is decided by each message alone (comparisons and isnan/isinf)."""
    if isinstance(node, Node):
        return all(is_stateless(item) for item in node.items)
    return isinstance(node, Comparison | Check)


def walk(node: Expression) -> list[Expression]:
    """``node`` and every node under it, depth first, in the order written."""
    found: list[Expression] = []
    stack: list[Expression] = [node]
    while stack:
        current = stack.pop()
        found.append(current)
        if isinstance(current, Node):
            stack.extend(reversed(current.items))
        elif isinstance(current, For):
            stack.append(current.item)
    return found
