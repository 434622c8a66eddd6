"""The simulated flight is self-consistent; fault schedules parse and switch on time."""

from __future__ import annotations

import pytest

from fusion.errors import FaultScheduleError
from fusion.faults import FaultKind, FaultSchedule
from fusion.sim import FlightProfile, trajectory_state


@pytest.mark.parametrize("t", [3.5, 10.0, 17.9, 32.0, 70.0, 80.0, 92.5])
def test_derivatives_match_finite_differences(t: float) -> None:
    profile = FlightProfile()
    dt = 1e-4
    before, at, after = (trajectory_state(profile, t + k * dt) for k in (-1, 0, 1))
    assert at.vertical_velocity == pytest.approx(
        (after.altitude - before.altitude) / (2 * dt), abs=1e-5
    )
    assert at.vertical_acceleration == pytest.approx(
        (after.vertical_velocity - before.vertical_velocity) / (2 * dt), abs=1e-5
    )
    assert at.velocity_east == pytest.approx((after.east - before.east) / (2 * dt), abs=1e-5)
    assert at.velocity_north == pytest.approx((after.north - before.north) / (2 * dt), abs=1e-5)


def test_take_off_climb_cruise_descent_and_loop() -> None:
    profile = FlightProfile(ground_altitude=300.0, cruise_height=120.0)
    ground = profile.ground_altitude
    assert trajectory_state(profile, 0.0).altitude == ground
    assert trajectory_state(profile, 0.0).east == 0.0
    top_of_climb = profile.takeoff_delay + profile.climb_duration
    assert trajectory_state(profile, top_of_climb).altitude == pytest.approx(ground + 120.0)
    assert trajectory_state(profile, top_of_climb + 10).vertical_velocity == 0.0
    landed = top_of_climb + profile.cruise_duration + profile.descent_duration
    assert trajectory_state(profile, landed + 1).altitude == ground
    t = 20.0
    assert trajectory_state(profile, t + profile.period).altitude == pytest.approx(
        trajectory_state(profile, t).altitude
    )
    once = FlightProfile(loop=False)
    assert trajectory_state(once, t + once.period).altitude == once.ground_altitude


def test_fault_schedule_parses_and_activates() -> None:
    schedule = FaultSchedule.parse("temperature_spike@6+2=40, gps_loss @ 12 + 4, imu_stuck@1e1+.5")
    spike = schedule.active(FaultKind.TEMPERATURE_SPIKE, 7.0)
    assert spike is not None and spike.magnitude == 40.0
    assert schedule.active(FaultKind.TEMPERATURE_SPIKE, 8.0) is None
    assert schedule.active(FaultKind.GPS_LOSS, 15.9) is not None
    assert schedule.active(FaultKind.IMU_STUCK, 10.2) is not None
    assert schedule.active(FaultKind.PRESSURE_SPIKE, 7.0) is None
    assert FaultSchedule.parse("").faults == ()
    repeating = FaultSchedule.parse("pressure_spike@1+1", period=10.0)
    assert repeating.active(FaultKind.PRESSURE_SPIKE, 21.5) is not None


def test_a_dropout_names_its_sensor() -> None:
    schedule = FaultSchedule.parse("dropout:gps@5+2, dropout@20+1")
    assert [(f.sensor, f.label) for f in schedule.faults] == [
        ("gps", "dropout:gps"),
        ("imu", "dropout:imu"),  # the default sensor
    ]
    assert schedule.active(FaultKind.DROPOUT, 6.0, "gps") is not None
    assert schedule.active(FaultKind.DROPOUT, 6.0, "imu") is None
    assert schedule.active(FaultKind.DROPOUT, 20.5, "imu") is not None


@pytest.mark.parametrize(
    "text",
    [
        "gps_loss@3",
        "wind@1+1",
        "gps_loss@a+1",
        "gps_loss@1+1=x",
        "dropout:lidar@1+1",  # not a sensor of the publisher
        "gps_loss:gps@1+1",  # only a dropout names a sensor
    ],
)
def test_bad_fault_schedules_are_rejected(text: str) -> None:
    with pytest.raises(FaultScheduleError):
        FaultSchedule.parse(text)
