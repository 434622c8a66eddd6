"""Comparing live service responses with recorded ones: the pure core of the verdict."""

from __future__ import annotations

from bagkit.playback.service_responses import (
    ServiceReplaySummary,
    Tolerance,
    compare_response,
    differences,
)


def test_differences_name_each_leaf_and_respect_tolerances() -> None:
    recorded = {"ok": True, "pose": {"x": 1.0, "cov": [1.0, 2.0]}, "text": "a"}
    live = {"ok": True, "pose": {"x": 1.05, "cov": [1.0, 2.0, 3.0]}, "text": "b"}
    assert differences(recorded, live, Tolerance()) == [
        "pose.x: 1.0 -> 1.05",
        "pose.cov: 2 elements -> 3",
        "text: 'a' -> 'b'",
    ]
    assert differences({"x": 100.0}, {"x": 100.4}, Tolerance(rtol=0.005)) == []
    assert differences({"x": 1.0}, {"x": 1.2}, Tolerance(atol=0.1)) == ["x: 1.0 -> 1.2"]
    assert differences({"x": float("nan")}, {"x": float("nan")}, Tolerance()) == []


def test_summary_counts_outcomes() -> None:
    summary = ServiceReplaySummary()
    tolerance = Tolerance()
    for seq, (recorded, live) in enumerate(
        [({"a": 1}, {"a": 1}), ({"a": 1}, {"a": 2}), ({"a": 1}, None), (None, {"a": 1})]
    ):
        summary.add(
            compare_response("/s", seq, 0, recorded=recorded, live=live, tolerance=tolerance)
        )
    data = summary.to_dict()
    assert data["totals"]["matched"] == 1 and data["totals"]["differed"] == 1
    assert data["totals"]["unanswered"] == 1 and data["totals"]["not_recorded"] == 1
    assert [c["outcome"] for c in data["calls"]] == ["differed", "unanswered", "not_recorded"]
    assert not summary.ok
