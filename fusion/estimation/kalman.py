"""Vertical-channel Kalman filter: altitude, vertical velocity and barometer bias.

Predicts with the IMU's vertical specific force minus gravity; updates with barometric altitude
(which measures altitude + bias) and GPS altitude (which measures altitude). The bias absorbs the
barometer's offset and drift, so the fused altitude keeps the barometer's short-term precision
and GPS's absolute reference.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

_BARO_H = np.array([1.0, 0.0, 1.0])
_GPS_H = np.array([1.0, 0.0, 0.0])


@dataclass(frozen=True, slots=True)
class VerticalFilterConfig:
    """Noise model of the filter.

    Attributes:
        accel_sigma: white acceleration noise driving the prediction (m/s^2), covering IMU
            noise, its bias and attitude error.
        bias_sigma: prior uncertainty of the barometer bias (m).
        bias_random_walk: barometer bias drift (m/sqrt(s)).
        velocity_sigma: prior uncertainty of the vertical velocity (m/s).
        innovation_gate: a measurement further than this many sigmas from the prediction is
            rejected as an outlier (0 disables the gate).
        max_rejections: after this many consecutive rejections of one source the next
            measurement is accepted anyway, so a diverged filter recovers.
    """

    accel_sigma: float = 0.3
    bias_sigma: float = 10.0
    bias_random_walk: float = 0.01
    velocity_sigma: float = 1.0
    innovation_gate: float = 5.0
    max_rejections: int = 6


class VerticalKalmanFilter:
    """State ``[altitude, vertical velocity, baro bias]``; uninitialized until a measurement."""

    def __init__(self, config: VerticalFilterConfig) -> None:
        self.config = config
        self.x = np.zeros(3)
        self.P = np.zeros((3, 3))
        self.initialized = False
        self._rejections = {"baro": 0, "gps": 0}

    @property
    def altitude(self) -> float:
        """Estimated altitude (m)."""
        return float(self.x[0])

    @property
    def vertical_velocity(self) -> float:
        """Estimated vertical velocity (m/s)."""
        return float(self.x[1])

    @property
    def baro_bias(self) -> float:
        """Estimated barometric altitude bias (m)."""
        return float(self.x[2])

    def predict(self, dt: float, vertical_acceleration: float) -> None:
        """Propagate by ``dt`` seconds under a vertical acceleration (m/s^2, up positive)."""
        if not self.initialized or dt <= 0:
            return
        c = self.config
        # x' = F x + B a and P' = F P F^T + B B^T accel_sigma^2 + diag(0, 0, bias walk^2 dt) with
        # F = [[1, dt, 0], [0, 1, 0], [0, 0, 1]], B = [dt^2 / 2, dt, 0], written out: this runs
        # for every IMU sample and 3x3 numpy products cost more in call overhead than in math.
        (h, v, b), p = self.x.tolist(), self.P.tolist()
        half_dt2 = 0.5 * dt * dt
        q = c.accel_sigma**2
        self.x = np.array(
            [h + dt * v + half_dt2 * vertical_acceleration, v + dt * vertical_acceleration, b]
        )
        # F P: row 0 gains dt times row 1; (F P) F^T: column 0 gains dt times column 1.
        r0 = [p[0][0] + dt * p[1][0], p[0][1] + dt * p[1][1], p[0][2] + dt * p[1][2]]
        r1, r2 = p[1], p[2]
        self.P = np.array(
            [
                [r0[0] + dt * r0[1] + half_dt2 * half_dt2 * q, r0[1] + half_dt2 * dt * q, r0[2]],
                [r1[0] + dt * r1[1] + dt * half_dt2 * q, r1[1] + dt * dt * q, r1[2]],
                [r2[0] + dt * r2[1], r2[1], r2[2] + c.bias_random_walk**2 * dt],
            ]
        )

    def update_baro(self, altitude: float, variance: float) -> bool:
        """Fuse a barometric altitude; returns False when it was rejected as an outlier."""
        if not self.initialized:
            # The first altitude comes from the barometer with the prior bias: h = z - b.
            b_var = self.config.bias_sigma**2
            self.x = np.array([altitude, 0.0, 0.0])
            self.P = np.array(
                [
                    [variance + b_var, 0.0, -b_var],
                    [0.0, self.config.velocity_sigma**2, 0.0],
                    [-b_var, 0.0, b_var],
                ]
            )
            self.initialized = True
            return True
        return self._update("baro", _BARO_H, altitude, variance)

    def update_gps(self, altitude: float, variance: float) -> bool:
        """Fuse a GPS altitude; returns False when it was rejected as an outlier."""
        if not self.initialized:
            self.x = np.array([altitude, 0.0, 0.0])
            self.P = np.diag([variance, self.config.velocity_sigma**2, self.config.bias_sigma**2])
            self.initialized = True
            return True
        return self._update("gps", _GPS_H, altitude, variance)

    def _update(self, source: str, h: np.ndarray, z: float, variance: float) -> bool:
        innovation = z - float(h @ self.x)
        s = float(h @ self.P @ h) + variance
        gate = self.config.innovation_gate
        if gate > 0 and innovation * innovation > gate * gate * s:
            self._rejections[source] += 1
            if self._rejections[source] <= self.config.max_rejections:
                return False
        self._rejections[source] = 0
        gain = self.P @ h / s
        self.x = self.x + gain * innovation
        # Joseph form: stays symmetric positive semi-definite under rounding.
        a = np.eye(3) - np.outer(gain, h)
        self.P = a @ self.P @ a.T + np.outer(gain, gain) * variance
        return True
