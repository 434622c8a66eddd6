"""sensor_publisher: the simulated flight measured by IMU, GPS, thermometer and barometer."""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
from geometry_msgs.msg import Vector3
from nav_msgs.msg import Odometry
from sensor_msgs.msg import FluidPressure, Imu, NavSatFix, NavSatStatus, Temperature

from bagkit.regression import Output
from fusion import topics
from fusion.estimation import GeodeticOrigin, pressure_at_altitude
from fusion.faults import SENSORS, FaultKind, FaultSchedule
from fusion.params import Params
from fusion.processors.base import ProcessorBase, Severity
from fusion.processors.messages import quaternion_from_euler, stamp
from fusion.sensors import (
    BarometerModel,
    GnssModel,
    GnssNoise,
    ImuModel,
    ImuNoise,
    ThermometerModel,
)
from fusion.sim import FlightProfile, TrajectoryState, trajectory_state
from fusion.sim.trajectory import STANDARD_GRAVITY

PARAMETER_DESCRIPTIONS: dict[str, str] = {
    "seed": "Seed of the noise generators: the same seed gives the same measurements.",
    "frame_id": "frame_id of the IMU, barometer and thermometer messages (the body frame).",
    "gps_frame_id": "frame_id of the GPS fixes (the antenna).",
    "publish_truth": "Publish the simulated ground truth on /sim/truth (nav_msgs/Odometry).",
    "rates.imu": "IMU rate (Hz) on /imu/data.",
    "rates.gps": "GPS rate (Hz) on /gps/fix.",
    "rates.temperature": "Thermometer rate (Hz) on /temperature.",
    "rates.pressure": "Barometer rate (Hz) on /barometer/pressure.",
    "faults": "Fault schedule: 'KIND@START+DURATION[=MAGNITUDE], ...' in seconds since start; "
    "kinds temperature_spike (C), pressure_spike (Pa), gps_loss, imu_stuck, dropout:SENSOR "
    "(imu, gps, temperature, pressure: silent). Empty: no faults.",
    "fault_period": "Repeat the fault schedule every this many seconds (0: run it once).",
    "flight.latitude": "Latitude (deg) of the take-off point.",
    "flight.longitude": "Longitude (deg) of the take-off point.",
    "flight.ground_altitude": "Altitude (m above mean sea level) of the take-off point.",
    "flight.cruise_height": "Cruise height (m) above the take-off point.",
    "flight.takeoff_delay": "Seconds on the ground before the climb.",
    "flight.climb_duration": "Seconds from take-off to cruise height.",
    "flight.cruise_duration": "Seconds at cruise height.",
    "flight.descent_duration": "Seconds from cruise height to touch-down.",
    "flight.ground_duration": "Seconds on the ground after landing, before the next cycle.",
    "flight.ground_speed": "Horizontal speed (m/s) along the circular orbit.",
    "flight.orbit_radius": "Radius (m) of the orbit.",
    "flight.loop": "Repeat the flight forever (false: stay on the ground after landing).",
    "atmosphere.qnh": "Sea-level pressure (Pa) of the simulated atmosphere.",
    "atmosphere.ground_temperature": "Air temperature (C) at the take-off point.",
    "atmosphere.lapse_rate": "Temperature lapse rate (C/m).",
    "imu.accel_density": "Accelerometer white noise density (m/s^2/sqrt(Hz)).",
    "imu.gyro_density": "Gyroscope white noise density (rad/s/sqrt(Hz)).",
    "imu.accel_bias_random_walk": "Accelerometer bias random walk (m/s^2/sqrt(s)).",
    "imu.gyro_bias_random_walk": "Gyroscope bias random walk (rad/s/sqrt(s)).",
    "imu.accel_turn_on_bias": "Sigma of the accelerometer bias at start (m/s^2).",
    "imu.gyro_turn_on_bias": "Sigma of the gyroscope bias at start (rad/s).",
    "imu.orientation_sigma": "Sigma (rad) of the reported orientation per axis.",
    "gps.horizontal_white": "GPS horizontal white noise per axis (m).",
    "gps.horizontal_bias": "GPS horizontal correlated (Gauss-Markov) error per axis (m).",
    "gps.vertical_white": "GPS vertical white noise (m).",
    "gps.vertical_bias": "GPS vertical correlated (Gauss-Markov) error (m).",
    "gps.bias_time_constant": "Correlation time (s) of the GPS error.",
    "barometer.white_sigma": "Barometer white noise (Pa).",
    "barometer.drift_random_walk": "Barometer drift random walk (Pa/sqrt(s)).",
    "barometer.offset": "Barometer constant offset (Pa).",
    "thermometer.white_sigma": "Thermometer white noise (C).",
    "thermometer.offset": "Thermometer constant offset (C).",
}

