"""Lockstep replay: determinism, bag-time timers, outputs on the time of their cause."""

from __future__ import annotations

from pathlib import Path

import pytest

from bagkit.bag import BagReader
from bagkit.regression.errors import RegressionError, SpecError
from bagkit.regression.lockstep import run_lockstep
from bagkit.regression.processor import Processor
from bagkit.regression.processor import make_processors as make_processors_of_spec
from fusion.regression import make_processors


def nodes(**sensor_fusion: object) -> list[Processor]:
    """Fresh processors of the three nodes under test (processors keep state)."""
    return make_processors({"data_logger": {}, "alert_system": {}, "sensor_fusion": sensor_fusion})


SENSORS = ("/imu/data", "/gps/fix", "/temperature", "/barometer/pressure")


def test_two_runs_are_bit_identical(simulated_flight: Path, tmp_path: Path) -> None:
    first = run_lockstep(simulated_flight, tmp_path / "a" / "out", processors=nodes())
    second = run_lockstep(simulated_flight, tmp_path / "b" / "out", processors=nodes())
    assert first.output_counts == second.output_counts
    assert set(first.output_counts) == {
        "/fusion/odometry",
        "/fusion/baro_altitude",
        "/logger/summary",
        "/alerts",
    }
    for name in ("out_0.mcap", "metadata.yaml"):
        assert (tmp_path / "a" / "out" / name).read_bytes() == (
            tmp_path / "b" / "out" / name
        ).read_bytes()


def test_outputs_are_written_at_the_bag_time_of_their_cause(
    simulated_flight: Path, tmp_path: Path
) -> None:
    result = run_lockstep(simulated_flight, tmp_path / "out", processors=nodes())
    with BagReader(simulated_flight) as inputs:
        imu_times = [m.log_time for m in inputs.messages(topics=["/imu/data"])]
        pressure_times = [m.log_time for m in inputs.messages(topics=["/barometer/pressure"])]
        start, end = inputs.start_ns, inputs.end_ns
    with BagReader(tmp_path / "out") as out:
        odometry = [m.log_time for m in out.messages(topics=["/fusion/odometry"])]
        altitude = [m.log_time for m in out.messages(topics=["/fusion/baro_altitude"])]
        summaries = [m.log_time for m in out.messages(topics=["/logger/summary"])]
    # the fusion node answers IMU and pressure samples at the time they were received
    assert set(odometry) <= set(imu_times) and len(odometry) >= len(imu_times) - 2
    assert set(altitude) <= set(pressure_times) and len(altitude) >= len(pressure_times) - 2
    # the logger's timer ticks at the first input (as a sim-time node's overdue timer does
    # when the clock jumps to the bag), then on the multiples of its 5 s period of bag time
    period = 5_000_000_000
    assert summaries == [start, *range((start // period + 1) * period, end + 1, period)]
    assert result.timer_calls >= len(summaries)
    assert result.input_messages == sum(
        1 for _ in BagReader(simulated_flight).open().messages(topics=list(SENSORS))
    )


def test_copied_topics_are_kept_byte_for_byte(simulated_flight: Path, tmp_path: Path) -> None:
    copied = [*SENSORS, "/sim/truth"]
    result = run_lockstep(
        simulated_flight, tmp_path / "out", processors=nodes(), copy_topics=copied
    )
    with BagReader(simulated_flight) as golden, BagReader(tmp_path / "out") as out:
        assert list(golden.messages(topics=copied)) == list(out.messages(topics=copied))
        assert out.topics["/imu/data"] == golden.topics["/imu/data"]
        assert out.topic_counts["/fusion/odometry"] == result.output_counts["/fusion/odometry"]
    assert "/sim/truth" not in result.output_counts


def test_changed_parameter_changes_the_outputs(simulated_flight: Path, tmp_path: Path) -> None:
    run_lockstep(simulated_flight, tmp_path / "a", processors=nodes())
    run_lockstep(simulated_flight, tmp_path / "b", processors=nodes(qnh=101425.0))
    with BagReader(tmp_path / "a") as a, BagReader(tmp_path / "b") as b:
        base = list(a.messages(topics=["/fusion/baro_altitude"]))
        other = list(b.messages(topics=["/fusion/baro_altitude"]))
    assert len(base) == len(other)
    assert all(x.data != y.data for x, y in zip(base, other, strict=True))


def test_bad_input_is_a_regression_error(simulated_flight: Path, tmp_path: Path) -> None:
    with pytest.raises(RegressionError, match="1 input topic missing: /lidar"):
        run_lockstep(simulated_flight, tmp_path / "a", processors=nodes(), input_topics=["/lidar"])
    with pytest.raises(SpecError, match="no_such_node"):
        make_processors_of_spec(
            "fusion.regression:make_processors", {"nodes": {"no_such_node": {}}}
        )
    with pytest.raises(SpecError, match="cannot import"):
        make_processors_of_spec("no_such_pkg.cores:make", {})
    with pytest.raises(SpecError, match="Processor objects"):
        make_processors_of_spec("builtins:list", {})
