"""fusion's faults bag: each scheduled fault is found by the condition that describes it
(spike: a value bound; gps_loss: NaN; imu_stuck: unchanged), start and end within one sample
period of the schedule.

The schedule's zero is found from the ground truth (tests/fusion/fault_clock.py).
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from fusion.faults import FaultKind, FaultSchedule
from fusion.processors.sensor_publisher import SensorPublisher
from tests.fusion.fault_clock import scenario as fault_scenario
from tests.fusion.fault_clock import schedule_zero_ns

FIXTURE = Path(__file__).parents[2] / "fixtures" / "faults"
BAG = FIXTURE / "golden"
BAGKIT = str(Path(sys.executable).with_name("bagkit"))
NS = 1_000_000_000


def scenario() -> dict[str, object]:
    return fault_scenario(FIXTURE / "scenario.yaml")


@pytest.fixture(scope="module")
def publisher() -> SensorPublisher:
    return SensorPublisher(scenario())


@pytest.fixture(scope="module")
def first_tick_ns(publisher: SensorPublisher) -> int:
    """Log-time scale of the schedule's zero, from the truth's altitude during the climb."""
    return schedule_zero_ns(BAG, publisher)


def find(when: str) -> list[tuple[int, int]]:
    done = subprocess.run(
        [BAGKIT, "find", str(BAG), "--when", when, "--format", "json"],
        check=False,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    return [(e["start_ns"], e["end_ns"]) for e in json.loads(done.stdout)]


CASES = [
    # fault, condition, sample period (s), what the episode spans
    (FaultKind.TEMPERATURE_SPIKE, "/temperature: temperature > 50", 0.5, "samples"),
    (FaultKind.PRESSURE_SPIKE, "/barometer/pressure: fluid_pressure > 105000", 0.5, "samples"),
    (FaultKind.GPS_LOSS, "/gps/fix: isnan(*)", 1.0, "samples"),
    # The stuck IMU repeats the last good sample: the run of equal values starts there.
    (FaultKind.IMU_STUCK, "/imu/data: unchanged(linear_acceleration) for 1s", 0.1, "repeats"),
]


@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_each_fault_is_found_where_the_schedule_put_it(
    publisher: SensorPublisher, first_tick_ns: int, case: tuple[FaultKind, str, float, str]
) -> None:
    kind, when, period, spans = case
    schedule = FaultSchedule.parse(str(scenario()["faults"]))
    (fault,) = [f for f in schedule.faults if f.kind == kind]
    assert publisher.faults.faults == schedule.faults
    (episode,) = find(when)
    start = first_tick_ns + round(fault.start * NS)
    end = first_tick_ns + round((fault.start + fault.duration) * NS)
    sample, logging = round(period * NS), 20_000_000  # a sample period; the time to log one
    first = start - sample if spans == "repeats" else start
    # The first faulty sample is the first tick at or after the start (the IMU's repeat, the
    # last good sample before it); the last one is the last tick before the end.
    assert first <= episode[0] <= first + sample + logging, (episode[0] - first) / NS
    assert end - sample <= episode[1] <= end + logging, (episode[1] - end) / NS
