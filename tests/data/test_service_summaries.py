"""Service events read by their fixed header (``bagkit info``) against the decoder's reading."""

from __future__ import annotations

import struct
from pathlib import Path

from bagkit.bag import BagReader, BagWriter
from bagkit.bag.service_calls import event_from_message
from bagkit.data.service_summaries import header_event, service_summaries, service_topics
from bagkit.decode import MessageTypes

GOLDEN = Path(__file__).resolve().parents[2] / "fixtures" / "fast" / "golden"


def _events(bag: Path) -> tuple[str, list[tuple[bytes, int, object]]]:
    """The event topic of the bag's one service and (payload, log time, decoded) per event."""
    with BagReader(bag) as reader:
        (topic,) = service_topics(reader).values()
        decode = MessageTypes.from_definitions(reader.definitions).decoder(
            reader.topics[topic].type
        )
        return topic, [(m.data, m.log_time, decode(m.data)) for m in reader.messages([topic])]


def test_header_events_are_the_decoded_events_without_payload() -> None:
    _, events = _events(GOLDEN)
    assert len(events) >= 4
    for data, log_time, decoded in events:
        expected = event_from_message(decoded, log_time)
        got = header_event(data, log_time)
        assert got is not None
        assert (got.kind, got.stamp_ns, got.log_time_ns, got.call) == (
            expected.kind,
            expected.stamp_ns,
            expected.log_time_ns,
            expected.call,
        )


def test_a_header_that_does_not_fit_is_none() -> None:
    _, events = _events(GOLDEN)
    data = events[0][0]
    assert header_event(data[:43], 0) is None  # cut inside the sequence number
    assert header_event(b"\x00\x03" + data[2:], 0) is None  # parameter-list CDR
    assert header_event(data[:4] + b"\x07" + data[5:], 0) is None  # no such event kind
    late = struct.pack("<I", 1_000_000_000)
    assert header_event(data[:12] + late + data[16:], 0) is None  # nanoseconds out of range
    assert header_event(b"", 0) is None


def _copy(tmp_path: Path, name: str, *, definition_first_line: str, cut_first: bool) -> Path:
    """The golden bag's service events alone, with its definition's first line replaced and
    the first event cut short if asked."""
    topic, events = _events(GOLDEN)
    with BagReader(GOLDEN) as reader:
        info = reader.topics[topic]
        definition = reader.definitions[info.type]
    first, rest = definition.split("\n", 1)
    assert first == "service_msgs/ServiceEventInfo info"
    copy = tmp_path / name
    with BagWriter(copy) as writer:
        writer.add_topic(info, definition=f"{definition_first_line}\n{rest}")
        for i, (data, log_time, _) in enumerate(events):
            writer.write(topic, data[:20] if cut_first and i == 0 else data, log_time=log_time)
    return copy


def test_a_definition_of_another_form_is_read_by_the_decoder(tmp_path: Path) -> None:
    # The header is not trusted unless the definition starts with it: here the decoder reads.
    other = _copy(
        tmp_path,
        "other",
        definition_first_line="service_msgs/msg/ServiceEventInfo info",
        cut_first=False,
    )
    assert service_summaries(other) == service_summaries(GOLDEN)
    assert service_summaries(GOLDEN)[0].counts.events == len(_events(GOLDEN)[1])


def test_a_cut_event_leaves_its_service_out_as_the_decoder_does(tmp_path: Path) -> None:
    cut = _copy(
        tmp_path, "cut", definition_first_line="service_msgs/ServiceEventInfo info", cut_first=True
    )
    assert service_summaries(cut) == []
