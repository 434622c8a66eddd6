"""Unit tests of the pure comparison core: matching, tolerances, events."""

from __future__ import annotations

import math

import pytest

from bagkit.compare.core import Event, Sample, compare_events, compare_samples
from bagkit.compare.errors import CompareError
from bagkit.compare.options import (
    CompareOptions,
    Tolerance,
    ToleranceRule,
    options_from_mapping,
)

SEC = 1_000_000_000


def stamped(t_ns: int, **fields: object) -> Sample:
    header = {"header.stamp.sec": t_ns // SEC, "header.stamp.nanosec": t_ns % SEC}
    return Sample(t_ns + 1000, t_ns + 500, {**header, **fields})  # type: ignore[dict-item]


def unstamped(t_ns: int, **fields: object) -> Sample:
    return Sample(t_ns, t_ns, dict(fields))  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("golden", "candidate", "atol", "rtol", "accepted"),
    [
        (1.0, 1.0, 0.0, 0.0, True),
        (1.0, 1.0 + 1e-9, 0.0, 0.0, False),
        (1.0, 1.05, 0.1, 0.0, True),
        (100.0, 101.0, 0.0, 0.01, True),
        (100.0, 101.5, 0.0, 0.01, False),
        (0.0, 1e-12, 0.0, 0.5, False),  # rtol cannot rescue a value against zero
        (math.nan, math.nan, 0.0, 0.0, True),
        (math.nan, 1.0, 1e9, 1.0, False),
        (math.inf, math.inf, 0.0, 0.0, True),
        (math.inf, -math.inf, 1e9, 0.0, False),
    ],
)
def test_tolerance_rule(
    golden: float, candidate: float, atol: float, rtol: float, accepted: bool
) -> None:
    assert Tolerance(atol, rtol).accepts(golden, candidate) is accepted


def test_negative_tolerance_is_rejected() -> None:
    with pytest.raises(CompareError):
        Tolerance(atol=-1.0)


