"""sensor_fusion: barometric altitude, the vertical Kalman filter and GPS position in local ENU."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from geometry_msgs.msg import PoseWithCovarianceStamped
from nav_msgs.msg import Odometry
from sensor_msgs.msg import NavSatFix, NavSatStatus

from bagkit.regression import Output
from fusion import topics
from fusion.estimation import (
    GeodeticOrigin,
    MovingAverage,
    VerticalFilterConfig,
    VerticalKalmanFilter,
    altitude_per_pascal,
    pressure_altitude,
)
from fusion.params import Params
from fusion.processors.base import ProcessorBase, Severity
from fusion.processors.messages import (
    copy_quaternion,
    copy_vector3,
    set_stamp,
    stamp,
    stamp_ns,
)

# Variance reported for quantities this node does not estimate (REP 103 has no "unknown" marker
# for pose covariances; a huge variance is what consumers such as robot_localization ignore).
UNKNOWN_VARIANCE = 1e6

PARAMETER_DESCRIPTIONS: dict[str, str] = {
    "frame_id": "Frame of the fused pose: local ENU, origin at the first GPS fix, z = altitude "
    "above mean sea level.",
    "child_frame_id": "Body frame of the odometry (the IMU's frame).",
    "qnh": "Sea-level pressure (Pa) for the ISA barometric altitude.",
    "gravity": "Gravity (m/s^2) subtracted from the IMU's vertical specific force.",
    "moving_average_window": "Average this many pressure samples before use (1: off).",
    "accel_sigma": "Process noise: white vertical acceleration (m/s^2) of the Kalman filter.",
    "baro_sigma": "Barometer noise (Pa) when the message reports variance 0 (unknown).",
    "baro_bias_sigma": "Prior uncertainty (m) of the barometric altitude bias.",
    "baro_bias_random_walk": "Drift (m/sqrt(s)) of the barometric altitude bias.",
    "gps_horizontal_sigma": "GPS horizontal sigma (m) when the fix has no covariance.",
    "gps_vertical_sigma": "GPS vertical sigma (m) when the fix has no covariance.",
    "horizontal_speed_sigma": "Growth (m/s) of the horizontal position sigma without a fix.",
    "innovation_gate": "Reject altitude measurements further than this many sigmas (0: off).",
    "max_rejections": "Accept a source again after this many consecutive rejections.",
}


class SensorFusion(ProcessorBase):
    """Odometry with each IMU sample, barometric altitude with each pressure sample."""

    input_topics = (topics.IMU, topics.GPS, topics.PRESSURE)
    output_topics = (topics.ODOMETRY, topics.BARO_ALTITUDE)
    timer_period_ns = None

    def __init__(self, params: Mapping[str, object] | None = None) -> None:
        super().__init__()
        p = Params("sensor_fusion", params)
        self.frame_id = p.text("frame_id")
        self.child_frame_id = p.text("child_frame_id")
        self.qnh = p.number("qnh", positive=True)
        self.gravity = p.number("gravity", positive=True)
        self.pressure_filter = MovingAverage(p.integer("moving_average_window", minimum=1))
        self.baro_sigma = p.number("baro_sigma", positive=True)
        self.gps_horizontal_sigma = p.number("gps_horizontal_sigma", positive=True)
        self.gps_vertical_sigma = p.number("gps_vertical_sigma", positive=True)
        self.horizontal_speed_sigma = p.number("horizontal_speed_sigma", non_negative=True)
        self.filter = VerticalKalmanFilter(
            VerticalFilterConfig(
                accel_sigma=p.number("accel_sigma", positive=True),
                bias_sigma=p.number("baro_bias_sigma", positive=True),
                bias_random_walk=p.number("baro_bias_random_walk", non_negative=True),
                innovation_gate=p.number("innovation_gate", non_negative=True),
                max_rejections=p.integer("max_rejections", minimum=0),
            )
        )
        self.origin: GeodeticOrigin | None = None
        self._filter_ns: int | None = None
        self._vertical_acceleration = 0.0
        self._fix_ns: int | None = None
        self._position = (0.0, 0.0)
        self._position_variance = UNKNOWN_VARIANCE
        self._velocity = (0.0, 0.0)
        self._velocity_variance = UNKNOWN_VARIANCE

    def on_message(self, topic: str, msg: Any, now_ns: int) -> list[Output]:
        """Fuse one sample."""
        if topic == topics.IMU:
            return self._on_imu(msg)
        if topic == topics.PRESSURE:
            return self._on_pressure(msg)
        if topic == topics.GPS:
            self._on_gps(msg)
        return []

    def _advance(self, t_ns: int) -> None:
        """Predict the filter forward to ``t_ns`` (samples arriving late are fused as of now)."""
        if self._filter_ns is not None and t_ns > self._filter_ns:
            self.filter.predict((t_ns - self._filter_ns) / 1e9, self._vertical_acceleration)
        if self._filter_ns is None or t_ns > self._filter_ns:
            self._filter_ns = t_ns

    def _on_imu(self, msg: Any) -> list[Output]:
        t_ns = stamp_ns(msg.header.stamp)
        self._advance(t_ns)
        self._vertical_acceleration = _vertical_specific_force(msg) - self.gravity
        if not self.filter.initialized:
            return []
        return [(topics.ODOMETRY, self._odometry(msg, t_ns))]

    def _on_pressure(self, msg: Any) -> list[Output]:
        t_ns = stamp_ns(msg.header.stamp)
        pressure = self.pressure_filter(float(msg.fluid_pressure))
        altitude = pressure_altitude(pressure, p0=self.qnh)
        # Averaging n independent samples divides the noise variance by n.
        pressure_variance = (
            msg.variance if msg.variance > 0 else self.baro_sigma**2
        ) / self.pressure_filter.count
        variance = altitude_per_pascal(pressure, p0=self.qnh) ** 2 * pressure_variance
        self._advance(t_ns)
        if not self.filter.update_baro(altitude, variance):
            self.log(Severity.WARN, f"barometric altitude {altitude:.1f} m rejected as outlier")
        out = PoseWithCovarianceStamped()
        out.header.stamp = stamp(t_ns)
        out.header.frame_id = self.frame_id
        out.pose.pose.position.z = altitude
        covariance = [0.0] * 36
        for i in (0, 7, 21, 28, 35):
            covariance[i] = UNKNOWN_VARIANCE
        covariance[14] = variance
        out.pose.covariance = covariance
        return [(topics.BARO_ALTITUDE, out)]

    def _on_gps(self, msg: Any) -> None:
        t_ns = stamp_ns(msg.header.stamp)
        if msg.status.status < NavSatStatus.STATUS_FIX or not all(
            math.isfinite(v) for v in (msg.latitude, msg.longitude, msg.altitude)
        ):
            return
        known = msg.position_covariance_type != NavSatFix.COVARIANCE_TYPE_UNKNOWN
        cov = msg.position_covariance
        horizontal_variance = float(max(cov[0], cov[4])) if known else self.gps_horizontal_sigma**2
        vertical_variance = float(cov[8]) if known else self.gps_vertical_sigma**2
        if self.origin is None:
            self.origin = GeodeticOrigin(msg.latitude, msg.longitude)
            self.log(
                Severity.INFO,
                f"ENU origin at the first fix: {msg.latitude:.7f}, {msg.longitude:.7f}",
            )
        position = self.origin.to_enu(msg.latitude, msg.longitude)
        if self._fix_ns is not None and t_ns > self._fix_ns:
            dt = (t_ns - self._fix_ns) / 1e9
            self._velocity = (
                (position[0] - self._position[0]) / dt,
                (position[1] - self._position[1]) / dt,
            )
            self._velocity_variance = 2.0 * horizontal_variance / (dt * dt)
        self._position = position
        self._position_variance = horizontal_variance
        self._fix_ns = t_ns
        self._advance(t_ns)
        if not self.filter.update_gps(float(msg.altitude), vertical_variance):
            self.log(Severity.WARN, f"GPS altitude {msg.altitude:.1f} m rejected as outlier")

    def _odometry(self, imu: Any, t_ns: int) -> Odometry:
        # Fields are set in place: each nested message of a new Odometry exists already, and
        # building a replacement costs microseconds per sample.
        msg = Odometry()
        set_stamp(msg.header.stamp, t_ns)
        msg.header.frame_id = self.frame_id
        msg.child_frame_id = self.child_frame_id
        covariance_kf = self.filter.P
        pose = msg.pose
        pose.pose.position.x, pose.pose.position.y = self._position
        pose.pose.position.z = self.filter.altitude
        horizontal_variance = self._position_variance
        if self._fix_ns is not None and t_ns > self._fix_ns:
            # Without a fresh fix the horizontal position is a hold: its uncertainty grows.
            horizontal_variance += (self.horizontal_speed_sigma * (t_ns - self._fix_ns) / 1e9) ** 2
        covariance = [0.0] * 36
        covariance[0] = covariance[7] = horizontal_variance
        covariance[14] = float(covariance_kf[0, 0])
        orientation_covariance = _floats(imu.orientation_covariance)
        if orientation_covariance[0] >= 0:
            copy_quaternion(pose.pose.orientation, imu.orientation)
            _set_rotation_block(covariance, orientation_covariance)
        else:
            for i in (21, 28, 35):
                covariance[i] = UNKNOWN_VARIANCE
        pose.covariance = covariance
        # Odometry twists are in the body frame: rotate the ENU velocity by the inverse attitude.
        q = pose.pose.orientation
        vx, vy, vz = _rotate_inverse(
            (q.w, q.x, q.y, q.z), (*self._velocity, self.filter.vertical_velocity)
        )
        twist = msg.twist
        twist.twist.linear.x, twist.twist.linear.y, twist.twist.linear.z = vx, vy, vz
        copy_vector3(twist.twist.angular, imu.angular_velocity)
        twist_covariance = [0.0] * 36
        # Horizontal variances are equal on both axes, so a yaw rotation leaves them unchanged.
        twist_covariance[0] = twist_covariance[7] = self._velocity_variance
        twist_covariance[14] = float(covariance_kf[1, 1])
        _set_rotation_block(twist_covariance, _floats(imu.angular_velocity_covariance))
        twist.covariance = twist_covariance
        return msg


def _floats(values: Any) -> list[float]:
    """A message's float array (numpy in rclpy and rosbags, or any sequence) as a list."""
    return values.tolist() if hasattr(values, "tolist") else [float(v) for v in values]


