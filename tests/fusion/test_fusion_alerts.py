"""Alert rules: hysteresis, debouncing, stuck sensors, GPS fix and staleness."""

from __future__ import annotations

from fusion.alerts import AlertMonitor, Level, RangeRule, SensorRules

S = 1_000_000_000
RULE = RangeRule("temperature", warn=(-20.0, 45.0), error=(-40.0, 60.0), hysteresis=1.0)


def _monitor(**options: int) -> AlertMonitor:
    sensors = {
        "temperature": SensorRules("temperature", period_ns=S // 2, ranges=(RULE,)),
        "gps": SensorRules("gps", period_ns=S, requires_fix=True),
        "imu": SensorRules("imu", period_ns=S // 10, stuck_samples=5),
    }
    return AlertMonitor(sensors, stale_periods=3.0, **options)


def test_range_rule_levels_and_hysteresis() -> None:
    assert RULE.level(20.0, Level.OK) is Level.OK
    assert RULE.level(45.5, Level.OK) is Level.WARN
    assert RULE.level(61.0, Level.OK) is Level.ERROR
    assert RULE.level(-41.0, Level.OK) is Level.ERROR
    # Once WARN, the value must come back below 45 - 1 to be OK again.
    assert RULE.level(44.5, Level.WARN) is Level.WARN
    assert RULE.level(43.9, Level.WARN) is Level.OK
    # Once ERROR, back below 60 - 1 before dropping to WARN.
    assert RULE.level(59.5, Level.ERROR) is Level.ERROR
    assert RULE.level(58.0, Level.ERROR) is Level.WARN
    assert RULE.level(float("nan"), Level.OK) is Level.ERROR


def test_value_hovering_at_a_limit_does_not_flap() -> None:
    monitor = _monitor(debounce_samples=1)
    changes = []
    t = 0
    for value in [44.0, 45.2, 44.8, 45.3, 44.6, 45.1, 44.9, 44.5, 43.5, 43.0]:
        t += S // 2
        changes += monitor.on_sample("temperature", t, {"temperature": value})
    assert [c.level for c in changes] == [Level.WARN, Level.OK]
    assert "temperature 45.2 outside [-20, 45]" in changes[0].message


def test_debounce_ignores_a_single_outlier() -> None:
    monitor = _monitor(debounce_samples=2)
    values = [20.0, 70.0, 20.0, 20.0, 70.0, 71.0, 20.0]
    levels = [
        [c.level for c in monitor.on_sample("temperature", (i + 1) * S // 2, {"temperature": v})]
        for i, v in enumerate(values)
    ]
    assert levels == [[], [], [], [], [], [Level.ERROR], []]
    assert monitor.states["temperature"].level is Level.ERROR


def test_gps_without_fix_and_stuck_imu_are_errors() -> None:
    monitor = _monitor(debounce_samples=1)
    assert monitor.on_sample("gps", S, {}, has_fix=True) == []
    (no_fix,) = monitor.on_sample("gps", 2 * S, {}, has_fix=False)
    assert no_fix.level is Level.ERROR and no_fix.message == "no GPS fix"
    changes = []
    for i in range(6):
        changes += monitor.on_sample("imu", S + i * S // 10, {}, stuck_key=(0.1, 9.8))
    assert [c.level for c in changes] == [Level.ERROR]
    assert "stuck: 5 identical samples" in changes[0].message
    (recovered,) = monitor.on_sample("imu", 2 * S, {}, stuck_key=(0.2, 9.8))
    assert recovered.level is Level.OK


def test_silent_sensor_goes_stale_after_three_periods_and_recovers() -> None:
    monitor = _monitor(startup_grace_ns=0)
    monitor.on_sample("temperature", 10 * S, {"temperature": 20.0})
    monitor.on_sample("gps", 10 * S, {}, has_fix=True)
    monitor.on_sample("imu", 10 * S, {}, stuck_key=(1.0,))
    assert monitor.check(10 * S + 3 * S // 10) == []  # imu: exactly 3 periods is not more
    (imu_stale,) = monitor.check(10 * S + 4 * S // 10)
    assert imu_stale.name == "imu" and imu_stale.level is Level.STALE
    assert "no message for 0.4 s" in imu_stale.message
    stale = monitor.check(10 * S + 1600 * S // 1000)
    assert [s.name for s in stale] == ["temperature"]
    assert monitor.check(10 * S + 1700 * S // 1000) == []  # already stale: no new change
    (back,) = monitor.on_sample("temperature", 12 * S, {"temperature": 20.0})
    assert back.level is Level.OK


def test_startup_grace_for_sensors_never_heard_from() -> None:
    monitor = _monitor(startup_grace_ns=3 * S)
    assert monitor.check(0) == []
    assert monitor.check(2 * S) == []
    stale = monitor.check(3 * S + 1)
    assert {s.name for s in stale} == {"temperature", "gps", "imu"}
    assert all(s.message == "no message received yet" for s in stale)
