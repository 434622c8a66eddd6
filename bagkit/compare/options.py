"""What a comparison accepts: tolerances per topic and field, ignored fields, matching windows."""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from bagkit.compare.errors import CompareError
from bagkit.selection.fields import FieldSelection, name_matches, path_matches
from bagkit.selection.times import seconds_to_ns

DEFAULT_EVENT_TOPICS = ("/alerts",)
DEFAULT_EVENT_WINDOW_NS = 500_000_000


@dataclass(frozen=True, slots=True)
class Tolerance:
    """A numeric value passes when ``|a - b| <= max(atol, rtol * max(|a|, |b|))``."""

    atol: float = 0.0
    rtol: float = 0.0

    def __post_init__(self) -> None:
        if not (self.atol >= 0 and self.rtol >= 0):
            raise CompareError(f"tolerances must be >= 0, got atol={self.atol} rtol={self.rtol}")

    def accepts(self, golden: float, candidate: float) -> bool:
        """Whether ``candidate`` is within tolerance of ``golden`` (NaN only equals NaN)."""
        if math.isnan(golden) or math.isnan(candidate):
            return math.isnan(golden) and math.isnan(candidate)
        if golden == candidate:  # also equal infinities, whose difference is NaN
            return True
        bound = max(self.atol, self.rtol * max(abs(golden), abs(candidate)))
        return abs(golden - candidate) <= bound


@dataclass(frozen=True, slots=True)
class ToleranceRule:
    """A tolerance for the fields ``field`` selects on topics matching ``topic`` (globs of
    :mod:`bagkit.selection.fields`)."""

    topic: str
    field: str
    tolerance: Tolerance

    def matches(self, topic: str, path: str) -> bool:
        """Whether this rule applies to ``path`` on ``topic``."""
        return name_matches(topic, self.topic) and path_matches(path, self.field)


@dataclass(frozen=True, slots=True)
class CompareOptions:
    """Everything that decides whether two bags are "the same".

    Attributes:
        topics: topics to compare; None compares the topics both bags have.
        tolerance: the default numeric tolerance.
        rules: per topic/field tolerances; the last matching rule wins.
        ignore_fields: globs on the dotted field path, or ``TOPIC_GLOB:FIELD_GLOB``.
        event_topics: DiagnosticArray topics whose statuses are compared as events, matched
            by (name, level) within ``event_window_ns`` of each other.
        match_window_ns: stamped messages match when their header stamps differ by at most
            this much (0: exactly); ``match_windows`` overrides it per topic.
        include_times: also compare receive and publish times (seconds, as ``~log_time`` and
            ``~publish_time`` fields); ignored by default.
        pass_rate: the fraction of a topic's golden messages (or events) that must be
            matched with every value within tolerance (1: all of them); ``pass_rates``
            overrides it per topic. Messages of another shape (fields, lengths) fail a topic
            whatever the rate.
        skip_ns: compare only messages stamped at least this long after the golden's first
            message (a warm-up whose state the bags do not hold).
        max_divergences: how many divergences each topic keeps for the report.
    """

    topics: tuple[str, ...] | None = None
    tolerance: Tolerance = field(default_factory=Tolerance)
    rules: tuple[ToleranceRule, ...] = ()
    ignore_fields: tuple[str, ...] = ()
    event_topics: tuple[str, ...] = DEFAULT_EVENT_TOPICS
    event_window_ns: int = DEFAULT_EVENT_WINDOW_NS
    match_window_ns: int = 0
    match_windows: Mapping[str, int] = field(default_factory=dict)
    include_times: bool = False
    pass_rate: float = 1.0
    pass_rates: Mapping[str, float] = field(default_factory=dict)
    skip_ns: int = 0
    max_divergences: int = 10

    def __post_init__(self) -> None:
        for rate in (self.pass_rate, *self.pass_rates.values()):
            if not 0.0 <= rate <= 1.0:
                raise CompareError(f"a pass rate is a fraction in [0, 1], got {rate}")

    def tolerance_for(self, topic: str, path: str) -> Tolerance:
        """The tolerance that applies to ``path`` on ``topic``."""
        chosen = self.tolerance
        for rule in self.rules:
            if rule.matches(topic, path):
                chosen = rule.tolerance
        return chosen

    def is_ignored(self, topic: str, path: str) -> bool:
        """Whether ``path`` on ``topic`` is excluded from the comparison."""
        return _selection(self.ignore_fields).selects(topic, path)

    def pass_rate_for(self, topic: str) -> float:
        """The fraction of ``topic``'s golden messages that must be matched within tolerance."""
        return self.pass_rates.get(topic, self.pass_rate)

    def window_for(self, topic: str) -> int:
        """The stamp matching window of ``topic`` in ns."""
        return self.match_windows.get(topic, self.match_window_ns)


