"""A health contract as written in YAML, checked before any bag is read.

::

    forbidden: [/debug]
    topics:
      /imu/data:
        type: sensor_msgs/msg/Imu
        rate: {min: 90, max: 110, over: 2s}   # Hz, counted over a sliding window
        max_gap: 100ms
        values:
          linear_acceleration.z: {min: 0, max: 20}
        never:                                 # conditions over time that must not hold
          - isnan(*)
          - unchanged(linear_acceleration.z) for 2s
      /gps/fix: {}                             # required, nothing more

A spec that does not parse, a key bagkit does not know or a condition that does not parse is
one :class:`SpecError` naming the line of the spec.
"""

from __future__ import annotations

import difflib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from bagkit.bag import safe_yaml
from bagkit.errors import BagkitError
from bagkit.selection.conditions import Condition, parse_condition
from bagkit.selection.errors import SelectionError
from bagkit.selection.times import parse_duration
from bagkit.selection.topics import absolute_topic_name

_TOP_KEYS = ("forbidden", "topics")
_TOPIC_KEYS = ("type", "rate", "max_gap", "values", "never")
_RATE_KEYS = ("min", "max", "over")
_BOUND_KEYS = ("min", "max")
DEFAULT_WINDOW = "1s"


class SpecError(BagkitError):
    """A contract that cannot be used: one line naming where in the spec."""

    exit_code = 2


@dataclass(frozen=True)
class TopicContract:
    """What one topic must look like: its assertions as conditions that must never hold."""

    topic: str
    type: str | None = None
    never: tuple[tuple[str, Condition], ...] = ()
    """(what is asserted, the condition that breaks it) in the order written."""
    lines: tuple[int, ...] = ()
    """The spec's line of each of ``never`` (0: not known), for errors found on reading a bag."""


@dataclass(frozen=True)
class HealthSpec:
    """A contract: forbidden topics, and required topics with their assertions."""

    topics: tuple[TopicContract, ...] = ()
    forbidden: tuple[str, ...] = ()
    source: str = ""
    lines: dict[str, int] = field(default_factory=dict, compare=False)

    @classmethod
    def load(cls, path: str | Path) -> HealthSpec:
        """Read and check a spec file.

        Raises:
            SpecError: unreadable, not a contract, an unknown key, a bad duration or condition.
        """
        path = Path(path)
        try:
            text = path.read_bytes().decode("utf-8")
        except OSError as exc:
            raise SpecError(f"{path}: {exc.strerror or exc}") from None
        except UnicodeDecodeError as exc:
            raise SpecError(f"{path}: not UTF-8 (byte {exc.start})") from None
        return cls.parse(text, str(path))

    @classmethod
    def parse(cls, text: str, source: str = "health.yaml") -> HealthSpec:
        """A contract from YAML text (``source`` names it in errors)."""
        try:
            data = safe_yaml.load(text)
            lines = _key_lines(text)
        except yaml.YAMLError as exc:
            mark = getattr(exc, "problem_mark", None)
            where = f":{mark.line + 1}" if mark is not None else ""
            raise SpecError(f"{source}{where}: not YAML ({exc})") from None
        return _Reader(source, lines).spec(data or {})

    @classmethod
    def parse_section(cls, text: str, key: str, source: str) -> HealthSpec | None:
        """The contract under ``key`` of a larger YAML document (a golden spec's ``health:``),
        None without one; errors name the document's lines."""
        data = safe_yaml.load(text)
        if not isinstance(data, Mapping) or data.get(key) is None:
            return None
        found = _key_lines(text)
        prefix = f"{key}."
        lines = {k.removeprefix(prefix): v for k, v in found.items() if k.startswith(prefix)}
        lines[""] = found.get(key, 0)  # "the spec must be a mapping" names the section's line
        return _Reader(source, lines).spec(data[key])


