"""Processors: the registry, deterministic outputs, stamps, and what each node publishes."""

from __future__ import annotations

import math

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticStatus
from fusion_loop import START_NS, run_loop
from rclpy.serialization import serialize_message
from rosbags.typesys import Stores, get_typestore

from bagkit.regression import Processor
from bagkit.ros.message_classes import message_type_name
from fusion import topics
from fusion.errors import ConfigError, UnknownNodeError
from fusion.params import default_parameters
from fusion.processors import NODE_NAMES, create_processor, parameter_descriptions
from fusion.processors.messages import stamp_ns


def _outputs(seed: int) -> list[tuple[int, str, str]]:
    result = run_loop(25.0, {"sensor_publisher": {"seed": seed}})
    # repr, not serialize_message: rclpy leaves CDR alignment padding uninitialized, so equal
    # messages can serialize to different bytes. repr shows every field (floats exactly, NaN
    # equal to NaN).
    return [(t, topic, repr(msg)) for t, topic, msg in result.published]


def test_same_inputs_give_identical_outputs() -> None:
    first, second = _outputs(5), _outputs(5)
    assert len(first) > 500
    assert first == second
    assert _outputs(6) != first


def test_registry_and_parameter_descriptions() -> None:
    assert NODE_NAMES == ("sensor_publisher", "data_logger", "alert_system", "sensor_fusion")
    for name in NODE_NAMES:
        processor = create_processor(name)
        assert isinstance(processor, Processor), name  # bagkit's protocol, as lockstep checks
        assert set(processor.input_topics) <= set(topics.TOPIC_TYPES)
        assert set(processor.output_topics) <= set(topics.TOPIC_TYPES)
        descriptions = parameter_descriptions(name)
        assert set(descriptions) == set(default_parameters(name)), name
        assert all(len(text) > 10 for text in descriptions.values())
    with pytest.raises(UnknownNodeError):
        create_processor("camera")
    with pytest.raises(ConfigError, match="unknown parameter"):
        create_processor("sensor_fusion", {"qhn": 101000.0})
    with pytest.raises(ConfigError, match="must be > 0"):
        create_processor("data_logger", {"summary_period": 0})
    with pytest.raises(ConfigError, match=r"\[low, high\]"):
        create_processor("alert_system", {"temperature.temperature.warn": [50.0, 10.0]})


def test_data_logger_answers_summary_requests() -> None:
    from std_srvs.srv import Trigger

    logger = create_processor("data_logger")
    assert logger.services == {topics.LOGGER_GET_SUMMARY: Trigger}
    empty = logger.on_request(topics.LOGGER_GET_SUMMARY, Trigger.Request(), 0)
    assert not empty.success
    result = run_loop(2.05)
    for topic in topics.SENSOR_TOPICS:
        for msg in result.messages(topic):
            logger.on_message(topic, msg, 0)
    answer = logger.on_request(topics.LOGGER_GET_SUMMARY, Trigger.Request(), 0)
    counts = {t: len(result.messages(t)) for t in topics.SENSOR_TOPICS}
    assert answer.success
    assert answer.message == "; ".join(f"{t}: {n}" for t, n in counts.items())
    with pytest.raises(ConfigError, match="service_introspection"):
        create_processor("data_logger", {"service_introspection": "on"})


def test_sensor_rates_and_output_stamps() -> None:
    result = run_loop(10.05)  # ticks at 0.1 s ... 10.0 s
    counts = {topic: len(result.messages(topic)) for topic in topics.SENSOR_TOPICS}
    assert counts == {topics.IMU: 100, topics.GPS: 10, topics.TEMPERATURE: 20, topics.PRESSURE: 20}
    imu_stamps = [stamp_ns(m.header.stamp) for m in result.messages(topics.IMU)]
    assert np.all(np.diff(imu_stamps) == 100_000_000)
    odometry = result.messages(topics.ODOMETRY)
    # Odometry answers each IMU sample once the filter has its first altitude.
    assert {stamp_ns(m.header.stamp) for m in odometry} <= set(imu_stamps)
    assert len(odometry) >= 99
    pressure_stamps = [stamp_ns(m.header.stamp) for m in result.messages(topics.PRESSURE)]
    baro_stamps = [stamp_ns(m.header.stamp) for m in result.messages(topics.BARO_ALTITUDE)]
    assert baro_stamps == pressure_stamps
    for now_ns, topic, msg in result.published:
        if topic in (topics.ALERTS, topics.LOGGER_SUMMARY):
            assert stamp_ns(msg.header.stamp) == now_ns


