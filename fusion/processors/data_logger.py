"""data_logger: running statistics of every numeric sensor field, summarised periodically."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from std_srvs.srv import Trigger

from bagkit.regression import Output
from fusion import topics
from fusion.errors import ConfigError
from fusion.params import Params
from fusion.processors.base import ProcessorBase, Severity
from fusion.processors.messages import numeric_fields, stamp, stamp_ns
from fusion.stats import StreamMoments

PARAMETER_DESCRIPTIONS: dict[str, str] = {
    "summary_period": "Seconds of node-clock time between two summaries on /logger/summary.",
    "service_introspection": "Introspection of /logger/get_summary: off, metadata or contents "
    "(events on /logger/get_summary/_service_event, QoS depth 100; docs/record.md).",
}
INTROSPECTION_STATES = ("off", "metadata", "contents")

STAT_NAMES = ("count", "nan", "min", "max", "mean", "std")


def _format(value: float) -> str:
    return f"{value:.6g}" if not math.isnan(value) else "nan"


class DataLogger(ProcessorBase):
    """Keeps count/min/max/mean/std per field of each sensor topic; publishes a summary."""

    input_topics = topics.SENSOR_TOPICS
    output_topics = (topics.LOGGER_SUMMARY,)
    services = {topics.LOGGER_GET_SUMMARY: Trigger}  # noqa: RUF012 (read only)

    def __init__(self, params: Mapping[str, object] | None = None) -> None:
        super().__init__()
        p = Params("data_logger", params)
        self.timer_period_ns = round(p.number("summary_period", positive=True) * 1e9)
        self.stats = {topic: StreamMoments() for topic in self.input_topics}
        self.service_introspection = p.text("service_introspection")
        if self.service_introspection not in INTROSPECTION_STATES:
            raise ConfigError(
                f"data_logger: service_introspection must be one of "
                f"{', '.join(INTROSPECTION_STATES)}, got {self.service_introspection!r}"
            )

    def on_message(self, topic: str, msg: Any, now_ns: int) -> list[Output]:
        """Add the message's numeric fields to the topic's statistics."""
        if topic not in self.stats:
            return []
        values = numeric_fields(msg)
        self.stats[topic].add(values)
        if self.logs(Severity.DEBUG):
            fields = " ".join(f"{name}={value:.6g}" for name, value in values.items())
            self.log(Severity.DEBUG, f"{topic} stamp={stamp_ns(msg.header.stamp)} {fields}")
        return []

    def on_request(self, service: str, request: Any, now_ns: int) -> Any:
        """``/logger/get_summary``: success once every sensor topic has data; the message
        counts per topic (``/imu/data: 120; /gps/fix: 12; ...``)."""
        response = Trigger.Response()
        response.success = all(m.messages for m in self.stats.values())
        response.message = "; ".join(f"{t}: {m.messages}" for t, m in self.stats.items())
        return response

    def on_timer(self, now_ns: int) -> list[Output]:
        """Publish the summary and log it as a table."""
        summary = DiagnosticArray()
        summary.header.stamp = stamp(now_ns)
        for topic, moments in self.stats.items():
            status = DiagnosticStatus()
            status.name = f"data_logger: {topic}"
            status.hardware_id = topic
            if moments.messages:
                status.level = DiagnosticStatus.OK
                status.message = f"{moments.messages} messages"
            else:
                status.level = DiagnosticStatus.WARN
                status.message = "no messages"
            for name, figures in moments.fields():
                status.values.extend(
                    KeyValue(key=f"{name}.{stat}", value=_format(float(value)))
                    for stat, value in zip(STAT_NAMES, figures.row(), strict=True)
                )
            summary.status.append(status)
        self.log(Severity.INFO, self.table(now_ns))
        return [(topics.LOGGER_SUMMARY, summary)]

    def table(self, now_ns: int) -> str:
        """The current statistics as a fixed-width text table."""
        header = (
            f"{'topic':<20} {'field':<24} {'count':>6} {'nan':>4} {'min':>11} {'max':>11} "
            f"{'mean':>11} {'std':>10}"
        )
        lines = [f"summary at {now_ns / 1e9:.1f} s", header]
        for topic, moments in self.stats.items():
            if not moments.messages:
                lines.append(f"{topic:<20} (no messages)")
            for name, s in moments.fields():
                lines.append(
                    f"{topic:<20} {name:<24} {s.count:>6} {s.nan_count:>4} {s.min:>11.6g} "
                    f"{s.max:>11.6g} {s.mean:>11.6g} {s.std:>10.4g}"
                )
        return "\n".join(lines)
