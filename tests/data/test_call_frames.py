"""``bagkit.read_calls``: a service's calls as a DataFrame, checked against the events' headers
parsed here from their CDR bytes (read with the ``mcap`` package) and paired by hand."""

from __future__ import annotations

import struct
from collections import defaultdict
from pathlib import Path

import pandas as pd
import pytest
from mcap.reader import make_reader

import bagkit
from bagkit.data.errors import UndecodableTopicError

GOLDEN = Path(__file__).parents[2] / "fixtures" / "fast" / "golden"
SERVICE = "/logger/get_summary"
REQUEST_RECEIVED, RESPONSE_SENT = 1, 2  # service_msgs/msg/ServiceEventInfo


def _calls_by_hand() -> list[tuple[int, str, int, float]]:
    """(first log time, client gid, sequence number, server latency s) of each call."""
    events: dict[tuple[str, int], dict[int, tuple[int, int]]] = defaultdict(dict)
    (file,) = GOLDEN.glob("*.mcap")
    with file.open("rb") as stream:
        topic = SERVICE + "/_service_event"
        for _, _, message in make_reader(stream).iter_messages([topic]):
            # CDR after its 4-byte header: uint8 event_type, int32 sec and uint32 nanosec at 4,
            # char[16] client_gid at 12, int64 sequence_number at 32.
            body = message.data[4:]
            kind, sec, nanosec = body[0], *struct.unpack_from("<iI", body, 4)
            gid, (sequence,) = body[12:28].hex(), struct.unpack_from("<q", body, 32)
            events[gid, sequence][kind] = (message.log_time, sec * 10**9 + nanosec)
    return sorted(
        (
            min(t for t, _ in kinds.values()),
            gid,
            sequence,
            (kinds[RESPONSE_SENT][1] - kinds[REQUEST_RECEIVED][1]) / 1e9,
        )
        for (gid, sequence), kinds in events.items()
    )


def test_calls_are_paired_and_timed_as_their_events_say() -> None:
    expected = _calls_by_hand()
    assert len(expected) == 4  # fixtures/fast: four calls, each answered
    calls = bagkit.read_calls(GOLDEN, SERVICE)
    columns = ["log_time", "client_gid", "sequence_number", "latency_s"]
    got = list(calls[columns].itertuples(index=False, name=None))
    assert got == expected
    assert (calls.index == pd.to_datetime([t for t, *_ in expected], unit="ns", utc=True)).all()
    assert calls["response.success"].tolist() == [True] * 4
    slow = bagkit.read_calls(GOLDEN, SERVICE, where=f"latency_s > {expected[0][3]}")
    assert slow["log_time"].tolist() == [t for t, *_, s in expected if s > expected[0][3]]
    assert bagkit.read_calls(GOLDEN, SERVICE, start=expected[-1][0] / 1e9).shape[0] == 1


def test_no_such_service_is_one_error() -> None:
    with pytest.raises(UndecodableTopicError, match="no service /nothing"):
        bagkit.read_calls(GOLDEN, "/nothing")
