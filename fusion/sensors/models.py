"""Sensor error models with the magnitudes real parts show; every draw from one seeded Generator.

Each model turns true values into measured ones, one sample at a time, and knows the variance
it reports in its message.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, slots=True)
class ImuNoise:
    """MEMS IMU: white noise densities, bias random walks and turn-on bias spread."""

    accel_density: float = 4e-3  # m/s^2/sqrt(Hz)
    gyro_density: float = 3.4e-4  # rad/s/sqrt(Hz)
    accel_bias_random_walk: float = 2e-4  # m/s^2/sqrt(s)
    gyro_bias_random_walk: float = 2e-5  # rad/s/sqrt(s)
    accel_turn_on_bias: float = 0.01  # m/s^2, sigma
    gyro_turn_on_bias: float = 1e-3  # rad/s, sigma
    orientation_sigma: float = 0.01  # rad, per axis of the reported orientation


class ImuModel:
    """White noise with per-sample sigma = density * sqrt(rate), plus a random-walk bias."""

    def __init__(self, noise: ImuNoise, rate: float, rng: np.random.Generator) -> None:
        self.noise = noise
        self.rate = rate
        self.rng = rng
        self.accel_sigma = noise.accel_density * math.sqrt(rate)
        self.gyro_sigma = noise.gyro_density * math.sqrt(rate)
        self.accel_bias = rng.normal(0.0, noise.accel_turn_on_bias, 3)
        self.gyro_bias = rng.normal(0.0, noise.gyro_turn_on_bias, 3)

    def sample(
        self, accel: np.ndarray, gyro: np.ndarray, dt: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Measured specific force, angular rate and orientation error (roll, pitch, yaw)."""
        n = self.noise
        self.accel_bias = self.accel_bias + self.rng.normal(
            0.0, n.accel_bias_random_walk * math.sqrt(dt), 3
        )
        self.gyro_bias = self.gyro_bias + self.rng.normal(
            0.0, n.gyro_bias_random_walk * math.sqrt(dt), 3
        )
        measured_accel = accel + self.accel_bias + self.rng.normal(0.0, self.accel_sigma, 3)
        measured_gyro = gyro + self.gyro_bias + self.rng.normal(0.0, self.gyro_sigma, 3)
        attitude_error = self.rng.normal(0.0, n.orientation_sigma, 3)
        return measured_accel, measured_gyro, attitude_error


@dataclass(frozen=True, slots=True)
class GnssNoise:
    """Consumer GNSS: white noise plus a first-order Gauss-Markov bias per axis (metres)."""

    horizontal_white: float = 1.5
    horizontal_bias: float = 1.3
    vertical_white: float = 2.5
    vertical_bias: float = 1.6
    bias_time_constant: float = 60.0  # s

    @property
    def horizontal_sigma(self) -> float:
        """Total horizontal sigma per axis (m)."""
        return math.hypot(self.horizontal_white, self.horizontal_bias)

    @property
    def vertical_sigma(self) -> float:
        """Total vertical sigma (m)."""
        return math.hypot(self.vertical_white, self.vertical_bias)


class GnssModel:
    """Position error = slowly correlated bias (stationary Gauss-Markov) + white noise."""

    def __init__(self, noise: GnssNoise, rng: np.random.Generator) -> None:
        self.noise = noise
        self.rng = rng
        self._bias_sigma = np.array(
            [noise.horizontal_bias, noise.horizontal_bias, noise.vertical_bias]
        )
        self._white_sigma = np.array(
            [noise.horizontal_white, noise.horizontal_white, noise.vertical_white]
        )
        self.bias = rng.normal(0.0, 1.0, 3) * self._bias_sigma

    def sample(self, dt: float) -> np.ndarray:
        """Error (east, north, up) in metres of the next fix, ``dt`` seconds after the last."""
        phi = math.exp(-dt / self.noise.bias_time_constant)
        self.bias = phi * self.bias + math.sqrt(1.0 - phi * phi) * self._bias_sigma * (
            self.rng.normal(0.0, 1.0, 3)
        )
        return self.bias + self.rng.normal(0.0, 1.0, 3) * self._white_sigma


class BarometerModel:
    """Pressure = truth + offset + random-walk drift + white noise (Pa)."""

    def __init__(
        self,
        *,
        white_sigma: float,
        drift_random_walk: float,
        offset: float,
        rng: np.random.Generator,
    ) -> None:
        self.white_sigma = white_sigma
        self.drift_random_walk = drift_random_walk
        self.offset = offset
        self.rng = rng
        self.drift = 0.0

    def sample(self, pressure: float, dt: float) -> float:
        """Measured pressure for a true ``pressure``, ``dt`` seconds after the last sample."""
        self.drift += float(self.rng.normal(0.0, self.drift_random_walk * math.sqrt(dt)))
        return pressure + self.offset + self.drift + float(self.rng.normal(0.0, self.white_sigma))


class ThermometerModel:
    """Temperature = truth + fixed offset + white noise (degrees Celsius)."""

    def __init__(self, *, white_sigma: float, offset: float, rng: np.random.Generator) -> None:
        self.white_sigma = white_sigma
        self.offset = offset
        self.rng = rng

    def sample(self, temperature: float) -> float:
        """Measured temperature for a true ``temperature``."""
        return temperature + self.offset + float(self.rng.normal(0.0, self.white_sigma))
