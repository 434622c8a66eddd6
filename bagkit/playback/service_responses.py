"""Live responses against recorded ones: the verdict of ``replay --publish-service-requests``.

rosbag2 sends the recorded requests and ignores what comes back; bagkit compares each live
response with the one recorded for the same call, field by field (numbers within
``atol + rtol * |recorded|``), and sums up: matched, differed, unanswered. Responses are plain
data (nested dicts and lists, as ``bagkit echo`` prints them). No rclpy import.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any

from bagkit.words import counted

MAX_LISTED_DIFFERENCES = 100


@dataclass(frozen=True, slots=True)
class Tolerance:
    """How far a live number may be from the recorded one: ``atol + rtol * |recorded|``."""

    atol: float = 0.0
    rtol: float = 0.0


def differences(recorded: Any, live: Any, tolerance: Tolerance, path: str = "") -> list[str]:
    """Where ``live`` differs from ``recorded``: ``path: recorded -> live``, one per leaf."""
    if isinstance(recorded, dict) and isinstance(live, dict):
        found = []
        for key in dict.fromkeys([*recorded, *live]):
            sub = f"{path}.{key}" if path else str(key)
            found += differences(recorded.get(key), live.get(key), tolerance, sub)
        return found
    if isinstance(recorded, list) and isinstance(live, list):
        if len(recorded) != len(live):
            return [f"{path}: {counted(len(recorded), 'element')} -> {len(live)}"]
        found = []
        for i, (a, b) in enumerate(zip(recorded, live, strict=True)):
            found += differences(a, b, tolerance, f"{path}[{i}]")
        return found
    if _numbers(recorded, live):
        a, b = float(recorded), float(live)
        if (math.isnan(a) and math.isnan(b)) or abs(a - b) <= (
            tolerance.atol + tolerance.rtol * abs(a)
        ):
            return []
    elif recorded == live:
        return []
    return [f"{path or '<response>'}: {recorded!r} -> {live!r}"]


def _numbers(a: Any, b: Any) -> bool:
    return all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in (a, b))


@dataclass(frozen=True, slots=True)
class CallOutcome:
    """One replayed request: where it sat in the bag and what came of it."""

    service: str
    sequence_number: int
    log_time_ns: int
    outcome: str
    """``matched``, ``differed``, ``unanswered`` or ``not_recorded`` (no recorded response)."""
    differences: tuple[str, ...] = ()


@dataclass(slots=True)
class ServiceReplaySummary:
    """Per service and in total: requests sent and how their responses compared."""

    sent: dict[str, int] = field(default_factory=dict)
    matched: dict[str, int] = field(default_factory=dict)
    differed: dict[str, int] = field(default_factory=dict)
    unanswered: dict[str, int] = field(default_factory=dict)
    not_recorded: dict[str, int] = field(default_factory=dict)
    empty_requests: dict[str, int] = field(default_factory=dict)
    """Request events without a request (METADATA introspection): nothing could be sent."""
    calls: list[CallOutcome] = field(default_factory=list)
    """The calls that did not match (at most ``MAX_LISTED_DIFFERENCES``)."""

    def add(self, outcome: CallOutcome) -> None:
        """Count one call's outcome (and keep it, unless it matched)."""
        counts = getattr(self, outcome.outcome)
        counts[outcome.service] = counts.get(outcome.service, 0) + 1
        if outcome.outcome != "matched" and len(self.calls) < MAX_LISTED_DIFFERENCES:
            self.calls.append(outcome)

    def total(self, kind: str) -> int:
        """``sent``, ``matched``, ``differed``, ``unanswered``... summed over services."""
        return sum(getattr(self, kind).values())

    @property
    def ok(self) -> bool:
        """Every request sent was answered as recorded."""
        return not self.total("differed") and not self.total("unanswered")

    def to_dict(self) -> dict[str, Any]:
        """The JSON form (``replay --format json``'s ``service_requests``)."""
        data = asdict(self)
        data["totals"] = {
            kind: self.total(kind)
            for kind in ("sent", "matched", "differed", "unanswered", "not_recorded")
        }
        return data


def compare_response(
    service: str,
    sequence_number: int,
    log_time_ns: int,
    *,
    recorded: Any,
    live: Any,
    tolerance: Tolerance,
) -> CallOutcome:
    """The outcome of one call: ``live`` None = unanswered, ``recorded`` None = not recorded."""
    if live is None:
        return CallOutcome(service, sequence_number, log_time_ns, "unanswered")
    if recorded is None:
        return CallOutcome(service, sequence_number, log_time_ns, "not_recorded")
    found = differences(recorded, live, tolerance)
    kind = "differed" if found else "matched"
    return CallOutcome(service, sequence_number, log_time_ns, kind, tuple(found))
