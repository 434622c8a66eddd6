"""Replaying services over real DDS: recorded requests sent to a live service, answers compared."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest
from conftest import BAGKIT, CALLS, record_calls, start_node, stop, wait_line

pytestmark = pytest.mark.ros


def replay_requests(bag: Path, *args: str) -> tuple[int, dict[str, object], str]:
    done = subprocess.run(
        [BAGKIT, "replay", str(bag), "--publish-service-requests", "--format", "json", *args],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    return done.returncode, json.loads(done.stdout)["service_requests"], done.stderr


@pytest.mark.parametrize("source", ["service_introspection", "client_introspection"])
def test_the_same_handler_answers_as_recorded(service_bag: Path, source: str) -> None:
    node = start_node()
    try:
        wait_line(node, "ready")
        code, summary, _ = replay_requests(service_bag, "--service-requests-source", source)
    finally:
        stop(node)
    assert summary["totals"] == {
        "sent": CALLS,
        "matched": CALLS,
        "differed": 0,
        "unanswered": 0,
        "not_recorded": 0,
    }
    assert code == 0


def test_a_changed_handler_is_reported(service_bag: Path) -> None:
    node = start_node("--negate")
    try:
        wait_line(node, "ready")
        code, summary, _ = replay_requests(service_bag)
    finally:
        stop(node)
    assert code == 1
    assert summary["totals"]["differed"] == CALLS  # type: ignore[index]
    calls = summary["calls"]
    assert isinstance(calls, list)
    assert [c["sequence_number"] for c in calls] == list(range(1, CALLS + 1))
    # The recorded answer was success == data, data alternating from True.
    assert calls[0]["differences"] == ["success: True -> False"]
    assert calls[1]["differences"] == ["success: False -> True"]


def test_an_absent_service_counts_unanswered_and_replay_goes_on(service_bag: Path) -> None:
    code, summary, _ = replay_requests(service_bag, "--service-timeout", "0.5")
    assert code == 1
    assert summary["totals"]["unanswered"] == CALLS  # type: ignore[index]
    assert summary["totals"]["sent"] == CALLS  # type: ignore[index]


def test_metadata_only_events_warn_and_send_nothing(tmp_path: Path) -> None:
    bag = tmp_path / "metadata"
    record_calls(bag, ["--services", "/svc/toggle"], ["--metadata"])
    code, summary, stderr = replay_requests(bag, "--service-timeout", "0.5")
    assert summary["empty_requests"] == {"/svc/toggle": CALLS}
    assert summary["totals"]["sent"] == 0  # type: ignore[index]
    assert stderr.count("carry no request") == 1
    assert code == 0