class _Reader:
    def __init__(self, source: str, lines: dict[str, int]) -> None:
        self.source = source
        self.lines = lines
        self.written: dict[str, str] = {}
        """Each condition's text -> where in the spec it was written."""

    def fail(self, where: str, message: str) -> SpecError:
        line = self.lines.get(where)
        return SpecError(f"{self.source}{f':{line}' if line else ''}: {message}")

    def keys(self, where: str, value: Any, known: tuple[str, ...]) -> Mapping[str, Any]:
        if not isinstance(value, Mapping):
            raise self.fail(where, f"{where or 'the spec'} must be a mapping")
        for key in value:
            if key not in known:
                close = difflib.get_close_matches(str(key), known, n=1)
                hint = f" (did you mean {close[0]}?)" if close else ""
                path = f"{where}.{key}" if where else str(key)
                raise self.fail(path, f"unknown key {key!r}{hint}; known: {', '.join(known)}")
        return value

    def spec(self, data: Any) -> HealthSpec:
        data = self.keys("", data, _TOP_KEYS)
        forbidden = data.get("forbidden") or []
        if not isinstance(forbidden, list) or not all(isinstance(t, str) for t in forbidden):
            raise self.fail("forbidden", "forbidden must be a list of topics")
        topics = data.get("topics") or {}
        if not isinstance(topics, Mapping):
            raise self.fail("topics", "topics must map each topic to its contract")
        contracts = tuple(self.topic(str(name), body or {}) for name, body in topics.items())
        return HealthSpec(
            contracts,
            tuple(absolute_topic_name(t) for t in forbidden),
            self.source,
            self.lines,
        )

    def topic(self, name: str, body: Any) -> TopicContract:
        where = f"topics.{name}"
        body = self.keys(where, body, _TOPIC_KEYS)
        never: list[tuple[str, Condition]] = []
        rate = body.get("rate")
        if rate is not None:
            rate = self.keys(f"{where}.rate", rate, _RATE_KEYS)
            over = str(rate.get("over", DEFAULT_WINDOW))
            self.duration(f"{where}.rate", over)
            if "min" not in rate and "max" not in rate:  # a contract nothing could break
                raise self.fail(f"{where}.rate", "rate has neither min nor max")
            for key, op in (("min", "<"), ("max", ">")):
                if key in rate:
                    hz = self.number(f"{where}.rate", rate[key])
                    never.append(self.condition(f"{where}.rate", f"rate {op} {hz} Hz over {over}"))
        if "max_gap" in body:
            gap = str(body["max_gap"])
            self.duration(f"{where}.max_gap", gap)
            never.append(self.condition(f"{where}.max_gap", f"gap > {gap}"))
        values = body.get("values") or {}
        if not isinstance(values, Mapping):
            raise self.fail(f"{where}.values", "values must map fields to {min, max}")
        for path, given in values.items():
            bounds = self.keys(f"{where}.values.{path}", given, _BOUND_KEYS)
            found = {
                k: self.number(f"{where}.values.{path}", bounds[k])
                for k in _BOUND_KEYS
                if k in bounds
            }
            if not found:  # a contract nothing could break
                raise self.fail(f"{where}.values.{path}", f"{path}: neither min nor max")
            if len(found) == 2 and found["min"] > found["max"]:  # a contract nothing keeps
                raise self.fail(
                    f"{where}.values.{path}",
                    f"{path}: min {found['min']} is above max {found['max']}",
                )
            parts = []
            if "min" in found:
                parts.append(f"{path} < {found['min']}")
            if "max" in found:
                parts.append(f"{path} > {found['max']}")
            never.append(self.condition(f"{where}.values.{path}", " or ".join(parts)))
        conditions = body.get("never") or []
        if not isinstance(conditions, list):
            raise self.fail(f"{where}.never", "never must be a list of conditions")
        never.extend(
            self.condition(f"{where}.never[{i}]", str(text)) for i, text in enumerate(conditions)
        )
        kind = body.get("type")
        return TopicContract(
            absolute_topic_name(name),
            None if kind is None else str(kind),
            tuple(never),
            tuple(self.lines.get(self.written[text], 0) for text, _ in never),
        )

    def condition(self, where: str, text: str) -> tuple[str, Condition]:
        self.written[text] = where
        try:
            return text, parse_condition(text)
        except SelectionError as exc:
            raise self.fail(where, str(exc)) from None

    def duration(self, where: str, text: str) -> int:
        try:
            return parse_duration(text, where.rsplit(".", 1)[-1])
        except SelectionError as exc:
            raise self.fail(where, str(exc)) from None

    def number(self, where: str, value: Any) -> float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise self.fail(where, f"{value!r} is not a number")
        return value


def _key_lines(text: str) -> dict[str, int]:
    """The line (1-based) of each key and list item of the document, by dotted path
    (``topics./imu.rate``, ``topics./imu.never[0]``)."""
    found: dict[str, int] = {}

    def walk(node: yaml.Node, prefix: str) -> None:
        if isinstance(node, yaml.MappingNode):
            for key, value in node.value:
                path = f"{prefix}.{key.value}" if prefix else str(key.value)
                found[path] = key.start_mark.line + 1
                walk(value, path)
        elif isinstance(node, yaml.SequenceNode):  # a list's items: ``topics./imu.never[1]``
            for index, item in enumerate(node.value):
                found[f"{prefix}[{index}]"] = item.start_mark.line + 1
                walk(item, f"{prefix}[{index}]")

    root = yaml.compose(text, Loader=yaml.CSafeLoader)
    if root is not None:
        walk(root, "")
    return found