def test_identical_stamped_messages_pass_and_record_zero_error() -> None:
    samples = [stamped(i * SEC // 10, x=float(i), name="a") for i in range(20)]
    result = compare_samples("/t", "pkg/msg/T", samples, list(samples), CompareOptions())
    assert result.passed
    assert result.matched_by == "stamp"
    assert (result.matched, result.missing, result.extra) == (20, 0, 0)
    x = next(f for f in result.fields if f.path == "x")
    assert x.numeric and x.compared == 20 and x.max_abs_error == 0.0
    # the stamp is what matched the messages: it is not compared again as a field
    assert {f.path for f in result.fields} == {"x", "name"}


def test_perturbed_field_reports_largest_errors() -> None:
    golden = [stamped(i * SEC, x=10.0 + i, y=1.0) for i in range(5)]
    deltas = [0.0, 0.001, 0.003, 0.002, 0.0]
    candidate = [stamped(i * SEC, x=10.0 + i + d, y=1.0) for i, d in enumerate(deltas)]
    loose = compare_samples(
        "/t", "T", golden, candidate, CompareOptions(tolerance=Tolerance(atol=0.005))
    )
    assert loose.passed
    x = next(f for f in loose.fields if f.path == "x")
    assert x.max_abs_error == pytest.approx(0.003)
    assert x.max_rel_error == pytest.approx(0.003 / 12.003)

    tight = compare_samples(
        "/t", "T", golden, candidate, CompareOptions(tolerance=Tolerance(atol=0.0015))
    )
    assert not tight.passed
    assert [f.path for f in tight.failed_fields] == ["x"]
    assert tight.divergence_count == 2
    first = tight.divergences[0]
    assert (first.kind, first.field, first.time_ns) == ("value", "x", 2 * SEC)
    assert first.abs_error == pytest.approx(0.003)


def test_missing_and_extra_messages_by_stamp() -> None:
    golden = [stamped(i * SEC, x=1.0) for i in range(6)]
    candidate = [s for s in golden if s.stamp != 3 * SEC] + [stamped(10 * SEC, x=1.0)]
    result = compare_samples("/t", "T", golden, candidate, CompareOptions())
    assert (result.matched, result.missing, result.extra) == (5, 1, 1)
    kinds = [(d.kind, d.time_ns) for d in result.divergences]
    assert kinds == [("missing_message", 3 * SEC), ("extra_message", 10 * SEC)]


def test_match_window_pairs_nearby_stamps() -> None:
    golden = [stamped(i * SEC, x=1.0) for i in range(4)]
    candidate = [stamped(i * SEC + 20_000_000, x=1.0) for i in range(4)]
    exact = compare_samples("/t", "T", golden, candidate, CompareOptions())
    assert exact.missing == 4 and exact.extra == 4
    windowed = CompareOptions(match_windows={"/t": 50_000_000})
    assert compare_samples("/t", "T", golden, candidate, windowed).passed


def test_unstamped_messages_match_by_order() -> None:
    golden = [unstamped(i, v=i) for i in range(3)]
    candidate = [unstamped(i + 7, v=i) for i in range(4)]
    result = compare_samples("/t", "T", golden, candidate, CompareOptions())
    assert result.matched_by == "order"
    assert (result.matched, result.missing, result.extra) == (3, 0, 1)


def test_changed_string_fails_exactly_whatever_the_tolerance() -> None:
    golden = [stamped(0, **{"status[0].message": "ok", "status[0].level": b"\x00"})]
    candidate = [stamped(0, **{"status[0].message": "ok ", "status[0].level": b"\x00"})]
    result = compare_samples(
        "/t", "T", golden, candidate, CompareOptions(tolerance=Tolerance(1e9, 1.0))
    )
    assert not result.passed
    assert [(d.field, d.golden, d.candidate) for d in result.divergences] == [
        ("status[0].message", "ok", "ok ")
    ]
    # No "max |err| 0" for a text that differs: how many values differ.
    assert [f.describe() for f in result.failed_fields] == ["status[0].message (1 of 1 differ)"]


def test_missing_field_and_type_change_are_divergences() -> None:
    golden = [stamped(0, a=1, b=True)]
    candidate = [stamped(0, b=1)]
    result = compare_samples(
        "/t", "T", golden, candidate, CompareOptions(tolerance=Tolerance(atol=10))
    )
    kinds = sorted((d.kind, d.field) for d in result.divergences)
    assert kinds == [("missing_field", "a"), ("value", "b")]


def test_ignore_fields_and_per_field_rules() -> None:
    golden = [stamped(0, **{"pose.x": 1.0, "pose.y": 1.0, "cov": 5.0})]
    candidate = [stamped(0, **{"pose.x": 1.2, "pose.y": 1.0, "cov": 9.0})]
    options = CompareOptions(
        rules=(ToleranceRule("/t", "pose.*", Tolerance(atol=0.5)),),
        ignore_fields=("/t:cov",),
    )
    assert compare_samples("/t", "T", golden, candidate, options).passed
    # the topic restriction of the ignore pattern holds
    assert not compare_samples("/u", "T", golden, candidate, options).passed


def test_times_are_ignored_unless_asked_for() -> None:
    golden = [unstamped(0, v=1)]
    candidate = [Sample(5 * SEC, 5 * SEC, {"v": 1})]
    assert compare_samples("/t", "T", golden, candidate, CompareOptions()).passed
    strict = compare_samples("/t", "T", golden, candidate, CompareOptions(include_times=True))
    assert {d.field for d in strict.divergences} == {"~log_time", "~publish_time"}


def test_kept_divergences_are_the_earliest() -> None:
    golden = [stamped(i * SEC, x=0.0) for i in range(50)]
    candidate = [stamped(i * SEC, x=1.0) for i in range(50)]
    result = compare_samples("/t", "T", golden[::-1], candidate, CompareOptions(max_divergences=3))
    assert result.divergence_count == 50
    assert [d.time_ns for d in result.divergences] == [0, SEC, 2 * SEC]


def alert(t_s: float, name: str = "baro", level: int = 2) -> Event:
    return Event(round(t_s * SEC), name, level, "")


def test_alert_shifted_within_window_matches() -> None:
    result = compare_events("/alerts", "D", [alert(10.0)], [alert(10.3)], CompareOptions())
    assert result.passed
    assert result.max_event_shift_ns == 300_000_000


def test_alert_shifted_outside_window_is_missing_and_extra() -> None:
    result = compare_events("/alerts", "D", [alert(10.0)], [alert(10.8)], CompareOptions())
    assert not result.passed
    assert [(d.kind, d.time_ns) for d in result.divergences] == [
        ("missing_event", 10 * SEC),
        ("extra_event", 10_800_000_000),
    ]


def test_alert_with_other_level_does_not_match() -> None:
    result = compare_events(
        "/alerts", "D", [alert(1.0, level=2)], [alert(1.0, level=1)], CompareOptions()
    )
    assert (result.matched, result.missing, result.extra) == (0, 1, 1)


def test_options_from_spec_mapping() -> None:
    options = options_from_mapping(
        {
            "atol": 1e-9,
            "event_window": 0.25,
            "ignore_fields": ["/logger/summary:*"],
            "topics": {
                "/fusion/odometry": {
                    "atol": 0.01,
                    "match_window": 0.05,
                    "fields": {"pose.pose.position.z": {"atol": 0.5}},
                }
            },
        },
        max_divergences=4,
    )
    assert options.event_window_ns == 250_000_000
    assert options.window_for("/fusion/odometry") == 50_000_000
    assert options.tolerance_for("/fusion/odometry", "pose.pose.position.z").atol == 0.5
    assert options.tolerance_for("/fusion/odometry", "twist.twist.linear.x").atol == 0.01
    assert options.tolerance_for("/other", "x").atol == 1e-9
    assert options.is_ignored("/logger/summary", "status[0].values[0].value")
    assert options.max_divergences == 4
    with pytest.raises(CompareError):
        options_from_mapping({"tolerance": 1})


@pytest.mark.parametrize("seconds", [float("nan"), float("inf"), 1e300, "soon"])
def test_a_window_that_is_no_time_is_a_compare_error(seconds: object) -> None:
    # YAML's .nan and .inf load as floats: the spec is untrusted like a bag.
    with pytest.raises(CompareError):
        options_from_mapping({"event_window": seconds})


def test_integers_compare_exactly_whatever_the_tolerance() -> None:
    golden = [stamped(0, level=2, x=1.0)]
    candidate = [stamped(0, level=1, x=1.5)]
    result = compare_samples(
        "/t", "T", golden, candidate, CompareOptions(tolerance=Tolerance(atol=1.0))
    )
    assert [f.path for f in result.failed_fields] == ["level"]


def test_sequence_fields_compare_length_and_elements() -> None:
    golden = [stamped(0, **{"status[].name": ["baro", "gps"], "status[].level": [2, 1]})]
    candidate = [
        stamped(0, **{"status[].name": ["baro", "imu", "gps"], "status[].level": [2, 1, 1]})
    ]
    result = compare_samples("/t", "T", golden, candidate, CompareOptions())
    found = sorted((d.kind, d.field, d.golden, d.candidate) for d in result.divergences)
    assert found == [
        ("length", "status[].level", 2, 3),
        ("length", "status[].name", 2, 3),
        ("value", "status[].name#1", "gps", "imu"),
    ]


def test_a_length_only_difference_names_its_field() -> None:
    golden = [stamped(0, **{"status[].level": [2, 1]})]
    candidate = [stamped(0, **{"status[].level": [2, 1, 1]})]
    result = compare_samples("/t", "T", golden, candidate, CompareOptions())
    assert not result.passed and result.failed_fields == []
    assert result.shape_fields == ["status[].level (length)"]


def test_brackets_in_field_globs_are_literal() -> None:
    options = CompareOptions(
        ignore_fields=("/s:status[].values[].value",),
        rules=(ToleranceRule("*", "pose.covariance[14]", Tolerance(atol=1.0)),),
    )
    assert options.is_ignored("/s", "status[].values[].value")
    assert not options.is_ignored("/s", "status[].values[].key")
    assert options.tolerance_for("/t", "pose.covariance[14]").atol == 1.0
    assert options.tolerance_for("/t", "pose.covariance[1]").atol == 0.0


def test_pass_rate_tolerates_isolated_failures_but_not_other_shapes() -> None:
    golden = [stamped(i * SEC, x=0.0) for i in range(50)]
    candidate = [stamped(i * SEC, x=1.0 if i in {7, 30} else 0.0) for i in range(50)]
    strict = compare_samples("/t", "T", golden, candidate, CompareOptions())
    assert not strict.passed and strict.failed_messages == 2
    lenient = compare_samples("/t", "T", golden, candidate, CompareOptions(pass_rates={"/t": 0.96}))
    assert lenient.passed and lenient.allowed_failed_messages == 2
    assert lenient.divergence_count == 2  # still reported
    assert not compare_samples("/t", "T", golden, candidate, CompareOptions(pass_rate=0.97)).passed
    # a missing or extra message counts against the rate too
    dropped = compare_samples("/t", "T", golden, candidate[:-1], CompareOptions(pass_rate=0.94))
    assert dropped.passed and dropped.failed_messages == 3
    assert not compare_samples(
        "/t", "T", golden, candidate[:-1], CompareOptions(pass_rate=0.96)
    ).passed
    # a message of another shape fails whatever the rate
    reshaped = [*candidate[:-1], stamped(49 * SEC, x=0.0, y=1.0)]
    assert not compare_samples("/t", "T", golden, reshaped, CompareOptions(pass_rate=0.5)).passed
    with pytest.raises(CompareError):
        CompareOptions(pass_rate=1.5)
