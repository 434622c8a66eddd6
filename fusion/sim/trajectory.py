"""A closed-form flight: orbit a point while taking off, cruising and landing.

The vehicle orbits a centre at constant ground speed (heading along the track, level attitude),
with a vertical profile of ground time, climb, cruise, descent and ground time again, optionally
repeated. Climb and descent follow half a cosine, so altitude, vertical velocity and vertical
acceleration are analytic and the IMU, GPS and barometer all describe the same motion.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

STANDARD_GRAVITY = 9.80665


@dataclass(frozen=True, slots=True)
class FlightProfile:
    """Parameters of the simulated flight (SI units, seconds from the start)."""

    ground_altitude: float = 488.0
    cruise_height: float = 120.0
    takeoff_delay: float = 3.0
    climb_duration: float = 30.0
    cruise_duration: float = 30.0
    descent_duration: float = 30.0
    ground_duration: float = 5.0
    ground_speed: float = 5.0
    orbit_radius: float = 60.0
    loop: bool = True

    @property
    def period(self) -> float:
        """Length of one take-off-to-landing cycle in seconds."""
        return (
            self.takeoff_delay
            + self.climb_duration
            + self.cruise_duration
            + self.descent_duration
            + self.ground_duration
        )


@dataclass(frozen=True, slots=True)
class TrajectoryState:
    """The true state at one instant: local ENU position from the start point, MSL altitude."""

    east: float
    north: float
    altitude: float
    vertical_velocity: float
    vertical_acceleration: float
    yaw: float
    yaw_rate: float
    velocity_east: float
    velocity_north: float
    centripetal_acceleration: float


def _vertical(profile: FlightProfile, t: float) -> tuple[float, float, float]:
    """Height above ground, vertical velocity and acceleration at ``t`` seconds."""
    if profile.loop:
        t = math.fmod(t, profile.period)
    height = profile.cruise_height
    t_climb = t - profile.takeoff_delay
    t_descent = t_climb - profile.climb_duration - profile.cruise_duration
    if t_climb <= 0:
        return 0.0, 0.0, 0.0
    if t_climb < profile.climb_duration:
        return _half_cosine(height, profile.climb_duration, t_climb)
    if t_descent <= 0:
        return height, 0.0, 0.0
    if t_descent < profile.descent_duration:
        h, v, a = _half_cosine(height, profile.descent_duration, t_descent)
        return height - h, -v, -a
    return 0.0, 0.0, 0.0


def _half_cosine(height: float, duration: float, t: float) -> tuple[float, float, float]:
    w = math.pi / duration
    return (
        height * (1.0 - math.cos(w * t)) / 2.0,
        height * w * math.sin(w * t) / 2.0,
        height * w * w * math.cos(w * t) / 2.0,
    )


def trajectory_state(profile: FlightProfile, t: float) -> TrajectoryState:
    """The true state ``t`` seconds after the start (``t`` >= 0)."""
    height, v_up, a_up = _vertical(profile, t)
    omega = profile.ground_speed / profile.orbit_radius
    theta = omega * t
    # Counter-clockwise orbit starting at the origin, centre to the west.
    east = profile.orbit_radius * (math.cos(theta) - 1.0)
    north = profile.orbit_radius * math.sin(theta)
    return TrajectoryState(
        east=east,
        north=north,
        altitude=profile.ground_altitude + height,
        vertical_velocity=v_up,
        vertical_acceleration=a_up,
        yaw=math.remainder(theta + math.pi / 2.0, math.tau),
        yaw_rate=omega,
        velocity_east=-profile.ground_speed * math.sin(theta),
        velocity_north=profile.ground_speed * math.cos(theta),
        centripetal_acceleration=profile.ground_speed * omega,
    )