def test_imu_at_rest_reads_plus_g_and_pressure_matches_altitude() -> None:
    result = run_loop(2.0, {"sensor_publisher": {"faults": ""}})
    accel_z = [m.linear_acceleration.z for m in result.messages(topics.IMU)]
    assert np.mean(accel_z) == pytest.approx(9.80665, abs=0.05)  # REP 145: +g at rest
    imu = result.messages(topics.IMU)[0]
    assert imu.linear_acceleration_covariance[0] == pytest.approx((4e-3 * math.sqrt(10)) ** 2)
    fix = result.messages(topics.GPS)[0]
    assert fix.position_covariance_type == fix.COVARIANCE_TYPE_DIAGONAL_KNOWN


def test_logger_summary_equals_numpy_over_the_inputs() -> None:
    result = run_loop(10.5)
    summaries = result.messages(topics.LOGGER_SUMMARY)
    assert [stamp_ns(s.header.stamp) - START_NS for s in summaries] == [
        5_000_000_000,
        10_000_000_000,
    ]
    # The second summary covers everything published before t = 10 s.
    cutoff = START_NS + 10_000_000_000
    temperatures = np.array(
        [
            m.temperature
            for t, topic, m in result.published
            if topic == topics.TEMPERATURE and t < cutoff
        ]
    )
    fixes = [m for t, topic, m in result.published if topic == topics.GPS and t < cutoff]
    status = {s.hardware_id: s for s in summaries[1].status}
    values = {kv.key: kv.value for kv in status[topics.TEMPERATURE].values}
    assert int(values["temperature.count"]) == temperatures.size
    assert float(values["temperature.mean"]) == pytest.approx(temperatures.mean(), rel=1e-5)
    assert float(values["temperature.std"]) == pytest.approx(temperatures.std(), rel=1e-5)
    assert float(values["temperature.max"]) == pytest.approx(temperatures.max(), rel=1e-5)
    gps_values = {kv.key: kv.value for kv in status[topics.GPS].values}
    assert gps_values["altitude.count"] == str(len(fixes))
    info = [line.text for line in result.logs["data_logger"] if line.severity == 20]
    assert len(info) == 2 and "linear_acceleration.z" in info[1]


def test_default_fault_schedule_raises_and_clears_alerts() -> None:
    result = run_loop(20.0)
    transitions: dict[str, list[tuple[float, bytes]]] = {t: [] for t in topics.SENSOR_TOPICS}
    previous: dict[str, bytes] = {}
    for alerts in result.messages(topics.ALERTS):
        # Every message carries every sensor's state, for late subscribers.
        assert {s.hardware_id for s in alerts.status} == set(topics.SENSOR_TOPICS)
        t = (stamp_ns(alerts.header.stamp) - START_NS) / 1e9
        for s in alerts.status:
            if previous.get(s.hardware_id, DiagnosticStatus.OK) != s.level:
                transitions[s.hardware_id].append((t, s.level))
            previous[s.hardware_id] = s.level
    levels = {topic: [level for _, level in changes] for topic, changes in transitions.items()}
    error_then_ok = [DiagnosticStatus.ERROR, DiagnosticStatus.OK]
    assert levels == dict.fromkeys(topics.SENSOR_TOPICS, error_then_ok)
    # Default schedule (seconds after the first sample, which is at 0.1 s): temperature spike
    # 6-8, pressure spike 9-10.5, GPS loss 12-16, IMU stuck 16-18; alerts follow within the
    # debounce (2 samples) or the stuck window (10 samples).
    raised = {topic: changes[0][0] for topic, changes in transitions.items()}
    assert 6.1 < raised[topics.TEMPERATURE] <= 6.7
    assert 9.1 < raised[topics.PRESSURE] <= 9.7
    assert 12.1 < raised[topics.GPS] <= 13.2
    assert 16.1 < raised[topics.IMU] <= 17.2


