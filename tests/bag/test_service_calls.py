"""Pairing service events into calls, counting and timing them: the pure core."""

from __future__ import annotations

from types import SimpleNamespace

from bagkit.bag.service_calls import (
    REQUEST_RECEIVED,
    REQUEST_SENT,
    RESPONSE_RECEIVED,
    RESPONSE_SENT,
    ServiceEvent,
    count_events,
    event_from_message,
    latency_summary,
    pair_calls,
)

CLIENT, SERVER_VIEW = b"\x01" * 16, b"\x02" * 16


def event(kind: int, stamp: int, gid: bytes, seq: int, message: object = None) -> ServiceEvent:
    return ServiceEvent(kind, stamp, stamp + 5, (gid, seq), message)


def test_halves_with_different_gids_join_by_sequence_and_time() -> None:
    events = [
        event(REQUEST_SENT, 100, CLIENT, 1, "req1"),
        event(REQUEST_RECEIVED, 110, SERVER_VIEW, 1, "req1"),
        event(RESPONSE_SENT, 120, SERVER_VIEW, 1, "resp1"),
        event(RESPONSE_RECEIVED, 150, CLIENT, 1, "resp1"),
        event(REQUEST_SENT, 200, CLIENT, 2, "req2"),
        # A server half received before the client sent: another client's call, not joined.
        event(REQUEST_RECEIVED, 190, SERVER_VIEW, 2, "other"),
    ]
    first, other, second = pair_calls(events)
    assert sorted(first.events) == [0, 1, 2, 3]
    assert (first.request, first.response, first.latency_ns, first.latency_side) == (
        "req1",
        "resp1",
        50,
        "client",
    )
    assert other.request == "other" and other.latency_ns is None
    assert second.response is None and second.latency_side is None
    counts = count_events(events)
    assert (counts.events, counts.requests, counts.responses) == (6, 3, 1)


def test_server_side_only_latency_and_metadata_events() -> None:
    events = [
        event(REQUEST_RECEIVED, 1_000, SERVER_VIEW, 7),
        event(RESPONSE_SENT, 4_000, SERVER_VIEW, 7),
    ]
    (call,) = pair_calls(events)
    assert (call.latency_ns, call.latency_side, call.request) == (3_000, "server", None)


def test_latency_summary_interpolates_percentiles() -> None:
    calls = pair_calls(
        e
        for i, latency in enumerate([10, 20, 30, 40, 100])
        for e in (
            event(REQUEST_SENT, 1000 * i, CLIENT, i),
            event(RESPONSE_RECEIVED, 1000 * i + latency, CLIENT, i),
        )
    )
    summary = latency_summary(calls)
    assert (summary.count, summary.p50_ns, summary.max_ns) == (5, 30, 100)
    assert summary.p99_ns is not None and abs(summary.p99_ns - (40 + 60 * 0.96)) < 1e-9
    assert latency_summary([]).count == 0


def test_event_from_a_decoded_message() -> None:
    message = SimpleNamespace(
        info=SimpleNamespace(
            event_type=RESPONSE_SENT,
            stamp=SimpleNamespace(sec=2, nanosec=5),
            client_gid=[255] * 16,
            sequence_number=9,
        ),
        request=[],
        response=["answer"],
    )
    parsed = event_from_message(message, 77)
    assert parsed.call == (b"\xff" * 16, 9)
    assert (parsed.stamp_ns, parsed.message, parsed.log_time_ns) == (2_000_000_005, "answer", 77)
