"""fusion's faults found by ``bagkit check``, each by the assertion that describes it, start
and end within one sample period of the schedule (its zero from the ground truth,
tests/fusion/fault_clock.py; never from bagkit's output).

The faults fixture (recorded live) holds a spike, a GPS loss and a stuck IMU; the dropouts are
recorded here from the live system, as `make golden` records a fixture.
"""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from bagkit.health import HealthSpec, check_bags
from bagkit.health.verdicts import HealthReport
from bagkit.regression.live import record_golden
from bagkit.regression.spec import load_spec
from fusion.faults import Fault, FaultKind, FaultSchedule
from fusion.processors.sensor_publisher import SensorPublisher
from tests.fusion.fault_clock import NS, scenario, schedule_zero_ns

FIXTURES = Path(__file__).parents[2] / "fixtures"
LOGGING_NS = 20_000_000  # from a sample's tick to its log time in the faults fixture
LIVE_LATENCY_NS = 50_000_000  # the same in a recording made while other tests load the machine
PERIODS = {"/imu/data": 0.1, "/gps/fix": 1.0, "/temperature": 0.5, "/barometer/pressure": 0.5}
FAULTS_CONTRACT = """\
topics:
  /temperature: {values: {temperature: {max: 50}}}
  /barometer/pressure: {values: {fluid_pressure: {max: 105000}}}
  /gps/fix: {never: [isnan(*)]}
  /imu/data: {never: ["unchanged(linear_acceleration) for 1s"]}
"""
DROPOUTS = "dropout:imu@5+2, dropout:gps@8+3"
DROPOUT_CONTRACT = """\
topics:
  /imu/data:
    max_gap: 300ms
    rate: {min: 5, over: 1s}
  /gps/fix:
    max_gap: 1500ms
"""


def broken_spans(report: HealthReport, topic: str, what: str) -> list[tuple[int, int]]:
    (assertion,) = [a for a in report.assertions if a.topic == topic and a.what == what]
    return [(start, end) for start, end, _ in assertion.spans.tolist()]


def scheduled(zero_ns: int, fault: Fault) -> tuple[int, int]:
    return zero_ns + round(fault.start * NS), zero_ns + round((fault.start + fault.duration) * NS)


CASES = [
    # fault, topic, the assertion that finds it, whether the span starts at the repeated sample
    (FaultKind.TEMPERATURE_SPIKE, "/temperature", "temperature > 50", False),
    (FaultKind.PRESSURE_SPIKE, "/barometer/pressure", "fluid_pressure > 105000", False),
    (FaultKind.GPS_LOSS, "/gps/fix", "isnan(*)", False),
    # The stuck IMU repeats the last good sample: the run of equal values starts there.
    (FaultKind.IMU_STUCK, "/imu/data", "unchanged(linear_acceleration) for 1s", True),
]


@pytest.fixture(scope="module")
def faults_report() -> tuple[HealthReport, int, FaultSchedule]:
    params = scenario(FIXTURES / "faults" / "scenario.yaml")
    bag = FIXTURES / "faults" / "golden"
    zero = schedule_zero_ns(bag, SensorPublisher(params))
    (report,) = check_bags(bag, HealthSpec.parse(FAULTS_CONTRACT)).reports
    return report, zero, FaultSchedule.parse(str(params["faults"]))


@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_each_recorded_fault_breaks_its_assertion_where_scheduled(
    faults_report: tuple[HealthReport, int, FaultSchedule],
    case: tuple[FaultKind, str, str, bool],
) -> None:
    report, zero, schedule = faults_report
    kind, topic, what, repeats = case
    (fault,) = [f for f in schedule.faults if f.kind == kind]
    start, end = scheduled(zero, fault)
    sample = round(PERIODS[topic] * NS)
    ((first, last),) = broken_spans(report, topic, what)
    first_expected = start - sample if repeats else start
    # The first faulty sample is the first tick at or after the start; the last one the last
    # tick before the end.
    assert first_expected <= first <= first_expected + sample + LOGGING_NS, (first - start) / NS
    assert end - sample <= last <= end + LOGGING_NS, (last - end) / NS
    assert len(report.broken) == len(CASES)  # and nothing else broke


@pytest.fixture(scope="module")
def dropout_flight(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, SensorPublisher]:
    """14 s of the live system (every node, over DDS) with an IMU and a GPS dropout."""
    fixture = tmp_path_factory.mktemp("dropouts") / "dropouts"
    fixture.mkdir()
    publisher = {
        "seed": 5,
        "faults": DROPOUTS,
        "flight": {"takeoff_delay": 2.0, "climb_duration": 20.0},
    }
    (fixture / "scenario.yaml").write_text(
        yaml.safe_dump({"sensor_publisher": {"ros__parameters": publisher}})
    )
    spec = {
        "description": "an IMU and a GPS dropout",
        "duration": 14,
        "record_launch": "fusion launch --params {fixture}/scenario.yaml",
        "launch": "fusion launch --use-sim-time --only alert_system",  # not run here
        "record_topics": ["/sim/truth"],
        "inputs": list(PERIODS),
        "outputs": ["/alerts"],
    }
    (fixture / "spec.yaml").write_text(yaml.safe_dump(spec))
    record_golden(load_spec(fixture), fixture.parent / "work", log=lambda _: None)
    return fixture / "golden", SensorPublisher(scenario(fixture / "scenario.yaml"))


def around(spans: list[tuple[int, int]], start: int, end: int) -> tuple[int, int]:
    """The one span over the middle of ``[start, end)``: under load the live publisher's
    timer can stall elsewhere too, which is a real silence in the recording."""
    middle = (start + end) // 2
    (found,) = [(a, b) for a, b in spans if a <= middle <= b]
    return found


@pytest.mark.ros
def test_a_dropout_breaks_the_gap_and_the_rate(
    dropout_flight: tuple[Path, SensorPublisher],
) -> None:
    bag, publisher = dropout_flight
    zero = schedule_zero_ns(bag, publisher)
    faults = {f.sensor: f for f in FaultSchedule.parse(DROPOUTS).faults}
    (report,) = check_bags(bag, HealthSpec.parse(DROPOUT_CONTRACT)).reports
    gaps = (("imu", "/imu/data", "gap > 300ms"), ("gps", "/gps/fix", "gap > 1500ms"))
    for sensor, topic, gap in gaps:
        start, end = scheduled(zero, faults[sensor])
        sample = round(PERIODS[topic] * NS)
        # From the last sample before the silence to the first after it (each logged a
        # little after its tick, the schedule's clock).
        first, last = around(broken_spans(report, topic, gap), start, end)
        assert start - sample <= first <= start + LIVE_LATENCY_NS, (first - start) / NS
        assert end <= last <= end + sample + LIVE_LATENCY_NS, (last - end) / NS
    # Fewer than 5 IMU samples in a second: the windows that overlap the silence by more than
    # half a second, so the span holds the silence and reaches at most a window beyond it.
    start, end = scheduled(zero, faults["imu"])
    first, last = around(broken_spans(report, "/imu/data", "rate < 5 Hz over 1s"), start, end)
    assert start - NS <= first <= start and end - 2 * round(0.1 * NS) <= last <= end + NS
