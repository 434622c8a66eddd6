"""alert_system: range, stuck, fix and staleness checks of every sensor, published on change."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from sensor_msgs.msg import NavSatStatus

from bagkit.regression import Output
from fusion import topics
from fusion.alerts import AlertMonitor, Level, RangeRule, SensorRules, SensorState
from fusion.params import Params
from fusion.processors.base import ProcessorBase, Severity
from fusion.processors.messages import field_value, stamp


@dataclass(frozen=True, slots=True)
class _Sensor:
    topic: str
    fields: dict[str, str]  # rule name -> message field
    stuck_fields: tuple[str, ...] = ()


# The checks are fixed per sensor; their limits are parameters.
SENSORS: dict[str, _Sensor] = {
    "imu": _Sensor(
        topics.IMU,
        {"accel_z": "linear_acceleration.z"},
        stuck_fields=tuple(
            f"{vector}.{axis}"
            for vector in ("linear_acceleration", "angular_velocity")
            for axis in "xyz"
        ),
    ),
    "gps": _Sensor(topics.GPS, {}),
    "temperature": _Sensor(topics.TEMPERATURE, {"temperature": "temperature"}),
    "pressure": _Sensor(topics.PRESSURE, {"fluid_pressure": "fluid_pressure"}),
}
_SENSOR_BY_TOPIC = {sensor.topic: name for name, sensor in SENSORS.items()}

_DIAGNOSTIC_LEVELS = {
    Level.OK: DiagnosticStatus.OK,
    Level.WARN: DiagnosticStatus.WARN,
    Level.ERROR: DiagnosticStatus.ERROR,
    Level.STALE: DiagnosticStatus.STALE,
}
_LOG_SEVERITY = {
    Level.OK: Severity.INFO,
    Level.WARN: Severity.WARN,
    Level.ERROR: Severity.ERROR,
    Level.STALE: Severity.WARN,
}


def _parameter_descriptions() -> dict[str, str]:
    descriptions = {
        "check_rate": "Rate (Hz) of the staleness check.",
        "stale_periods": "A sensor silent for more than this many of its periods is STALE.",
        "startup_grace": "Seconds a sensor never heard from has before it is STALE.",
        "debounce_samples": "Consecutive samples a new level must persist to be published.",
        "imu.stuck_samples": "Identical consecutive IMU samples that mean a stuck IMU (ERROR).",
    }
    for name, sensor in SENSORS.items():
        descriptions[f"{name}.period"] = f"Nominal period (s) of {sensor.topic}."
        for rule, path in sensor.fields.items():
            descriptions[f"{name}.{rule}.warn"] = f"[low, high] of {path}; outside: WARN."
            descriptions[f"{name}.{rule}.error"] = f"[low, high] of {path}; outside: ERROR."
            descriptions[f"{name}.{rule}.hysteresis"] = (
                f"How far inside a limit {path} must come back before its level drops."
            )
    return descriptions


PARAMETER_DESCRIPTIONS = _parameter_descriptions()


class AlertSystem(ProcessorBase):
    """Publishes the state of every sensor on /alerts whenever one of them changes."""

    input_topics = topics.SENSOR_TOPICS
    output_topics = (topics.ALERTS,)

    def __init__(self, params: Mapping[str, object] | None = None) -> None:
        super().__init__()
        p = Params("alert_system", params)
        self.timer_period_ns = round(1e9 / p.number("check_rate", positive=True))
        rules = {}
        for name, sensor in SENSORS.items():
            stuck_key = f"{name}.stuck_samples"
            rules[name] = SensorRules(
                name=name,
                period_ns=round(p.number(f"{name}.period", positive=True) * 1e9),
                ranges=tuple(
                    RangeRule(
                        name=rule,
                        warn=p.interval(f"{name}.{rule}.warn"),
                        error=p.interval(f"{name}.{rule}.error"),
                        hysteresis=p.number(f"{name}.{rule}.hysteresis", non_negative=True),
                    )
                    for rule in sensor.fields
                ),
                stuck_samples=p.integer(stuck_key, minimum=0) if stuck_key in p else 0,
                requires_fix=sensor.topic == topics.GPS,
            )
        self.monitor = AlertMonitor(
            rules,
            stale_periods=p.number("stale_periods", positive=True),
            debounce_samples=p.integer("debounce_samples", minimum=1),
            startup_grace_ns=round(p.number("startup_grace", non_negative=True) * 1e9),
        )

    def on_message(self, topic: str, msg: Any, now_ns: int) -> list[Output]:
        """Check one sample against its sensor's rules."""
        name = _SENSOR_BY_TOPIC.get(topic)
        if name is None:
            return []
        sensor = SENSORS[name]
        changed = self.monitor.on_sample(
            name,
            now_ns,
            {rule: float(field_value(msg, path)) for rule, path in sensor.fields.items()},
            stuck_key=tuple(float(field_value(msg, path)) for path in sensor.stuck_fields),
            has_fix=topic != topics.GPS or msg.status.status >= NavSatStatus.STATUS_FIX,
        )
        return self._report(changed, now_ns)

    def on_timer(self, now_ns: int) -> list[Output]:
        """Check for silent sensors."""
        return self._report(self.monitor.check(now_ns), now_ns)

    def _report(self, changed: list[SensorState], now_ns: int) -> list[Output]:
        if not changed:
            return []
        for state in changed:
            self.log(
                _LOG_SEVERITY[state.level],
                f"{SENSORS[state.name].topic}: {state.level.name}: {state.message}",
            )
        # The whole state every time: with a transient-local depth of 1, a late subscriber
        # gets every sensor's current level from one message.
        alerts = DiagnosticArray()
        alerts.header.stamp = stamp(now_ns)
        for state in self.monitor.states.values():
            status = DiagnosticStatus()
            status.level = _DIAGNOSTIC_LEVELS[state.level]
            status.name = f"alert_system: {state.name}"
            status.hardware_id = SENSORS[state.name].topic
            status.message = state.message
            status.values = [KeyValue(key=k, value=f"{v:.6g}") for k, v in state.values]
            alerts.status.append(status)
        return [(topics.ALERTS, alerts)]
