"""The verdict of `fusion check` from measured figures (the live test does the measuring)."""

from __future__ import annotations

import json

from fusion.nodes.monitor import LiveCheck, TopicRate


def _check(imu_rate: float, fused: float, gps: float) -> LiveCheck:
    rates = (
        TopicRate("/imu/data", 10.0, round(imu_rate * 30), imu_rate, 0.11),
        TopicRate("/gps/fix", 1.0, 30, 1.0, 1.0),
    )
    return LiveCheck(30.0, rates, fused, gps, 300, ("/gps/fix: no GPS fix",))


def test_targets_need_every_rate_within_ten_percent_and_fused_better_than_gps() -> None:
    assert _check(10.0, 2.0, 3.0).targets_met()
    assert _check(9.05, 2.0, 3.0).targets_met()
    assert not _check(8.9, 2.0, 3.0).targets_met()
    assert not _check(10.0, 3.1, 3.0).targets_met()
    assert _check(8.9, 2.0, 3.0).targets_met(rate_tolerance=0.15)


def test_json_form() -> None:
    data = json.loads(json.dumps(_check(10.0, 2.0, 3.0).as_dict()))
    assert data["targets_met"] is True
    assert data["rates"][0] == {
        "topic": "/imu/data",
        "nominal_hz": 10.0,
        "count": 300,
        "rate_hz": 10.0,
        "max_gap_s": 0.11,
    }
    assert data["alerts"] == ["/gps/fix: no GPS fix"]