@functools.lru_cache(maxsize=64)
def _selection(patterns: tuple[str, ...]) -> FieldSelection:
    return FieldSelection(patterns)


def _seconds_to_ns(value: Any, what: str) -> int:
    try:
        seconds = float(value)
    except (TypeError, ValueError):
        raise CompareError(f"{what} must be a number of seconds, got {value!r}") from None
    if seconds < 0:
        raise CompareError(f"{what} must be >= 0, got {value!r}")
    return seconds_to_ns(seconds, value, CompareError)


def _fraction(value: Any, what: str) -> float:
    try:
        return float(value)
    except (TypeError, ValueError):
        raise CompareError(f"{what} must be a fraction in [0, 1], got {value!r}") from None


def _tolerance(data: Mapping[str, Any], base: Tolerance, where: str) -> Tolerance:
    unknown = set(data) - {"atol", "rtol"}
    if unknown:
        raise CompareError(f"{where}: unknown tolerance keys {sorted(unknown)}")
    try:
        return Tolerance(
            atol=float(data.get("atol", base.atol)), rtol=float(data.get("rtol", base.rtol))
        )
    except (TypeError, ValueError):
        raise CompareError(f"{where}: atol and rtol must be numbers") from None


def options_from_mapping(data: Mapping[str, Any], **overrides: Any) -> CompareOptions:
    """Build options from the ``compare:`` section of a fixture spec (see docs/regression.md).

    Keys: ``atol``, ``rtol``, ``ignore_fields`` (list), ``event_topics`` (list),
    ``event_window`` (s), ``match_window`` (s), ``include_times``, ``pass_rate``, and
    ``topics``: a mapping of topic to ``{atol, rtol, match_window, pass_rate, fields: {GLOB:
    {atol, rtol}}}``. ``overrides``
    replace the resulting options' attributes (what the command line sets explicitly).
    """
    known = {
        "atol",
        "rtol",
        "ignore_fields",
        "event_topics",
        "event_window",
        "match_window",
        "include_times",
        "pass_rate",
        "topics",
    }
    unknown = set(data) - known
    if unknown:
        raise CompareError(f"compare spec: unknown keys {sorted(unknown)}")
    default = _tolerance({k: v for k, v in data.items() if k in {"atol", "rtol"}}, Tolerance(), "")
    rules: list[ToleranceRule] = []
    windows: dict[str, int] = {}
    rates: dict[str, float] = {}
    for topic, raw_topic_spec in (data.get("topics") or {}).items():
        topic_spec = dict(raw_topic_spec or {})
        fields = topic_spec.pop("fields", None) or {}
        if "match_window" in topic_spec:
            windows[topic] = _seconds_to_ns(topic_spec.pop("match_window"), f"{topic} match_window")
        if "pass_rate" in topic_spec:
            rates[topic] = _fraction(topic_spec.pop("pass_rate"), f"{topic} pass_rate")
        topic_tolerance = _tolerance(topic_spec, default, f"compare spec topic {topic}")
        if topic_spec:
            rules.append(ToleranceRule(topic, "*", topic_tolerance))
        for glob, field_spec in fields.items():
            where = f"compare spec {topic} field {glob}"
            rules.append(
                ToleranceRule(topic, glob, _tolerance(field_spec or {}, topic_tolerance, where))
            )
    options = CompareOptions(
        tolerance=default,
        rules=tuple(rules),
        ignore_fields=tuple(data.get("ignore_fields") or ()),
        event_topics=tuple(data.get("event_topics", DEFAULT_EVENT_TOPICS)),
        event_window_ns=_seconds_to_ns(data.get("event_window", 0.5), "event_window"),
        match_window_ns=_seconds_to_ns(data.get("match_window", 0.0), "match_window"),
        match_windows=windows,
        include_times=bool(data.get("include_times", False)),
        pass_rate=_fraction(data.get("pass_rate", 1.0), "pass_rate"),
        pass_rates=rates,
    )
    return replace_options(options, **overrides)


def replace_options(options: CompareOptions, **changes: Any) -> CompareOptions:
    """``options`` with ``changes`` applied, skipping the ones that are None."""
    import dataclasses

    return dataclasses.replace(options, **{k: v for k, v in changes.items() if v is not None})
