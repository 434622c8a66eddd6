"""Drive the four processors in-process on a simulated clock, as the nodes would over DDS."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from fusion import topics
from fusion.processors import LogLine, Processor, create_processor

START_NS = 1_700_000_000_000_000_000


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
    nodes: tuple[str, ...] = ("sensor_publisher", "data_logger", "alert_system", "sensor_fusion"),
) -> LoopResult:
    """Run ``nodes`` for ``duration_s`` of simulated time; outputs feed every subscriber."""
    params = params or {}
    processors: dict[str, Processor] = {n: create_processor(n, params.get(n)) for n in nodes}
    # Like rclpy timers, each first fires one period after the start.
    next_tick = {
        name: START_NS + p.timer_period_ns
        for name, p in processors.items()
        if p.timer_period_ns is not None
    }
    result = LoopResult(logs={name: [] for name in nodes})
    end_ns = START_NS + round(duration_s * 1e9)
    while True:
        now_ns = min(next_tick.values())
        if now_ns >= end_ns:
            break
        for name, processor in processors.items():
            if next_tick.get(name) != now_ns:
                continue
            assert processor.timer_period_ns is not None
            next_tick[name] += processor.timer_period_ns
            _deliver(processors, result, now_ns, processor.on_timer(now_ns))
        for name, processor in processors.items():
            result.logs[name] += processor.drain_log()
    return result


def _deliver(
    processors: Mapping[str, Processor],
    result: LoopResult,
    now_ns: int,
    outputs: list[tuple[str, Any]],
) -> None:
    queue = list(outputs)
    while queue:
        topic, msg = queue.pop(0)
        result.published.append((now_ns, topic, msg))
        for processor in processors.values():
            if topic in processor.input_topics:
                queue += processor.on_message(topic, msg, now_ns)


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
