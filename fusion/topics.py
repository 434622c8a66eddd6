"""The topics of the live system, their message types and their delivery semantics."""

from __future__ import annotations

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseWithCovarianceStamped
from nav_msgs.msg import Odometry
from sensor_msgs.msg import FluidPressure, Imu, NavSatFix, Temperature

IMU = "/imu/data"
GPS = "/gps/fix"
TEMPERATURE = "/temperature"
PRESSURE = "/barometer/pressure"
ALERTS = "/alerts"
LOGGER_SUMMARY = "/logger/summary"
ODOMETRY = "/fusion/odometry"
BARO_ALTITUDE = "/fusion/baro_altitude"
# Ground truth of the simulation, stamped like the IMU sample it belongs to: what the fused
# estimate is scored against in tests and recorded bags.
TRUTH = "/sim/truth"

# The data logger's service: its current per-topic message counts, on request
# (std_srvs/srv/Trigger); introspection events on LOGGER_GET_SUMMARY + "/_service_event".
LOGGER_GET_SUMMARY = "/logger/get_summary"

SENSOR_TOPICS: tuple[str, ...] = (IMU, GPS, TEMPERATURE, PRESSURE)

TOPIC_TYPES: dict[str, type] = {
    IMU: Imu,
    GPS: NavSatFix,
    TEMPERATURE: Temperature,
    PRESSURE: FluidPressure,
    ALERTS: DiagnosticArray,
    LOGGER_SUMMARY: DiagnosticArray,
    ODOMETRY: Odometry,
    BARO_ALTITUDE: PoseWithCovarianceStamped,
    TRUTH: Odometry,
}

# State topics: the last message is the current state, so a late subscriber must receive it
# (transient local, depth 1). Every other topic is a stream that must not lose messages.
STATE_TOPICS: frozenset[str] = frozenset({ALERTS, LOGGER_SUMMARY})
