"""Field conditions: ``status[*].level >= 2 and not hardware_id == 'imu'``, parsed, never eval'd.

The language (grammar, parser) is :mod:`bagkit.selection.condition_syntax`. ``[*]`` (or
``[]``) is any element: the comparison holds when it holds for one of them. A condition is
evaluated on a decoded message (:meth:`Condition.matches`) or, for fixed-layout topics, on
whole numpy columns at once (:meth:`Condition.mask`). Names starting with ``_`` are not fields
and are refused, so a condition can only read a message's fields. A condition with terms over
time (``gap``, ``rate``, ``delta`` ...: :attr:`Condition.temporal`) is evaluated over a
topic's stream (:mod:`bagkit.selection.temporal`, :mod:`bagkit.selection.streaming`).
"""

from __future__ import annotations

import math
import operator
import re
from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from bagkit.selection.condition_syntax import parse_expression
from bagkit.selection.condition_terms import (
    ANY,
    Age,
    Check,
    Comparison,
    Delta,
    Expression,
    Latency,
    Node,
    Path,
    Step,
    Unchanged,
    is_stateless,
    path_text,
    walk,
)
from bagkit.selection.errors import SelectionError, UnknownFieldError
from bagkit.selection.fields import unknown_field_message
from bagkit.selection.topics import absolute_topic_name

if TYPE_CHECKING:
    import numpy as np
    import numpy.typing as npt

_OPERATORS: dict[str, Callable[[Any, Any], Any]] = {
    "==": operator.eq,
    "!=": operator.ne,
    "<=": operator.le,
    ">=": operator.ge,
    "<": operator.lt,
    ">": operator.gt,
}
_TEMPORAL_HELP = (
    "terms over time (gap, rate, unchanged, delta, age, latency, for) are for "
    "find --when, filter --around and --where, echo --where and record --trigger"
)


class Condition:
    """A parsed condition (:mod:`~bagkit.selection.condition_syntax` has the grammar)."""

    def __init__(self, text: str, tree: Expression | None = None) -> None:
        self.text = text
        self.tree: Expression = parse_expression(text) if tree is None else tree

    def __repr__(self) -> str:
        return f"Condition({self.text!r})"

    @property
    def temporal(self) -> bool:
        """Whether a term needs more than one message (``gap``, ``delta``, ``for`` ...)."""
        return not is_stateless(self.tree)

    def require_per_message(self) -> None:
        """Raise SelectionError (naming the ``where`` option) if the condition is temporal:
        a ``where`` that checks one message at a time was given it."""
        if self.temporal:
            raise SelectionError(
                f"{self.text!r} checks each message alone: {_TEMPORAL_HELP}", "where"
            )

    def comparisons(self) -> list[Comparison | Check]:
        """Every comparison (and isnan/isinf), in the order written."""
        return [node for node in walk(self.tree) if isinstance(node, Comparison | Check)]

    def paths(self) -> list[Path | None]:
        """Every path a term over time reads (None: every numeric leaf), in the order written."""
        found: list[Path | None] = []
        for node in walk(self.tree):
            if isinstance(node, Delta | Age | Latency | Unchanged):
                found.append(node.path)
        return found

    def check_fields(
        self, topic: str, leaf_paths: Sequence[str], text_paths: Collection[str] | None = None
    ) -> None:
        """Raise UnknownFieldError when a path names no field of the topic's leaf paths.

        ``leaf_paths`` are :mod:`bagkit.selection.fields` paths (``a.b``, ``c[0]``, ``d[].e``).
        With ``text_paths`` (those of ``leaf_paths`` holding strings), a comparison of text
        with a number is a SelectionError before any message is read.
        """
        for node in walk(self.tree):
            if isinstance(node, Comparison):
                matched = self._fields(topic, node.path, leaf_paths, subtree=False)
            elif isinstance(node, Delta | Age | Latency | Check | Unchanged):
                if node.path is not None:
                    self._fields(topic, node.path, leaf_paths, subtree=True)
                continue
            else:
                continue
            if text_paths is None:
                continue
            text_field = all(path in text_paths for path in matched)
            if text_field != isinstance(node.value, str):
                raise SelectionError(
                    f"{node.text} {node.op} {node.value!r}: cannot compare "
                    f"{'str' if text_field else 'a number'} with "
                    f"{type(node.value).__name__} ({topic})"
                )

    @staticmethod
    def _fields(topic: str, path: Path, leaf_paths: Sequence[str], *, subtree: bool) -> list[str]:
        pattern = _leaf_pattern(path, subtree=subtree)
        matched = [leaf for leaf in leaf_paths if pattern.fullmatch(leaf)]
        if not matched:
            raise UnknownFieldError(unknown_field_message(topic, [path_text(path)], leaf_paths))
        return matched

    def matches(self, message: Any, octets: Collection[Comparison | Check] = ()) -> bool:
        """Whether a decoded message (fields as attributes) satisfies the condition.

        ``octets``: comparisons reading ``byte``/``char`` fields, which a decoder may give as
        signed; they compare as the octet (0-255) ROS 2 defines.

        Raises:
            SelectionError: a path names no field of the message, or a value cannot be compared.
        """
        return _evaluate(self.tree, message, octets)

    def reads(self, leaf_paths: Sequence[str]) -> dict[Comparison | Check, list[str]]:
        """The leaf paths each comparison reads (``status[*].level``: ``status[].level``)."""
        return {node: leaves_read(node, leaf_paths) for node in self.comparisons()}

    def bulk_columns(self, leaf_paths: Sequence[str]) -> dict[Comparison | Check, list[str]] | None:
        """The numpy columns each comparison reads, or None when one needs a sequence."""
        columns = self.reads(leaf_paths)
        for names in columns.values():
            if not names or any("[]" in name for name in names):
                return None
        return columns

    def mask(
        self,
        columns: Mapping[str, npt.NDArray[Any]],
        reads: Mapping[Comparison | Check, list[str]],
    ) -> npt.NDArray[np.bool_]:
        """Which rows of ``columns`` (leaf path -> array) satisfy it; ``reads`` from
        :meth:`bulk_columns`.

        Raises:
            SelectionError: a value cannot be compared with its column.
        """
        return _mask(self.tree, columns, reads)