def _set_rotation_block(covariance: list[float], block: list[float]) -> None:
    """Put a row-major 3x3 ``block`` into the rotation part of a row-major 6x6 covariance."""
    covariance[21:24] = block[0:3]
    covariance[27:30] = block[3:6]
    covariance[33:36] = block[6:9]


def _vertical_specific_force(imu: Any) -> float:
    """The ENU z component of the IMU's specific force (body z when no orientation is given)."""
    a = imu.linear_acceleration
    if imu.orientation_covariance[0] < 0:
        return float(a.z)
    q = imu.orientation
    return float(
        2.0 * (q.x * q.z - q.w * q.y) * a.x
        + 2.0 * (q.y * q.z + q.w * q.x) * a.y
        + (1.0 - 2.0 * (q.x * q.x + q.y * q.y)) * a.z
    )


def _rotate_inverse(
    q: tuple[float, float, float, float], v: tuple[float, float, float]
) -> tuple[float, float, float]:
    """Rotate ``v`` by the inverse of the unit quaternion ``q`` = (w, x, y, z): world to body."""
    w, x, y, z = q
    # R(q)^T v, with R the rotation matrix of q.
    r = (
        (1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)),
        (2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)),
        (2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)),
    )
    return (
        r[0][0] * v[0] + r[1][0] * v[1] + r[2][0] * v[2],
        r[0][1] * v[0] + r[1][1] * v[1] + r[2][1] * v[2],
        r[0][2] * v[0] + r[1][2] * v[1] + r[2][2] * v[2],
    )
