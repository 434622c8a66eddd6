"""Run the nodes' processors together in-process on a simulated clock, without ROS.

Every output is delivered to every processor subscribed to its topic at once, and each timer
fires on its own period, first one period after the start (as rclpy timers do). The result is
what the live system publishes, deterministically and far faster than real time.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from fusion.processors import NODE_NAMES, LogLine, ProcessorBase, create_processor

DEFAULT_START_NS = 1_700_000_000_000_000_000


@dataclass(frozen=True, slots=True)
class Published:
    """One message published by ``node`` on ``topic`` at clock time ``now_ns``."""

    now_ns: int
    node: str
    topic: str
    msg: Any


def simulate(
    duration_s: float,
    params: Mapping[str, Mapping[str, object]] | None = None,
    *,
    nodes: Sequence[str] = NODE_NAMES,
    start_ns: int = DEFAULT_START_NS,
    on_log: Callable[[str, LogLine], None] | None = None,
) -> Iterator[Published]:
    """Yield every message the ``nodes`` publish during ``duration_s`` seconds of clock time.

    ``params`` maps node name to parameter overrides; ``on_log`` receives each node's log lines.

    Raises:
        UnknownNodeError, ConfigError: as ``create_processor``.
    """
    params = params or {}
    processors: dict[str, ProcessorBase] = {n: create_processor(n, params.get(n)) for n in nodes}
    next_tick = {
        name: start_ns + p.timer_period_ns
        for name, p in processors.items()
        if p.timer_period_ns is not None
    }
    end_ns = start_ns + round(duration_s * 1e9)
    while next_tick:
        now_ns = min(next_tick.values())
        if now_ns >= end_ns:
            return
        for name, processor in processors.items():
            period = processor.timer_period_ns
            if period is None or next_tick[name] != now_ns:
                continue
            next_tick[name] += period
            queue = deque((name, output) for output in processor.on_timer(now_ns))
            while queue:
                source, (topic, msg) = queue.popleft()
                yield Published(now_ns, source, topic, msg)
                for receiver, subscriber in processors.items():
                    if topic in subscriber.input_topics:
                        queue.extend(
                            (receiver, out) for out in subscriber.on_message(topic, msg, now_ns)
                        )
        if on_log is not None:
            for name, processor in processors.items():
                for line in processor.drain_log():
                    on_log(name, line)