def parse_condition(text: str) -> Condition:
    """Parse ``text``. Raises SelectionError naming the position of the first problem."""
    return Condition(text)


@dataclass(frozen=True, slots=True)
class TopicCondition:
    """``TOPIC: CONDITION`` (``--around``, ``--when``): a condition on one topic's messages."""

    topic: str
    condition: Condition

    @property
    def text(self) -> str:
        """As written, normalized: ``/alerts: status[*].level >= 2``."""
        return f"{self.topic}: {self.condition.text}"


def parse_topic_condition(text: str) -> TopicCondition:
    """Parse ``'TOPIC: CONDITION'`` (topic names hold no colon: the first one separates).

    Raises:
        SelectionError: no colon, no topic or a topic with blanks, or a condition that does
            not parse (its position counted in the condition).
    """
    topic, colon, rest = text.partition(":")
    name = topic.strip()
    if not colon or not name or any(c.isspace() for c in name):
        raise SelectionError(f"{text!r}: expected 'TOPIC: CONDITION' (e.g. '/alerts: level >= 2')")
    try:
        condition = parse_condition(rest.strip())
    except SelectionError as exc:
        raise SelectionError(f"{text!r}: {exc}") from None
    return TopicCondition(absolute_topic_name(name), condition)


def topic_of(text: str) -> TopicCondition | None:
    """``text`` as a topic and its condition when it names a topic (``'TOPIC: CONDITION'``),
    None when it is a condition alone (``--where`` takes either).

    A condition holds a colon only inside a quoted text, after a blank or a quote: what comes
    before the first colon is then no topic name.

    Raises:
        SelectionError: a topic and a condition that does not parse.
    """
    name, colon, _ = text.partition(":")
    if not colon or not name.strip() or any(c.isspace() or c in "'\"" for c in name.strip()):
        return None
    return parse_topic_condition(text)


def leaves_read(node: Comparison | Check, leaf_paths: Sequence[str]) -> list[str]:
    """The leaf paths a comparison reads; isnan/isinf read every leaf below their path (or
    every leaf with ``*``)."""
    if node.path is None:
        return list(leaf_paths)
    pattern = _leaf_pattern(node.path, subtree=isinstance(node, Check))
    return [p for p in leaf_paths if pattern.fullmatch(p)]


def subtree_leaves(path: Path | None, leaf_paths: Sequence[str]) -> list[str]:
    """The leaf paths at or below ``path`` (every one when None)."""
    if path is None:
        return list(leaf_paths)
    pattern = _leaf_pattern(path, subtree=True)
    return [p for p in leaf_paths if pattern.fullmatch(p)]


def _leaf_pattern(path: tuple[Step, ...], *, subtree: bool = False) -> re.Pattern[str]:
    """The leaf paths a condition path reads: ``a[*].b`` reads ``a[].b`` or ``a[0].b`` ...;
    with ``subtree`` also every leaf below it (``header.stamp``: ``header.stamp.sec`` ...)."""
    out = ""
    for step in path:
        if isinstance(step, str):
            out += ("\\." if out else "") + re.escape(step)
        elif step == ANY:
            out += r"\[\d*\]"
        else:
            out += rf"(?:\[{step}\]|\[\])"
    return re.compile(out + r"(?:[.\[].*)?" if subtree else out)


def _evaluate(node: Expression, message: Any, octets: Collection[Comparison | Check]) -> bool:
    if isinstance(node, Check):
        found = message if node.path is None else _values(message, node.path)
        test = math.isnan if node.kind == "isnan" else math.isinf
        return any(test(number) for number in _floats(found))
    if isinstance(node, Comparison):
        values = _values(message, node)
        if node in octets:
            values = [v & 0xFF if isinstance(v, int) else v for v in values]
        return any(_compare(value, node) for value in values)
    assert isinstance(node, Node)  # a temporal condition is refused before (require_per_message)
    if node.kind == "not":
        return not _evaluate(node.items[0], message, octets)
    results = (_evaluate(item, message, octets) for item in node.items)
    return any(results) if node.kind == "or" else all(results)


