"""Closed-loop runs of the processors for the tests, and altitude errors against the truth."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from fusion import topics
from fusion.processors import NODE_NAMES, LogLine
from fusion.simulate import DEFAULT_START_NS, simulate

START_NS = DEFAULT_START_NS


@dataclass
class LoopResult:
    """Every message published, in order, with the clock value it was published at."""

    published: list[tuple[int, str, Any]] = field(default_factory=list)
    logs: dict[str, list[LogLine]] = field(default_factory=dict)

    def messages(self, topic: str) -> list[Any]:
        return [msg for _, t, msg in self.published if t == topic]


def run_loop(
    duration_s: float,
    params: Mapping[str, Mapping[str, object]] | None = None,
    *,
    nodes: tuple[str, ...] = NODE_NAMES,
) -> LoopResult:
    """Run ``nodes`` for ``duration_s`` of simulated time and keep everything they publish."""
    result = LoopResult(logs={name: [] for name in nodes})
    for published in simulate(
        duration_s,
        params,
        nodes=nodes,
        on_log=lambda node, line: result.logs[node].append(line),
    ):
        result.published.append((published.now_ns, published.topic, published.msg))
    return result


def rms(values: list[float]) -> float:
    return math.sqrt(sum(v * v for v in values) / len(values))


def altitude_errors(result: LoopResult, *, after_s: float = 0.0) -> dict[str, list[float]]:
    """Fused, barometric and GPS altitude minus the truth at the same stamp."""
    truth = {_ns(m.header.stamp): m.pose.pose.position.z for m in result.messages(topics.TRUTH)}
    start = START_NS + round(after_s * 1e9)

    def errors(topic: str, value: Any) -> list[float]:
        out = []
        for msg in result.messages(topic):
            t = _ns(msg.header.stamp)
            v = value(msg)
            if t >= start and t in truth and math.isfinite(v):
                out.append(v - truth[t])
        return out

    return {
        "fused": errors(topics.ODOMETRY, lambda m: m.pose.pose.position.z),
        "baro": errors(topics.BARO_ALTITUDE, lambda m: m.pose.pose.position.z),
        "gps": errors(topics.GPS, lambda m: m.altitude),
    }


def _ns(stamp: Any) -> int:
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)
