"""The pure comparison: matching messages and events, checking fields against tolerances."""

from __future__ import annotations

import heapq
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from bagkit.compare.options import CompareOptions, Tolerance
from bagkit.compare.result import SHAPE_KINDS, Divergence, FieldResult, TopicResult, Value

STAMP_FIELDS = ("header.stamp.sec", "header.stamp.nanosec")


@dataclass(frozen=True, slots=True)
class Sample:
    """One message reduced to what is compared: its times and its flattened leaf fields."""

    log_time: int
    publish_time: int
    fields: Mapping[str, Any]

    @property
    def stamp(self) -> int | None:
        """The header stamp in ns, or None for messages without a header."""
        sec = self.fields.get(STAMP_FIELDS[0])
        nanosec = self.fields.get(STAMP_FIELDS[1])
        if isinstance(sec, int) and isinstance(nanosec, int):
            return sec * 1_000_000_000 + nanosec
        return None

    @property
    def time_ns(self) -> int:
        """The time a report shows: the header stamp where there is one, else the receive time."""
        stamp = self.stamp
        return self.log_time if stamp is None else stamp


@dataclass(frozen=True, slots=True)
class Event:
    """One status of a DiagnosticArray event topic (an alert raised or cleared)."""

    time_ns: int
    name: str
    level: int
    message: str


def _is_number(value: object) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _elements(value: object) -> list[Value] | None:
    """The elements of a sequence field (a list or numpy array); None for a scalar."""
    if isinstance(value, str | bytes):
        return None
    tolist = getattr(value, "tolist", None)
    if tolist is not None:
        return list(tolist())
    return list(value) if isinstance(value, list | tuple) else None


# Integers are enums, levels, counts and stamps: equal or not.
_EXACT = Tolerance()


def _match_by_stamp(
    golden: Sequence[Sample], candidate: Sequence[Sample], window_ns: int
) -> tuple[list[tuple[Sample, Sample]], list[Sample], list[Sample]]:
    """Pair messages whose stamps are within ``window_ns``, in stamp order (a sorted merge)."""
    g_sorted = sorted(golden, key=lambda s: s.time_ns)
    c_sorted = sorted(candidate, key=lambda s: s.time_ns)
    pairs: list[tuple[Sample, Sample]] = []
    missing: list[Sample] = []
    extra: list[Sample] = []
    i = j = 0
    while i < len(g_sorted) and j < len(c_sorted):
        g_time, c_time = g_sorted[i].time_ns, c_sorted[j].time_ns
        if abs(g_time - c_time) <= window_ns:
            pairs.append((g_sorted[i], c_sorted[j]))
            i += 1
            j += 1
        elif c_time < g_time:
            extra.append(c_sorted[j])
            j += 1
        else:
            missing.append(g_sorted[i])
            i += 1
    missing.extend(g_sorted[i:])
    extra.extend(c_sorted[j:])
    return pairs, missing, extra


def _relative_error(golden: float, candidate: float) -> float:
    scale = max(abs(golden), abs(candidate))
    return 0.0 if scale == 0 else abs(golden - candidate) / scale


class _TopicComparison:
    """Accumulates one topic's field results and divergences."""

    def __init__(self, result: TopicResult, options: CompareOptions) -> None:
        self.result = result
        self.options = options
        self.fields: dict[str, FieldResult] = {}
        self.kept: list[tuple[int, int, Divergence]] = []

    def diverge(self, divergence: Divergence) -> None:
        # Keep the earliest ones: a bounded max-heap on (time, arrival order).
        self.result.divergence_count += 1
        if divergence.kind in SHAPE_KINDS:
            self.result.shape_divergences += 1
        item = (-divergence.time_ns, -self.result.divergence_count, divergence)
        if len(self.kept) < self.options.max_divergences:
            heapq.heappush(self.kept, item)
        elif item > self.kept[0]:
            heapq.heapreplace(self.kept, item)

    def field_result(self, path: str, numeric: bool) -> FieldResult:
        found = self.fields.get(path)
        if found is None:
            tolerance = self.options.tolerance_for(self.result.topic, path)
            found = FieldResult(path, numeric, tolerance.atol, tolerance.rtol)
            self.fields[path] = found
        return found

    def compare_pair(self, golden: Sample, candidate: Sample, *, skip: frozenset[str]) -> None:
        topic = self.result.topic
        g_fields = dict(golden.fields)
        c_fields = dict(candidate.fields)
        if self.options.include_times:
            for sample, fields in ((golden, g_fields), (candidate, c_fields)):
                fields["~log_time"] = sample.log_time / 1e9
                fields["~publish_time"] = sample.publish_time / 1e9
        for path in g_fields.keys() | c_fields.keys():
            if path in skip or self.options.is_ignored(topic, path):
                continue
            if path not in c_fields:
                self.diverge(
                    Divergence("missing_field", topic, golden.time_ns, path, g_fields[path])
                )
                continue
            if path not in g_fields:
                self.diverge(
                    Divergence("extra_field", topic, golden.time_ns, path, None, c_fields[path])
                )
                continue
            g_value, c_value = g_fields[path], c_fields[path]
            g_items, c_items = _elements(g_value), _elements(c_value)
            if g_items is None and c_items is None:
                self.compare_value(path, g_value, c_value, golden.time_ns)
                continue
            # A sequence field: its length, then element by element under the field's path.
            g_items = [g_value] if g_items is None else g_items
            c_items = [c_value] if c_items is None else c_items
            if len(g_items) != len(c_items):
                self.diverge(
                    Divergence("length", topic, golden.time_ns, path, len(g_items), len(c_items))
                )
            for i, (g_item, c_item) in enumerate(zip(g_items, c_items, strict=False)):
                self.compare_value(path, g_item, c_item, golden.time_ns, label=f"{path}#{i}")

    def compare_value(
        self, path: str, golden: Value, candidate: Value, time_ns: int, *, label: str = ""
    ) -> None:
        """Compare one value: floats within tolerance, integers (enums, levels, counts) and
        strings exactly. ``label`` names the element of a sequence field in divergences."""
        topic = self.result.topic
        label = label or path
        if _is_number(golden) and _is_number(candidate):
            assert isinstance(golden, int | float) and isinstance(candidate, int | float)
            stats = self.field_result(path, numeric=True)
            stats.compared += 1
            exact = isinstance(golden, int) and isinstance(candidate, int)
            tolerance = _EXACT if exact else self.options.tolerance_for(topic, path)
            g, c = float(golden), float(candidate)
            if math.isnan(g) or math.isnan(c) or math.isinf(g) or math.isinf(c):
                abs_error = 0.0 if tolerance.accepts(g, c) else math.inf
                rel_error = abs_error
            else:
                abs_error = abs(g - c)
                rel_error = _relative_error(g, c)
            stats.max_abs_error = max(stats.max_abs_error, abs_error)
            stats.max_rel_error = max(stats.max_rel_error, rel_error)
            if not tolerance.accepts(g, c):
                stats.failed += 1
                self.diverge(
                    Divergence("value", topic, time_ns, label, golden, candidate, abs_error)
                )
            return
        stats = self.field_result(path, numeric=False)
        stats.compared += 1
        if golden != candidate or type(golden) is not type(candidate):
            stats.failed += 1
            self.diverge(Divergence("value", topic, time_ns, label, golden, candidate))

    def finish(self) -> TopicResult:
        self.result.fields = sorted(self.fields.values(), key=lambda f: f.path)
        self.result.divergences = [d for *_, d in sorted(self.kept, reverse=True)]
        return self.result