def message_numbers(message: Any, path: Path | None) -> list[float]:
    """Every number at or below ``path`` of a decoded message (all when None), in field order."""
    found = [message] if path is None else _values(message, path)
    return [x for value in found for x in _numbers(value)]


def _numbers(value: Any) -> list[float]:
    if isinstance(value, bool | int | float):
        return [float(value)]
    if isinstance(value, str | bytes):
        return []
    names = _field_names(value)
    if names:
        return [x for name in names for x in _numbers(getattr(value, name))]
    if hasattr(value, "dtype"):
        return [float(x) for x in value.ravel()] if value.dtype.kind in "biuf" else []
    if isinstance(value, list | tuple):
        return [x for item in value for x in _numbers(item)]
    return []


def _floats(value: Any) -> list[float]:
    """Every float in a decoded value (messages, arrays, sequences)."""
    if isinstance(value, float):
        return [value]
    if isinstance(value, str | bytes | int):
        return []
    names = _field_names(value)
    if names:
        return [x for name in names for x in _floats(getattr(value, name))]
    if hasattr(value, "dtype"):  # numpy arrays of the decoders
        return [float(x) for x in value.ravel()] if value.dtype.kind == "f" else []
    if isinstance(value, list | tuple):
        return [x for item in value for x in _floats(item)]
    return []


def message_values(message: Any, path: Path) -> list[Any]:
    """The values ``path`` reaches in a decoded message (several through ``[*]``).

    Raises:
        UnknownFieldError: the message has no such field. SelectionError: an index into
            what is not an array.
    """
    return _values(message, path)


def _values(message: Any, comparison: Comparison | Path) -> list[Any]:
    """The values a path reaches in ``message`` (several through ``[*]``)."""
    path = comparison.path if isinstance(comparison, Comparison) else comparison
    text = path_text(path)
    current = [message]
    for step in path:
        reached = []
        for value in current:
            if isinstance(step, str):
                if step not in _field_names(value):
                    raise UnknownFieldError(f"no field {text!r} in the message")
                reached.append(getattr(value, step))
            elif not hasattr(value, "__len__") or isinstance(value, str | bytes):
                raise SelectionError(f"{text}: not an array")
            elif step == ANY:
                reached.extend(value)
            elif step < len(value):
                reached.append(value[step])
        current = reached
    return current


def _field_names(message: Any) -> Collection[str]:
    """The fields of a decoded message (a dataclass) or of an rclpy message object."""
    fields = getattr(message, "__dataclass_fields__", None)
    if fields is not None:
        return fields
    rclpy_fields = getattr(type(message), "get_fields_and_field_types", None)
    return rclpy_fields() if rclpy_fields is not None else ()


def _compare(value: Any, comparison: Comparison) -> bool:
    expected = comparison.value
    if isinstance(value, bytes) and len(value) == 1:  # rclpy's byte fields
        value = value[0]
    if isinstance(expected, str) != isinstance(value, str):
        raise SelectionError(
            f"{comparison.text} {comparison.op} {expected!r}: cannot compare "
            f"{type(value).__name__} with {type(expected).__name__}"
        )
    return bool(_OPERATORS[comparison.op](value, expected))


def _mask(
    node: Expression,
    columns: Mapping[str, npt.NDArray[Any]],
    reads: Mapping[Comparison | Check, list[str]],
) -> npt.NDArray[np.bool_]:
    import numpy as np

    if isinstance(node, Check):
        test = np.isnan if node.kind == "isnan" else np.isinf
        some = next(iter(columns.values()))
        hits = [test(columns[n]) for n in reads[node] if columns[n].dtype.kind == "f"]
        return np.logical_or.reduce(hits) if hits else np.zeros(len(some), dtype=bool)
    if isinstance(node, Comparison):
        hits = [_column_compare(columns[name], node) for name in reads[node]]
        return np.logical_or.reduce(hits) if len(hits) > 1 else hits[0]
    assert isinstance(node, Node)
    masks = [_mask(item, columns, reads) for item in node.items]
    if node.kind == "not":
        return ~masks[0]
    return (np.logical_or if node.kind == "or" else np.logical_and).reduce(masks)


def _column_compare(column: npt.NDArray[Any], comparison: Comparison) -> npt.NDArray[np.bool_]:
    import numpy as np

    text_column = column.dtype.kind in "OUS"
    if isinstance(comparison.value, str) != text_column:
        raise SelectionError(
            f"{comparison.text} {comparison.op} {comparison.value!r}: cannot compare "
            f"{'text' if text_column else 'a number'} with {type(comparison.value).__name__}"
        )
    if column.dtype.kind == "f" and column.dtype.itemsize < 8:
        # Each float32 as its exact float64, as decoded messages hold it (the match message by
        # message, rosbags, rclpy): numpy would round the value written to float32 instead,
        # and 'range <= 1.6' would hold for the float32 just above 1.6.
        column = column.astype(np.float64)
    return np.asarray(_OPERATORS[comparison.op](column, comparison.value), dtype=bool)
