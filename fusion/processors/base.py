"""What every fusion processor shares: bagkit's ``Processor`` protocol and a log buffer.

The rclpy nodes and bagkit's lockstep harness drive the same objects; lockstep knows them as
``bagkit.regression.Processor``, which :class:`ProcessorBase` implements.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass
from typing import Any

from bagkit.regression import Output


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


class ProcessorBase:
    """A ``bagkit.regression.Processor`` with no-op handlers, plus the log buffer the node reads.

    ``now_ns`` is the node clock (sim time under ``use_sim_time``, the bag's log time in
    lockstep); processors never read the wall clock and own their random generators, so the
    same inputs at the same times give the same outputs. ``drain_log`` returns the lines to
    log; lines below ``min_log_severity`` are not produced (the node sets its logger's level).
    """

    input_topics: tuple[str, ...] = ()
    output_topics: tuple[str, ...] = ()
    timer_period_ns: int | None = None
    # Service name -> its rclpy service type; requests go to ``on_request``.
    services: dict[str, type] = {}  # noqa: RUF012 (read only; overridden per class)

    def __init__(self) -> None:
        self._log: list[LogLine] = []
        self.min_log_severity = Severity.DEBUG

    def on_message(self, topic: str, msg: Any, now_ns: int) -> list[Output]:
        """Ignore the message."""
        return []

    def on_timer(self, now_ns: int) -> list[Output]:
        """Do nothing."""
        return []

    def on_request(self, service: str, request: Any, now_ns: int) -> Any:
        """Answer a request of one of ``services``; the base class offers none."""
        raise NotImplementedError(service)

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