def test_rosbags_messages_give_the_same_outputs_as_rclpy_messages() -> None:
    """Lockstep replay may feed messages decoded by rosbags instead of rclpy classes."""
    typestore = get_typestore(Stores.ROS2_JAZZY)
    inputs = [
        (t, topic, msg)
        for t, topic, msg in run_loop(20.0, nodes=("sensor_publisher",)).published
        if topic in topics.SENSOR_TOPICS
    ]
    for name in ("data_logger", "alert_system", "sensor_fusion"):
        outputs = []
        for decode in (False, True):
            processor = create_processor(name)
            published = []
            for t, topic, msg in inputs:
                if topic in processor.input_topics:
                    given = (
                        typestore.deserialize_cdr(serialize_message(msg), message_type_name(msg))
                        if decode
                        else msg
                    )
                    published += processor.on_message(topic, given, t)
            published += processor.on_timer(inputs[-1][0])
            outputs.append([(topic, repr(msg)) for topic, msg in published])
        assert outputs[0] == outputs[1], name
        assert len(outputs[0]) > 0


def test_publisher_schedule_survives_late_ticks_and_clock_jumps() -> None:
    publisher = create_processor("sensor_publisher", {"faults": ""})
    ms = 1_000_000
    published = {}
    for tick_ms in (0, 100, 200, 455, 500, 600, 1000, 1100, 2650, 2700, 2800, 3000):
        outputs = publisher.on_timer(START_NS + tick_ms * ms)
        published[tick_ms] = {topic for topic, _ in outputs} - {topics.TRUTH}
    slow = {topics.GPS, topics.TEMPERATURE, topics.PRESSURE}
    assert published[0] == {topics.IMU} | slow
    assert published[455] == {topics.IMU}  # late, but only one IMU sample for 300-455
    assert published[500] == {topics.IMU, topics.TEMPERATURE, topics.PRESSURE}
    assert published[1000] == {topics.IMU} | slow
    # A jump over 1.5 s: one sample each now, then back in phase with the original schedule.
    assert published[2650] == {topics.IMU} | slow
    assert published[2700] == published[2800] == {topics.IMU}
    assert published[3000] == {topics.IMU} | slow


def test_a_dropout_silences_its_sensor_for_its_duration() -> None:
    result = run_loop(10.05, {"sensor_publisher": {"faults": "dropout:gps@3+2.5, dropout@6+1"}})
    # Fault times count from the publisher's first tick, 0.1 s after START_NS.
    first_ns = START_NS + 100_000_000
    gps = [(stamp_ns(m.header.stamp) - first_ns) / 1e9 for m in result.messages(topics.GPS)]
    imu = [(stamp_ns(m.header.stamp) - first_ns) / 1e9 for m in result.messages(topics.IMU)]
    # 1 Hz GPS from the first tick: the samples due at 3, 4 and 5 s fall in [3, 5.5).
    assert len(gps) == 10 - 3 and not any(3.0 <= t < 5.5 for t in gps)
    # 10 Hz IMU: the ten samples due in [6, 7) are missing, the others are there.
    assert len(imu) == 100 - 10 and not any(6.0 - 1e-9 <= t < 7.0 - 1e-9 for t in imu)
    assert imu[0] == 0.0
    assert len(result.messages(topics.TEMPERATURE)) == 20


def test_topics_outside_input_topics_are_ignored() -> None:
    imu = run_loop(0.15, nodes=("sensor_publisher",)).messages(topics.IMU)[0]
    for name in NODE_NAMES:
        assert create_processor(name).on_message("/camera/image", imu, START_NS) == []