_SENSORS = SENSORS


def _diagonal(a: float, b: float, c: float) -> list[float]:
    return [a, 0.0, 0.0, 0.0, b, 0.0, 0.0, 0.0, c]


class SensorPublisher(ProcessorBase):
    """Samples the flight on a timer; every sensor due at ``now_ns`` publishes, stamped now."""

    output_topics = (topics.IMU, topics.GPS, topics.TEMPERATURE, topics.PRESSURE, topics.TRUTH)

    def __init__(self, params: Mapping[str, object] | None = None) -> None:
        super().__init__()
        p = Params("sensor_publisher", params)
        self.frame_id = p.text("frame_id")
        self.gps_frame_id = p.text("gps_frame_id")
        self.publish_truth = p.flag("publish_truth")
        self.periods_ns = {
            name: round(1e9 / p.number(f"rates.{name}", positive=True)) for name in _SENSORS
        }
        self.tick_ns = min(self.periods_ns.values())
        self.timer_period_ns = self.tick_ns
        self.faults = FaultSchedule.parse(
            p.text("faults"), period=p.number("fault_period", non_negative=True)
        )
        self.profile = _flight_profile(p)
        self.origin = GeodeticOrigin(p.number("flight.latitude"), p.number("flight.longitude"))
        self.qnh = p.number("atmosphere.qnh", positive=True)
        self.ground_temperature = p.number("atmosphere.ground_temperature")
        self.lapse_rate = p.number("atmosphere.lapse_rate")
        # One independent stream per sensor: changing one sensor's rate leaves the others'
        # noise sequences untouched.
        imu_rng, gps_rng, baro_rng, temp_rng = (
            np.random.default_rng(s) for s in np.random.SeedSequence(p.integer("seed")).spawn(4)
        )
        self.imu = ImuModel(
            ImuNoise(
                **{
                    name: p.number(f"imu.{name}", non_negative=True)
                    for name in ImuNoise.__dataclass_fields__
                }
            ),
            rate=1e9 / self.periods_ns["imu"],
            rng=imu_rng,
        )
        self.gnss = GnssModel(_gnss_noise(p), gps_rng)
        self.barometer = BarometerModel(
            white_sigma=p.number("barometer.white_sigma", non_negative=True),
            drift_random_walk=p.number("barometer.drift_random_walk", non_negative=True),
            offset=p.number("barometer.offset"),
            rng=baro_rng,
        )
        self.thermometer = ThermometerModel(
            white_sigma=p.number("thermometer.white_sigma", non_negative=True),
            offset=p.number("thermometer.offset"),
            rng=temp_rng,
        )
        self._start_ns: int | None = None
        self._next_due_ns: dict[str, int] = {}
        self._last_sample_ns: dict[str, int] = {}
        self._last_imu: Imu | None = None
        self._active_faults: set[str] = set()

    def on_timer(self, now_ns: int) -> list[Output]:
        """Publish every sensor whose next sample is due."""
        if self._start_ns is None:
            self._start_ns = now_ns
            self._next_due_ns = dict.fromkeys(_SENSORS, now_ns)
        t = (now_ns - self._start_ns) / 1e9
        self._log_fault_changes(t)
        state = trajectory_state(self.profile, t)
        # The schedule is anchored at the first tick, which may itself have fired a little
        # late: a tenth of a tick of tolerance keeps slower sensors on the tick of their due
        # time instead of slipping a whole tick, without sampling early on a coarse sim clock.
        tolerance = self.tick_ns // 10
        out: list[Output] = []
        for name in _SENSORS:
            due = self._next_due_ns[name]
            if now_ns < due - tolerance:
                continue
            period = self.periods_ns[name]
            # Late by more than a period (a starved timer, a jump of the sim clock): skip the
            # missed samples but stay in phase with the original schedule.
            self._next_due_ns[name] = due + period * max(1, (now_ns - due) // period + 1)
            if self.faults.active(FaultKind.DROPOUT, t, name):
                continue  # silent: the next sample's noise covers the gap (its dt)
            dt = (now_ns - self._last_sample_ns.get(name, now_ns - period)) / 1e9
            self._last_sample_ns[name] = now_ns
            out += self._sample(name, state, t, now_ns, max(dt, 1e-9))
        return out

    def _sample(
        self, name: str, state: TrajectoryState, t: float, now_ns: int, dt: float
    ) -> list[Output]:
        if name == "imu":
            outputs: list[Output] = [(topics.IMU, self._imu(state, t, now_ns, dt))]
            if self.publish_truth:
                outputs.append((topics.TRUTH, self._truth(state, now_ns)))
            return outputs
        if name == "gps":
            return [(topics.GPS, self._gps(state, t, now_ns, dt))]
        if name == "pressure":
            return [(topics.PRESSURE, self._pressure(state, t, now_ns, dt))]
        return [(topics.TEMPERATURE, self._temperature(state, t, now_ns))]

    def _log_fault_changes(self, t: float) -> None:
        active = {fault.label for fault in self.faults.active_faults(t)}
        for label in sorted(active - self._active_faults):
            self.log(Severity.INFO, f"fault injected: {label} at t={t:.1f} s")
        for label in sorted(self._active_faults - active):
            self.log(Severity.INFO, f"fault cleared: {label} at t={t:.1f} s")
        self._active_faults = active

    def _imu(self, state: TrajectoryState, t: float, now_ns: int, dt: float) -> Imu:
        # Level flight with the nose along the track: the centripetal acceleration points to
        # body +y (left), gravity's reaction to body +z (REP 145: +g on z at rest).
        accel = np.array(
            [0.0, state.centripetal_acceleration, state.vertical_acceleration + STANDARD_GRAVITY]
        )
        gyro = np.array([0.0, 0.0, state.yaw_rate])
        measured_accel, measured_gyro, attitude_error = self.imu.sample(accel, gyro, dt)
        msg = Imu()
        msg.header.stamp = stamp(now_ns)
        msg.header.frame_id = self.frame_id
        if self._last_imu is not None and self.faults.active(FaultKind.IMU_STUCK, t):
            msg.orientation = self._last_imu.orientation
            msg.angular_velocity = self._last_imu.angular_velocity
            msg.linear_acceleration = self._last_imu.linear_acceleration
        else:
            msg.orientation = quaternion_from_euler(
                float(attitude_error[0]),
                float(attitude_error[1]),
                state.yaw + float(attitude_error[2]),
            )
            msg.angular_velocity = Vector3(
                x=float(measured_gyro[0]), y=float(measured_gyro[1]), z=float(measured_gyro[2])
            )
            msg.linear_acceleration = Vector3(
                x=float(measured_accel[0]), y=float(measured_accel[1]), z=float(measured_accel[2])
            )
        var_o = self.imu.noise.orientation_sigma**2
        var_g = self.imu.gyro_sigma**2
        var_a = self.imu.accel_sigma**2
        msg.orientation_covariance = _diagonal(var_o, var_o, var_o)
        msg.angular_velocity_covariance = _diagonal(var_g, var_g, var_g)
        msg.linear_acceleration_covariance = _diagonal(var_a, var_a, var_a)
        self._last_imu = msg
        return msg

    def _gps(self, state: TrajectoryState, t: float, now_ns: int, dt: float) -> NavSatFix:
        error = self.gnss.sample(dt)
        msg = NavSatFix()
        msg.header.stamp = stamp(now_ns)
        msg.header.frame_id = self.gps_frame_id
        msg.status.service = NavSatStatus.SERVICE_GPS
        if self.faults.active(FaultKind.GPS_LOSS, t):
            msg.status.status = NavSatStatus.STATUS_NO_FIX
            msg.latitude = msg.longitude = msg.altitude = math.nan
            msg.position_covariance_type = NavSatFix.COVARIANCE_TYPE_UNKNOWN
            return msg
        msg.status.status = NavSatStatus.STATUS_FIX
        msg.latitude, msg.longitude = self.origin.to_geodetic(
            state.east + float(error[0]), state.north + float(error[1])
        )
        msg.altitude = state.altitude + float(error[2])
        var_h = self.gnss.noise.horizontal_sigma**2
        msg.position_covariance = _diagonal(var_h, var_h, self.gnss.noise.vertical_sigma**2)
        msg.position_covariance_type = NavSatFix.COVARIANCE_TYPE_DIAGONAL_KNOWN
        return msg

    def _pressure(self, state: TrajectoryState, t: float, now_ns: int, dt: float) -> FluidPressure:
        pressure = self.barometer.sample(pressure_at_altitude(state.altitude, p0=self.qnh), dt)
        spike = self.faults.active(FaultKind.PRESSURE_SPIKE, t)
        msg = FluidPressure()
        msg.header.stamp = stamp(now_ns)
        msg.header.frame_id = self.frame_id
        msg.fluid_pressure = pressure + (spike.magnitude if spike else 0.0)
        msg.variance = self.barometer.white_sigma**2
        return msg

    def _temperature(self, state: TrajectoryState, t: float, now_ns: int) -> Temperature:
        height = state.altitude - self.profile.ground_altitude
        temperature = self.thermometer.sample(self.ground_temperature - self.lapse_rate * height)
        spike = self.faults.active(FaultKind.TEMPERATURE_SPIKE, t)
        msg = Temperature()
        msg.header.stamp = stamp(now_ns)
        msg.header.frame_id = self.frame_id
        msg.temperature = temperature + (spike.magnitude if spike else 0.0)
        msg.variance = self.thermometer.white_sigma**2
        return msg

    def _truth(self, state: TrajectoryState, now_ns: int) -> Odometry:
        msg = Odometry()
        msg.header.stamp = stamp(now_ns)
        msg.header.frame_id = "map"
        msg.child_frame_id = self.frame_id
        msg.pose.pose.position.x = state.east
        msg.pose.pose.position.y = state.north
        msg.pose.pose.position.z = state.altitude
        msg.pose.pose.orientation = quaternion_from_euler(0.0, 0.0, state.yaw)
        # Twist in the body frame, as Odometry specifies: forward along the track, up.
        msg.twist.twist.linear.x = self.profile.ground_speed
        msg.twist.twist.linear.z = state.vertical_velocity
        msg.twist.twist.angular.z = state.yaw_rate
        return msg


def _flight_profile(p: Params) -> FlightProfile:
    """The simulated flight from the ``flight.*`` parameters."""
    return FlightProfile(
        ground_altitude=p.number("flight.ground_altitude"),
        cruise_height=p.number("flight.cruise_height", non_negative=True),
        takeoff_delay=p.number("flight.takeoff_delay", non_negative=True),
        climb_duration=p.number("flight.climb_duration", positive=True),
        cruise_duration=p.number("flight.cruise_duration", non_negative=True),
        descent_duration=p.number("flight.descent_duration", positive=True),
        ground_duration=p.number("flight.ground_duration", non_negative=True),
        ground_speed=p.number("flight.ground_speed", non_negative=True),
        orbit_radius=p.number("flight.orbit_radius", positive=True),
        loop=p.flag("flight.loop"),
    )


def _gnss_noise(p: Params) -> GnssNoise:
    """The GPS receiver's noise from the ``gps.*`` parameters."""
    return GnssNoise(
        horizontal_white=p.number("gps.horizontal_white", non_negative=True),
        horizontal_bias=p.number("gps.horizontal_bias", non_negative=True),
        vertical_white=p.number("gps.vertical_white", non_negative=True),
        vertical_bias=p.number("gps.vertical_bias", non_negative=True),
        bias_time_constant=p.number("gps.bias_time_constant", positive=True),
    )
