"""pass_reader: a pass's messages and latched state from real bags, each payload of a migrated
topic through its migration (a stand-in for bagkit.migrate.TopicMigration: the pure core)."""

from __future__ import annotations

from contextlib import ExitStack
from pathlib import Path

from test_play_source import LATCHED, START, write

from bagkit.playback.pass_reader import pass_reader
from bagkit.playback.seeking import WindowSpan
from bagkit.playback.source import MessageOrder, PlaySource


class Doubled:
    """Each payload's bytes twice over."""

    def payload(self, data: bytes | memoryview) -> bytes:
        return bytes(data) * 2


def test_the_migrated_topic_is_migrated_in_the_pass_and_in_the_latched_state(
    tmp_path: Path,
) -> None:
    rows = [("/state", 0, 0), ("/x", 10, 10), ("/state", 20, 20), ("/x", 30, 30), ("/x", 40, 40)]
    bag = write(tmp_path / "bag", rows, qos={"/state": LATCHED})
    with ExitStack() as stack:
        source = PlaySource.open([bag], MessageOrder.RECEIVED, stack)
        span = WindowSpan(START, START + 40, START + 39)  # the last message is past the window
        reader = pass_reader(
            source, ["/state", "/x"], span, latched={"/state"}, migrations={"/state": Doubled()}
        )
        got = [(m.topic, m.log_time - START, bytes(m.data)) for m in reader.messages_from(START)]
        assert got == [
            ("/state", 0, b"\x00\x00"),
            ("/x", 10, b"\x01"),
            ("/state", 20, b"\x02\x02"),
            ("/x", 30, b"\x03"),
        ]
        latched = reader.latched_before(START + 25)
        assert [(m.topic, m.log_time - START, bytes(m.data)) for m in latched] == [
            ("/state", 20, b"\x02\x02")
        ]
        assert reader.end_ns == START + 39
        plain = pass_reader(source, ["/x"], span, latched=set(), migrations={})
        assert [bytes(m.data) for m in plain.messages_from(START + 15)] == [b"\x03"]
        assert plain.latched_before(START + 25) == []
