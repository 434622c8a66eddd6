"""Field conditions: ``status[*].level >= 2 and not hardware_id == 'imu'``, parsed, never eval'd.

The language (grammar, parser) is :mod:`bagkit.selection.condition_syntax`. ``[*]`` (or
``[]``) is any element: the comparison holds when it holds for one of them. A condition is
evaluated on a decoded message (:meth:`Condition.matches`) or, for fixed-layout topics, on
whole numpy columns at once (:meth:`Condition.mask`). Names starting with ``_`` are not fields
and are refused, so a condition can only read a message's fields.
"""

from __future__ import annotations

import operator
import re
from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from bagkit.selection.condition_syntax import ANY, Comparison, Expression, Step, parse_expression
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


class Condition:
    """A parsed condition (:mod:`~bagkit.selection.condition_syntax` has the grammar)."""

    def __init__(self, text: str) -> None:
        self.text = text
        self.tree: Expression = parse_expression(text)

    def __repr__(self) -> str:
        return f"Condition({self.text!r})"

    def comparisons(self) -> list[Comparison]:
        """Every comparison, in the order written."""
        found: list[Comparison] = []
        stack: list[Expression] = [self.tree]
        while stack:
            node = stack.pop()
            if isinstance(node, Comparison):
                found.append(node)
            else:
                stack.extend(reversed(node.items))
        return found

    def check_fields(
        self, topic: str, leaf_paths: Sequence[str], text_paths: Collection[str] | None = None
    ) -> None:
        """Raise UnknownFieldError when a path names no field of the topic's leaf paths.

        ``leaf_paths`` are :mod:`bagkit.selection.fields` paths (``a.b``, ``c[0]``, ``d[].e``).
        With ``text_paths`` (those of ``leaf_paths`` holding strings), a comparison of text
        with a number is a SelectionError before any message is read.
        """
        for comparison in self.comparisons():
            pattern = _leaf_pattern(comparison.path)
            matched = [path for path in leaf_paths if pattern.fullmatch(path)]
            if not matched:
                raise UnknownFieldError(unknown_field_message(topic, [comparison.text], leaf_paths))
            if text_paths is None:
                continue
            text_field = all(path in text_paths for path in matched)
            if text_field != isinstance(comparison.value, str):
                raise SelectionError(
                    f"{comparison.text} {comparison.op} {comparison.value!r}: cannot compare "
                    f"{'str' if text_field else 'a number'} with "
                    f"{type(comparison.value).__name__} ({topic})"
                )

    def matches(self, message: Any, octets: Collection[Comparison] = ()) -> bool:
        """Whether a decoded message (fields as attributes) satisfies the condition.

        ``octets``: comparisons reading ``byte``/``char`` fields, which a decoder may give as
        signed; they compare as the octet (0-255) ROS 2 defines.

        Raises:
            SelectionError: a path names no field of the message, or a value cannot be compared.
        """
        return _evaluate(self.tree, message, octets)

    def reads(self, leaf_paths: Sequence[str]) -> dict[Comparison, list[str]]:
        """The leaf paths each comparison reads (``status[*].level``: ``status[].level``)."""
        return {
            comparison: [p for p in leaf_paths if _leaf_pattern(comparison.path).fullmatch(p)]
            for comparison in self.comparisons()
        }

    def bulk_columns(self, leaf_paths: Sequence[str]) -> dict[Comparison, list[str]] | None:
        """The numpy columns each comparison reads, or None when one needs a sequence."""
        columns = self.reads(leaf_paths)
        for names in columns.values():
            if not names or any("[]" in name for name in names):
                return None
        return columns

    def mask(
        self, columns: Mapping[str, npt.NDArray[Any]], reads: Mapping[Comparison, list[str]]
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


def _leaf_pattern(path: tuple[Step, ...]) -> re.Pattern[str]:
    """The leaf paths a condition path reads: ``a[*].b`` reads ``a[].b`` or ``a[0].b`` ..."""
    out = ""
    for step in path:
        if isinstance(step, str):
            out += ("\\." if out else "") + re.escape(step)
        elif step == ANY:
            out += r"\[\d*\]"
        else:
            out += rf"(?:\[{step}\]|\[\])"
    return re.compile(out)


def _evaluate(node: Expression, message: Any, octets: Collection[Comparison]) -> bool:
    if isinstance(node, Comparison):
        values = _values(message, node)
        if node in octets:
            values = [v & 0xFF if isinstance(v, int) else v for v in values]
        return any(_compare(value, node) for value in values)
    if node.kind == "not":
        return not _evaluate(node.items[0], message, octets)
    results = (_evaluate(item, message, octets) for item in node.items)
    return any(results) if node.kind == "or" else all(results)


def _values(message: Any, comparison: Comparison) -> list[Any]:
    """The values ``comparison.path`` reaches in ``message`` (several through ``[*]``)."""
    current = [message]
    for step in comparison.path:
        reached = []
        for value in current:
            if isinstance(step, str):
                if step not in _field_names(value):
                    raise UnknownFieldError(f"no field {comparison.text!r} in the message")
                reached.append(getattr(value, step))
            elif not hasattr(value, "__len__") or isinstance(value, str | bytes):
                raise SelectionError(f"{comparison.text}: not an array")
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
    reads: Mapping[Comparison, list[str]],
) -> npt.NDArray[np.bool_]:
    import numpy as np

    if isinstance(node, Comparison):
        hits = [_column_compare(columns[name], node) for name in reads[node]]
        return np.logical_or.reduce(hits) if len(hits) > 1 else hits[0]
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
    return np.asarray(_OPERATORS[comparison.op](column, comparison.value), dtype=bool)
