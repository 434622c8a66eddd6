"""Noise statistics of the sensor models over many samples against the configured sigmas."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fusion.sensors import (
    BarometerModel,
    GnssModel,
    GnssNoise,
    ImuModel,
    ImuNoise,
    ThermometerModel,
)

N = 20_000


def test_imu_white_noise_sigma_is_density_times_sqrt_rate() -> None:
    noise = ImuNoise(
        accel_bias_random_walk=0.0,
        gyro_bias_random_walk=0.0,
        accel_turn_on_bias=0.0,
        gyro_turn_on_bias=0.0,
    )
    model = ImuModel(noise, rate=100.0, rng=np.random.default_rng(1))
    truth_accel = np.array([0.0, 0.5, 9.81])
    samples = [model.sample(truth_accel, np.zeros(3), 0.01) for _ in range(N)]
    accel = np.array([s[0] for s in samples]) - truth_accel
    gyro = np.array([s[1] for s in samples])
    assert model.accel_sigma == pytest.approx(4e-3 * 10.0)
    # Sample std of N normal draws is within 3 % of sigma with overwhelming probability.
    np.testing.assert_allclose(accel.std(axis=0), model.accel_sigma, rtol=0.03)
    np.testing.assert_allclose(gyro.std(axis=0), 3.4e-4 * 10.0, rtol=0.03)
    np.testing.assert_allclose(accel.mean(axis=0), 0.0, atol=4 * model.accel_sigma / math.sqrt(N))


def test_imu_bias_is_a_random_walk() -> None:
    noise = ImuNoise(accel_density=0.0, gyro_density=0.0, accel_turn_on_bias=0.0)
    model = ImuModel(noise, rate=10.0, rng=np.random.default_rng(2))
    accel = np.array([model.sample(np.zeros(3), np.zeros(3), 0.1)[0] for _ in range(N)])
    steps = np.diff(accel, axis=0)
    np.testing.assert_allclose(steps.std(axis=0), 2e-4 * math.sqrt(0.1), rtol=0.03)


def test_gnss_error_has_configured_sigma_and_is_correlated() -> None:
    noise = GnssNoise()
    model = GnssModel(noise, np.random.default_rng(3))
    errors = np.array([model.sample(1.0) for _ in range(100_000)])
    # 100k s at a 60 s correlation time: ~800 independent bias values, so 10 % is generous.
    np.testing.assert_allclose(
        errors.std(axis=0),
        [noise.horizontal_sigma, noise.horizontal_sigma, noise.vertical_sigma],
        rtol=0.1,
    )
    # Lag-1 autocorrelation: bias variance share times exp(-1/tau), far from white noise's 0.
    up = errors[:, 2] - errors[:, 2].mean()
    lag1 = float(np.dot(up[1:], up[:-1]) / np.dot(up, up))
    expected = noise.vertical_bias**2 / noise.vertical_sigma**2 * math.exp(-1 / 60)
    assert lag1 == pytest.approx(expected, abs=0.05)
    assert 2.0 <= noise.vertical_sigma <= 4.0


def test_barometer_white_noise_and_drift() -> None:
    white = BarometerModel(
        white_sigma=2.0, drift_random_walk=0.0, offset=30.0, rng=np.random.default_rng(4)
    )
    samples = np.array([white.sample(95000.0, 0.5) for _ in range(N)])
    assert samples.std() == pytest.approx(2.0, rel=0.03)
    assert samples.mean() == pytest.approx(95030.0, abs=0.1)
    drifting = BarometerModel(
        white_sigma=0.0, drift_random_walk=0.05, offset=0.0, rng=np.random.default_rng(5)
    )
    steps = np.diff([drifting.sample(95000.0, 0.5) for _ in range(N)])
    assert steps.std() == pytest.approx(0.05 * math.sqrt(0.5), rel=0.03)


def test_thermometer_offset_and_noise() -> None:
    model = ThermometerModel(white_sigma=0.05, offset=0.3, rng=np.random.default_rng(6))
    samples = np.array([model.sample(15.0) for _ in range(N)])
    assert samples.mean() == pytest.approx(15.3, abs=0.005)
    assert samples.std() == pytest.approx(0.05, rel=0.03)
