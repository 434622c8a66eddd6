"""The processor interface shared by the rclpy nodes and the lockstep regression harness."""

from __future__ import annotations

import enum
from dataclasses import dataclass
from typing import Any, Protocol

Output = tuple[str, Any]


class Severity(enum.IntEnum):
    """Severity of a log line, mapped onto the ROS logger by the node."""

    DEBUG = 10
    INFO = 20
    WARN = 30
    ERROR = 40


@dataclass(frozen=True, slots=True)
class LogLine:
    """A line the node should log (the processor itself never logs)."""

    severity: Severity
    text: str


class Processor(Protocol):
    """A node's logic without rclpy: ROS message objects in, ROS message objects out.

    ``now_ns`` is the node clock (sim time under ``use_sim_time``, the bag's log time in
    lockstep); processors never read the wall clock and own their random generators, so the
    same inputs at the same times give the same outputs.
    """

    @property
    def input_topics(self) -> tuple[str, ...]:
        """Topics to subscribe to and pass to ``on_message``."""
        ...

    @property
    def output_topics(self) -> tuple[str, ...]:
        """Topics the outputs may name (types in ``fusion.topics.TOPIC_TYPES``)."""
        ...

    @property
    def timer_period_ns(self) -> int | None:
        """Period of ``on_timer`` calls on the node clock; None: no timer."""
        ...

    def on_message(self, topic: str, msg: Any, now_ns: int) -> list[Output]:
        """Handle one received message; return ``(topic, message)`` pairs to publish.

        Topics not in ``input_topics`` are ignored.
        """
        ...

    def on_timer(self, now_ns: int) -> list[Output]:
        """Handle a timer tick (only called when ``timer_period_ns`` is set)."""
        ...

    def drain_log(self) -> list[LogLine]:
        """Return and forget the log lines produced since the last call."""
        ...

    min_log_severity: Severity
    """Lines below this severity are not produced (the node sets its logger's level)."""


class ProcessorBase:
    """Default no-op handlers and the log buffer."""

    input_topics: tuple[str, ...] = ()
    output_topics: tuple[str, ...] = ()
    timer_period_ns: int | None = None

    def __init__(self) -> None:
        self._log: list[LogLine] = []
        self.min_log_severity = Severity.DEBUG

    def on_message(self, topic: str, msg: Any, now_ns: int) -> list[Output]:
        """Ignore the message."""
        return []

    def on_timer(self, now_ns: int) -> list[Output]:
        """Do nothing."""
        return []

    def drain_log(self) -> list[LogLine]:
        """Return and forget the log lines produced since the last call."""
        lines, self._log = self._log, []
        return lines

    def logs(self, severity: Severity) -> bool:
        """Whether a line of ``severity`` would be kept (to skip formatting one that is not)."""
        return severity >= self.min_log_severity

    def log(self, severity: Severity, text: str) -> None:
        """Queue a line for the node to log (unless below ``min_log_severity``)."""
        if severity >= self.min_log_severity:
            self._log.append(LogLine(severity, text))
