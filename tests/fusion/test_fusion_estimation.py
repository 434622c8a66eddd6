"""The vertical Kalman filter converges on a simulated climb and beats each raw sensor."""

from __future__ import annotations

import math

import numpy as np
import pytest
from fusion_loop import LoopResult, altitude_errors, rms, run_loop

from fusion import topics
from fusion.estimation import MovingAverage, VerticalFilterConfig, VerticalKalmanFilter
from fusion.sim import FlightProfile, trajectory_state

G = 9.80665


def test_filter_tracks_a_climb_from_exact_inputs() -> None:
    """Noise-free accelerations, a biased barometer and an exact GPS: the bias is learned."""
    profile = FlightProfile()
    kf = VerticalKalmanFilter(VerticalFilterConfig(accel_sigma=0.05))
    baro_bias = 7.0
    dt = 0.1
    for k in range(1, 600):
        t = k * dt
        state = trajectory_state(profile, t)
        kf.predict(dt, state.vertical_acceleration)
        if k % 5 == 0:
            kf.update_baro(state.altitude + baro_bias, 0.2**2)
        if k % 10 == 0:
            kf.update_gps(state.altitude, 3.0**2)
    truth = trajectory_state(profile, 599 * dt)
    assert kf.altitude == pytest.approx(truth.altitude, abs=0.3)
    assert kf.vertical_velocity == pytest.approx(truth.vertical_velocity, abs=0.1)
    assert kf.baro_bias == pytest.approx(baro_bias, abs=0.3)
    assert kf.P[0, 0] > 0 and np.allclose(kf.P, kf.P.T)


def test_outliers_are_gated_then_accepted_after_max_rejections() -> None:
    kf = VerticalKalmanFilter(VerticalFilterConfig(innovation_gate=5.0, max_rejections=2))
    kf.update_baro(500.0, 0.04)
    assert not kf.update_baro(-700.0, 0.04)
    assert not kf.update_baro(-700.0, 0.04)
    assert kf.altitude == pytest.approx(500.0)
    assert kf.update_baro(-700.0, 0.04)  # a third one in a row: the world changed


def test_fused_altitude_converges_in_closed_loop_and_beats_raw_sensors() -> None:
    """Default noise on a 120 s flight (climb, cruise, descent), faults included.

    Stated accuracy after 10 s of convergence: fused RMS error below 2 m, below the GPS's
    and the barometer's own RMS errors.
    """
    result = run_loop(120.0)
    errors = altitude_errors(result, after_s=10.0)
    fused, gps = rms(errors["fused"]), rms(errors["gps"])
    # The pressure spike is an outlier the filter rejects; score the raw barometer without it.
    baro = rms([e for e in errors["baro"] if abs(e) < 100.0])
    assert len(errors["fused"]) == 1100
    assert fused < 2.0
    assert fused < gps
    assert fused < baro
    rejected = [line.text for line in result.logs["sensor_fusion"] if "rejected" in line.text]
    assert len(rejected) == 3  # the 1.5 s pressure spike at 2 Hz


def test_moving_average_option_smooths_pressure() -> None:
    params = {"sensor_publisher": {"faults": ""}}
    raw = run_loop(30.0, params, nodes=("sensor_publisher", "sensor_fusion"))
    params["sensor_fusion"] = {"moving_average_window": 4}
    smooth = run_loop(30.0, params, nodes=("sensor_publisher", "sensor_fusion"))

    def jitter(result: LoopResult) -> float:
        z = [m.pose.pose.position.z for m in result.messages(topics.BARO_ALTITUDE)]
        return float(np.std(np.diff(z, n=2)))

    assert jitter(smooth) < 0.6 * jitter(raw)


def test_moving_average() -> None:
    average = MovingAverage(3)
    assert [average(v) for v in (3.0, 6.0, 9.0, 12.0)] == [3.0, 4.5, 6.0, 9.0]
    assert average.count == 3
    with pytest.raises(ValueError):
        MovingAverage(0)
    assert math.isclose(MovingAverage(1)(2.5), 2.5)
