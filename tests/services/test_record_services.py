"""Services recorded over real DDS: stored as rosbag2 does, counted, paired, read by peers."""

from __future__ import annotations

import csv
import io
import json
import subprocess
from pathlib import Path

import numpy as np
import pytest
from conftest import BAGKIT, CALLS, record_calls
from mcap.reader import make_reader
from rosbags.highlevel import AnyReader

from bagkit.bag import BagReader, bag_info
from bagkit.data.service_summaries import service_summaries
from bagkit.data.services import read_calls

pytestmark = pytest.mark.ros

TOPIC = "/svc/toggle/_service_event"


def test_all_records_service_events_as_rosbag2_names_them(service_bag: Path) -> None:
    info = bag_info(service_bag)
    (event,) = [t for t in info.topics if t.topic == TOPIC]
    assert event.type == "std_srvs/srv/SetBool_Event"
    # Four events per call: the client's two and the server's two.
    assert event.count == 4 * CALLS
    with BagReader(service_bag) as bag:
        assert bag.definitions["std_srvs/srv/SetBool_Event"].startswith(
            "service_msgs/ServiceEventInfo info\n"
        )


def test_info_counts_requests_and_responses_once_per_call(service_bag: Path) -> None:
    (summary,) = service_summaries(service_bag)
    assert (summary.service, summary.type) == ("/svc/toggle", "std_srvs/srv/SetBool")
    assert (summary.counts.events, summary.counts.requests, summary.counts.responses) == (
        4 * CALLS,
        CALLS,
        CALLS,
    )
    latency = summary.latency
    assert latency.count == CALLS
    assert latency.p50_ns is not None and latency.max_ns is not None
    assert 0 < latency.p50_ns <= latency.max_ns
    out = subprocess.run(
        [BAGKIT, "info", str(service_bag), "--format", "json"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    (listed,) = json.loads(out)["services"]
    assert listed["counts"] == {"events": 4 * CALLS, "requests": CALLS, "responses": CALLS}


def test_echo_pairs_each_request_with_its_response(service_bag: Path) -> None:
    out = subprocess.run(
        [BAGKIT, "echo", str(service_bag), "/svc/toggle", "--format", "json"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    calls = [json.loads(line) for line in out.splitlines()]
    assert [c["sequence_number"] for c in calls] == list(range(1, CALLS + 1))
    assert [c["request"]["data"] for c in calls] == [i % 2 == 0 for i in range(CALLS)]
    for call in calls:
        assert len(call["events"]) == 4
        assert call["response"]["success"] == call["request"]["data"]
        assert call["response"]["message"] == f"set {call['request']['data']}"
        assert call["latency_side"] == "client"
        assert call["latency_s"] > 0


def _echo_calls(bag: Path, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [BAGKIT, "echo", str(bag), "/svc/toggle", "--format", "json", *args],
        capture_output=True,
        text=True,
        check=False,
    )


def test_echo_of_a_service_keeps_the_calls_of_a_window_and_a_condition(service_bag: Path) -> None:
    every = [json.loads(line) for line in _echo_calls(service_bag).stdout.splitlines()]
    assert len(every) == CALLS

    kept = _echo_calls(service_bag, "--where", "response.success == true and latency_s > 0")
    assert kept.returncode == 0, kept.stderr
    numbers = [json.loads(line)["sequence_number"] for line in kept.stdout.splitlines()]
    assert numbers == [c["sequence_number"] for c in every if c["response"]["success"]]
    assert 0 < len(numbers) < CALLS

    third = every[2]["log_time"]
    later = _echo_calls(service_bag, "--start", f"{third}ns", "-n", "2")
    numbers = [json.loads(line)["sequence_number"] for line in later.stdout.splitlines()]
    assert numbers == [c["sequence_number"] for c in every if c["log_time"] >= third][:2]

    none = _echo_calls(service_bag, "--where", "latency_s < 0")
    assert none.returncode == 0 and none.stdout == ""
    assert "no call satisfies" in none.stderr

    for bad in (
        ["--where", "response.nope > 1"],
        ["--where", "response.message > 1"],
        ["--fields", "request.data"],
    ):
        refused = _echo_calls(service_bag, *bad)
        lines = refused.stderr.strip().splitlines()
        assert refused.returncode == 2 and len(lines) == 1, (bad, refused.stderr)
        assert lines[0].startswith("error:") and "Traceback" not in refused.stderr


def test_rosbags_reads_the_events(service_bag: Path) -> None:
    with AnyReader([service_bag]) as reader:
        connections = [c for c in reader.connections if c.topic == TOPIC]
        # rosbags names every type pkg/<kind>/msg/Name: the event type is registered so.
        events = [
            reader.deserialize(raw, "std_srvs/srv/msg/SetBool_Event")
            for _, _, raw in reader.messages(connections=connections)
        ]
    assert len(events) == 4 * CALLS
    requests = [e.request[0].data for e in events if e.info.event_type == 0]
    assert requests == [i % 2 == 0 for i in range(CALLS)]


def test_mcap_reads_the_schema_and_records(service_bag: Path) -> None:
    (path,) = sorted(service_bag.glob("*.mcap"))
    with path.open("rb") as stream:
        reader = make_reader(stream)
        summary = reader.get_summary()
        assert summary is not None
        (channel,) = [c for c in summary.channels.values() if c.topic == TOPIC]
        schema = summary.schemas[channel.schema_id]
        assert (schema.name, schema.encoding) == ("std_srvs/srv/SetBool_Event", "ros2msg")
        assert summary.statistics is not None
        assert summary.statistics.channel_message_counts[channel.id] == 4 * CALLS


def test_services_and_exclusions_select_event_topics(tmp_path: Path) -> None:
    bag = tmp_path / "excluded"
    record_calls(
        bag,
        ["--all-services", "--exclude-services", "/svc/toggle", "--all-topics"],
        [],
        events_recorded=False,
    )
    with BagReader(bag, allow_empty=True) as reader:
        assert TOPIC not in reader.topics
    bag = tmp_path / "named"
    record_calls(bag, ["--services", "svc/toggle"], [])
    (summary,) = service_summaries(bag)
    # The server's side only: one request and one response event per call.
    assert (summary.counts.events, summary.counts.requests) == (2 * CALLS, CALLS)
    assert summary.latency.count == CALLS


def stats_summary(bag: Path, output: str) -> str:
    """``bagkit stats summary BAG --format OUTPUT``'s stdout."""
    return subprocess.run(
        [BAGKIT, "stats", "summary", str(bag), "--format", output],
        capture_output=True,
        text=True,
        check=True,
    ).stdout


def test_stats_reach_request_and_response_fields_and_latency(service_bag: Path) -> None:
    result = json.loads(stats_summary(service_bag, "json"))
    (topic,) = [t for t in result["topics"] if t["topic"] == TOPIC]
    fields = {f["field"]: f for f in topic["fields"]}
    # Requests carried by the client's and the server's request events, alternating data.
    assert fields["request[].data"]["count"] == 2 * CALLS
    assert fields["response[].success"]["count"] == 2 * CALLS
    (latency,) = result["services"]
    assert (latency["service"], latency["count"]) == ("/svc/toggle", CALLS)
    assert 0 < latency["p50_s"] <= latency["p99_s"] <= latency["max_s"]
    # CSV: one more row of the event topic, field latency_s, against the paired calls.
    table = stats_summary(service_bag, "csv")
    (row,) = [r for r in csv.DictReader(io.StringIO(table)) if r["field"] == "latency_s"]
    seconds = np.array([c.latency_ns for c in read_calls(service_bag, "/svc/toggle")]) / 1e9
    assert (row["topic"], int(row["count"]), int(row["nan_count"])) == (TOPIC, CALLS, 0)
    expected = {"min": seconds.min(), "max": seconds.max(), "mean": seconds.mean()}
    assert {k: float(row[k]) for k in expected} == pytest.approx(expected, rel=1e-12)
    assert float(row["std"]) == pytest.approx(seconds.std(ddof=1), rel=1e-9)
    assert float(row["max"]) == latency["max_s"]
