"""What the streaming evaluator reads of each message, and its per-message tests.

:class:`Message` is one message as :mod:`~bagkit.selection.streaming` reads it (a decoded
message: :class:`DecodedMessage`); :class:`MessageTest` decides a per-message condition on
it, keeping what ``delta`` (the previous values) and ``latency`` (its source's stamps) need.
"""

from __future__ import annotations

import collections
import math
from typing import Any, Protocol

import numpy as np

from bagkit.selection.condition_terms import (
    Age,
    Delta,
    Expression,
    Latency,
    Node,
    Path,
    is_stateless,
)
from bagkit.selection.conditions import Condition, message_numbers
from bagkit.selection.temporal import OPERATORS

LATENCY_STAMPS = 100_000
"""Stamps of a latency's source topic kept to find the input of each output message."""

NO_STAMP = -(2**62)


class Message(Protocol):
    """One message as the streaming evaluator reads it."""

    def holds(self, node: Expression) -> bool:
        """Whether it satisfies a stateless condition."""

    def values(self, path: Path | None) -> np.ndarray:
        """Its numeric leaves at or below ``path`` (float64; None: all)."""


class DecodedMessage:
    """A decoded message (rosbags' or rclpy's) as :class:`Message`."""

    def __init__(self, condition: Condition, message: Any) -> None:
        self.condition = condition
        self.message = message

    def holds(self, node: Expression) -> bool:
        return Condition(self.condition.text, node).matches(self.message)

    def values(self, path: Path | None) -> np.ndarray:
        return np.array(message_numbers(self.message, path), dtype=np.float64)


class MessageTest:
    """Whether each message satisfies a per-message condition (``delta`` keeps the previous
    value, ``latency`` the source's stamps)."""

    def __init__(self, node: Expression) -> None:
        self.node = node
        self.previous: dict[int, np.ndarray] = {}
        self.stamps: dict[str, collections.OrderedDict[int, int]] = {}

    def source(self, topic: str, time: int, stamp: int) -> None:
        stamps = self.stamps.setdefault(topic, collections.OrderedDict())
        stamps.setdefault(stamp, time)  # the first message with a stamp is the input
        if len(stamps) > LATENCY_STAMPS:
            stamps.popitem(last=False)

    def __call__(self, time: int, message: Message) -> bool:
        return self._test(self.node, time, message)

    def _test(self, node: Expression, time: int, message: Message) -> bool:
        if is_stateless(node):
            return message.holds(node)
        if isinstance(node, Node):
            results = [self._test(item, time, message) for item in node.items]
            if node.kind == "not":
                return not results[0]
            return any(results) if node.kind == "or" else all(results)
        if isinstance(node, Delta):
            values = message.values(node.path)
            previous = self.previous.get(id(node))
            self.previous[id(node)] = values
            if previous is None or previous.shape != values.shape:
                return False
            with np.errstate(invalid="ignore"):
                return bool(OPERATORS[node.op](np.abs(values - previous), node.value).any())
        assert isinstance(node, Age | Latency)
        stamp = _stamp(message.values(node.path))
        if isinstance(node, Age):
            return bool(OPERATORS[node.op](time - stamp, node.ns))
        stamps = self.stamps.get(node.source)
        source = None if stamps is None else stamps.get(stamp)
        return source is not None and time >= source and OPERATORS[node.op](time - source, node.ns)


def _stamp(values: np.ndarray) -> int:
    sec, nanosec = values
    return int(sec) * 1_000_000_000 + int(nanosec) if math.isfinite(sec) else NO_STAMP
