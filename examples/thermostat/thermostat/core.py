"""The controller without ROS: temperature in, heater power out (a PI law on message stamps)."""

from __future__ import annotations

from typing import Any

from std_msgs.msg import Float64
from std_srvs.srv import Trigger

SETPOINT_C = 21.0
KP = 0.35  # heater power per degree below the setpoint
KI = 0.02  # heater power per degree-second below the setpoint
INPUT = "/thermostat/temperature"
OUTPUT = "/thermostat/heater"
STATUS = "/thermostat/status"


class Controller:
    """PI control of the heater power (0 - 1) from ``sensor_msgs/Temperature`` readings.

    Time comes from each reading's header stamp, never from a clock, so the same readings
    always give the same powers: what golden-bag regression needs.
    """

    input_topics = (INPUT,)
    output_topics = (OUTPUT,)
    timer_period_ns = None
    services = {STATUS: Trigger}  # noqa: RUF012 (read only)

    def __init__(self) -> None:
        self.integral = 0.0
        self.last_stamp_ns: int | None = None

    def on_message(self, topic: str, msg: Any, now_ns: int) -> list[tuple[str, Any]]:
        stamp_ns = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        error = SETPOINT_C - msg.temperature
        if self.last_stamp_ns is not None:
            self.integral += error * (stamp_ns - self.last_stamp_ns) / 1e9
        self.last_stamp_ns = stamp_ns
        power = min(1.0, max(0.0, KP * error + KI * self.integral))
        return [(OUTPUT, Float64(data=power))]

    def on_timer(self, now_ns: int) -> list[tuple[str, Any]]:
        return []

    def on_request(self, service: str, request: Any, now_ns: int) -> Any:
        """``/thermostat/status``: the control law's configuration (what a technician asks)."""
        return Trigger.Response(
            success=True, message=f"setpoint {SETPOINT_C:g} C, kp {KP:g}, ki {KI:g}"
        )


def make_processors() -> list[Controller]:
    """The factory the golden spec names (``processor: thermostat.core:make_processors``)."""
    return [Controller()]