def compare_samples(
    topic: str,
    msg_type: str,
    golden: Sequence[Sample],
    candidate: Sequence[Sample],
    options: CompareOptions,
) -> TopicResult:
    """Compare one topic's messages: matched by header stamp, or by order without a header.

    Matched messages are compared field by field; the stamp fields used for matching are not
    compared again. Unmatched golden messages are missing, unmatched candidate ones extra.
    """
    stamped = all(s.stamp is not None for s in (*golden, *candidate)) and bool(golden or candidate)
    result = TopicResult(topic, msg_type, "stamp" if stamped else "order")
    result.golden_count = len(golden)
    result.candidate_count = len(candidate)
    comparison = _TopicComparison(result, options)
    if stamped:
        pairs, missing, extra = _match_by_stamp(golden, candidate, options.window_for(topic))
        skip = frozenset(STAMP_FIELDS)
    else:
        pairs = list(zip(golden, candidate, strict=False))
        missing = list(golden[len(pairs) :])
        extra = list(candidate[len(pairs) :])
        skip = frozenset()
    result.matched = len(pairs)
    result.missing = len(missing)
    result.extra = len(extra)
    for sample in missing:
        comparison.diverge(Divergence("missing_message", topic, sample.time_ns))
    for sample in extra:
        comparison.diverge(Divergence("extra_message", topic, sample.time_ns))
    result.failed_messages = len(missing) + len(extra)
    for g, c in pairs:
        before = result.divergence_count
        comparison.compare_pair(g, c, skip=skip)
        if result.divergence_count > before:
            result.failed_messages += 1
    result.allowed_failed_messages = _allowed(options, topic, len(golden))
    return comparison.finish()


def _allowed(options: CompareOptions, topic: str, golden_count: int) -> int:
    return math.floor((1.0 - options.pass_rate_for(topic)) * golden_count + 1e-9)


def compare_events(
    topic: str,
    msg_type: str,
    golden: Sequence[Event],
    candidate: Sequence[Event],
    options: CompareOptions,
) -> TopicResult:
    """Compare alert events: each golden event needs a candidate event with the same
    (name, level) within ``options.event_window_ns``; the nearest unused one is taken."""
    result = TopicResult(topic, msg_type, "event")
    result.golden_count = len(golden)
    result.candidate_count = len(candidate)
    comparison = _TopicComparison(result, options)
    unused = sorted(candidate, key=lambda e: e.time_ns)
    for event in sorted(golden, key=lambda e: e.time_ns):
        nearby = [
            c
            for c in unused
            if (c.name, c.level) == (event.name, event.level)
            and abs(c.time_ns - event.time_ns) <= options.event_window_ns
        ]
        if not nearby:
            result.missing += 1
            comparison.diverge(
                Divergence("missing_event", topic, event.time_ns, event.name, _level(event))
            )
            continue
        best = min(nearby, key=lambda c: abs(c.time_ns - event.time_ns))
        unused.remove(best)
        result.matched += 1
        result.max_event_shift_ns = max(
            result.max_event_shift_ns, abs(best.time_ns - event.time_ns)
        )
    for event in unused:
        result.extra += 1
        comparison.diverge(
            Divergence("extra_event", topic, event.time_ns, event.name, None, _level(event))
        )
    result.failed_messages = result.missing + result.extra
    result.allowed_failed_messages = _allowed(options, topic, len(golden))
    return comparison.finish()


_LEVEL_NAMES = {0: "OK", 1: "WARN", 2: "ERROR", 3: "STALE"}


def _level(event: Event) -> str:
    return _LEVEL_NAMES.get(event.level, str(event.level))
