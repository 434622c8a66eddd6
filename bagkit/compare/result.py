"""What a comparison finds: per field, per topic and overall, as small dataclasses."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any

Value = float | int | str | bool | bytes | list[Any] | None


@dataclass(frozen=True, slots=True)
class Divergence:
    """One place where the candidate differs from the golden.

    ``kind`` is one of ``value``, ``missing_field``, ``extra_field``, ``missing_message``,
    ``extra_message``, ``missing_event``, ``extra_event``, ``type``. ``time_ns`` is the header
    stamp (or receive time where there is none) of the golden message, or of the candidate's
    for extra messages.
    """

    kind: str
    topic: str
    time_ns: int
    field: str = ""
    golden: Value = None
    candidate: Value = None
    abs_error: float | None = None

    def describe(self) -> str:
        """One human-readable line."""
        where = f"{self.topic} t={self.time_ns / 1e9:.3f}s"
        if self.kind == "value":
            error = "" if self.abs_error is None else f" (|err| {self.abs_error:.6g})"
            return f"{where} {self.field}: {self.golden!r} -> {self.candidate!r}{error}"
        what = self.kind.replace("_", " ")
        if self.kind in {"missing_event", "extra_event"}:
            return f"{where} {what} {self.field} {self.golden or self.candidate!s}"
        return f"{where} {what} {self.field}".rstrip()


@dataclass(slots=True)
class FieldResult:
    """Errors of one field over all matched messages of a topic."""

    path: str
    numeric: bool
    atol: float
    rtol: float
    compared: int = 0
    failed: int = 0
    max_abs_error: float = 0.0
    max_rel_error: float = 0.0

    @property
    def passed(self) -> bool:
        """Whether every compared value was within tolerance."""
        return self.failed == 0

    def describe(self) -> str:
        """``path (max |err| 0.04)``; a text has no error: ``path (3 of 6 differ)``."""
        if self.numeric:
            return f"{self.path} (max |err| {self.max_abs_error:.3g})"
        return f"{self.path} ({self.failed} of {self.compared} differ)"


# Divergences no pass rate excuses: the messages do not have the same shape.
SHAPE_KINDS = frozenset({"missing_field", "extra_field", "length", "type"})


@dataclass(slots=True)
class TopicResult:
    """How one topic of the candidate compares with the golden."""

    topic: str
    type: str
    matched_by: str  # "stamp", "order", "event" or "" (not compared)
    golden_count: int = 0
    candidate_count: int = 0
    matched: int = 0
    missing: int = 0
    extra: int = 0
    fields: list[FieldResult] = field(default_factory=list)
    divergence_count: int = 0
    divergences: list[Divergence] = field(default_factory=list)
    max_event_shift_ns: int = 0
    shape_divergences: int = 0  # fields, sequence lengths or types that differ
    failed_messages: int = 0  # missing, extra, or matched with a value out of tolerance
    allowed_failed_messages: int = 0  # what the topic's pass rate allows
    # Messages whose payload did not decode: left out of the matching (so their partners count
    # as missing or extra).
    golden_undecodable: int = 0
    candidate_undecodable: int = 0
    absent: str = ""
    """Why a golden topic is absent from the candidate ("" when present): a broken candidate
    fails whatever the pass rate."""

    @property
    def counted(self) -> str:
        """What the counts count: ``statuses`` on an event topic, else ``messages``."""
        return "statuses" if self.matched_by == "event" else "messages"

    @property
    def passed(self) -> bool:
        """Whether the topic is identical within tolerance: present in the candidate (with
        messages when the golden has some), no message of another shape, and no more missing,
        extra or out-of-tolerance messages (or events) than the topic's pass rate allows (none
        by default)."""
        return (
            not self.absent
            and self.shape_divergences == 0
            and self.failed_messages <= self.allowed_failed_messages
        )

    @property
    def failed_fields(self) -> list[FieldResult]:
        """The fields with at least one value out of tolerance."""
        return [f for f in self.fields if not f.passed]

    @property
    def shape_fields(self) -> list[str]:
        """Fields of another shape (a sequence's length, a field missing, extra or retyped),
        as ``path (kind)``, among the divergences kept."""
        found = {f"{d.field} ({d.kind})" for d in self.divergences if d.kind in SHAPE_KINDS}
        return sorted(found)


@dataclass(slots=True)
class CompareReport:
    """The verdict of comparing a candidate bag with a golden one."""

    golden: str
    candidate: str
    topics: list[TopicResult]
    warnings: list[str] = field(default_factory=list)

    @property
    def passed(self) -> bool:
        """Whether every compared topic is identical within tolerance."""
        return all(t.passed for t in self.topics)

    @property
    def exit_code(self) -> int:
        """0 when identical within tolerance, 1 when different."""
        return 0 if self.passed else 1

    def first_divergences(self, limit: int = 10) -> list[Divergence]:
        """The earliest divergences over all topics, by time."""
        everything = [d for t in self.topics for d in t.divergences]
        return sorted(everything, key=lambda d: (d.time_ns, d.topic))[:limit]

    def to_dict(self) -> dict[str, Any]:
        """The JSON verdict (schema in docs/regression.md)."""
        return {
            "verdict": "pass" if self.passed else "fail",
            "golden": self.golden,
            "candidate": self.candidate,
            "warnings": list(self.warnings),
            "topics": [
                {
                    "topic": t.topic,
                    "type": t.type,
                    "passed": t.passed,
                    "absent": t.absent,
                    "matched_by": t.matched_by,
                    "counted": t.counted,
                    "golden_count": t.golden_count,
                    "candidate_count": t.candidate_count,
                    "matched": t.matched,
                    "missing": t.missing,
                    "extra": t.extra,
                    "divergence_count": t.divergence_count,
                    "failed_messages": t.failed_messages,
                    "allowed_failed_messages": t.allowed_failed_messages,
                    "golden_undecodable": t.golden_undecodable,
                    "candidate_undecodable": t.candidate_undecodable,
                    "max_event_shift_s": t.max_event_shift_ns / 1e9,
                    "failed_fields": [f.path for f in t.failed_fields],
                    "fields": [
                        {**asdict(f), "passed": f.passed}
                        | {
                            "max_abs_error": _json_float(f.max_abs_error),
                            "max_rel_error": _json_float(f.max_rel_error),
                        }
                        for f in t.fields
                    ],
                    "divergences": [_divergence_dict(d) for d in t.divergences],
                }
                for t in self.topics
            ],
        }


def _json_float(value: float) -> float | str:
    # JSON has no infinities or NaN; strict parsers reject them.
    return value if math.isfinite(value) else str(value)


def _json_value(value: Value) -> Any:
    if isinstance(value, bytes):
        return list(value)
    if isinstance(value, float):
        return _json_float(value)
    return value


def _divergence_dict(d: Divergence) -> dict[str, Any]:
    return {
        "kind": d.kind,
        "topic": d.topic,
        "time_s": d.time_ns / 1e9,
        "field": d.field,
        "golden": _json_value(d.golden),
        "candidate": _json_value(d.candidate),
        "abs_error": None if d.abs_error is None else _json_float(d.abs_error),
        "text": d.describe(),
    }
