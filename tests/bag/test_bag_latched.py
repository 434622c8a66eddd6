"""bagkit.bag.latched: the last message before a time of each latched topic, from the indexes.

The oracle is the list of messages the test wrote (or, for damaged files, a full read).
"""

from __future__ import annotations

import random
import shutil
import sqlite3
from pathlib import Path

import pytest
from bag_samples import IMU, STRING, imu_cdr, string_cdr
from ros2_messages import qos_yaml
from test_bag_sqlite_hostile import write_db3

import bagkit.bag.mcap_file
from bagkit.bag import BagReader, BagWriter, TopicInfo
from bagkit.bag.latched import (
    LatchedOptions,
    is_transient_local,
    last_messages_before,
    latched_state,
    latched_topics,
    transient_local_topics,
)
from bagkit.selection.errors import UnknownTopicError

START = 1_700_000_000_000_000_000
LATCHED = qos_yaml(depth=1, reliability="reliable", durability="transient_local")
VOLATILE = qos_yaml(depth=10, reliability="reliable", durability="volatile")
# rosbag2 metadata version 8 and older: policies as rmw enum integers (1 = transient_local).
LATCHED_V8 = "- history: 1\n  depth: 1\n  reliability: 1\n  durability: 1\n"

Written = tuple[str, int, bytes]  # topic, log time, payload


def _write_bag(path: Path, n: int = 3000, chunk_size: int = 2048) -> list[Written]:
    """/imu/data every 1 ms (volatile), /map every 250th (transient-local), /tf_static twice,
    /mode every 100th (volatile); small chunks so there are many."""
    written: list[Written] = []
    with BagWriter(path, chunk_size=chunk_size) as bag:
        bag.add_topic(TopicInfo("/imu/data", IMU, offered_qos_profiles=VOLATILE))
        bag.add_topic(TopicInfo("/map", STRING, offered_qos_profiles=LATCHED))
        bag.add_topic(TopicInfo("/tf_static", STRING, offered_qos_profiles=LATCHED_V8))
        bag.add_topic(TopicInfo("/mode", STRING, offered_qos_profiles=VOLATILE))

        def put(topic: str, data: bytes, t: int) -> None:
            bag.write(topic, data, log_time=t)
            written.append((topic, t, data))

        for i in range(n):
            t = START + i * 1_000_000
            put("/imu/data", imu_cdr(i), t)
            if i % 250 == 3:
                put("/map", string_cdr(f"map {i}"), t + 1)
            if i in (0, 1500):
                put("/tf_static", string_cdr(f"tf {i}"), t + 2)
            if i % 100 == 50:
                put("/mode", string_cdr(f"mode {i}"), t + 3)
    return written


def _oracle(written: list[Written], topics: set[str], before: int) -> dict[str, Written]:
    last: dict[str, Written] = {}
    for message in written:  # written in log-time order per topic
        if message[0] in topics and message[1] < before:
            last[message[0]] = message
    return last


def _found(bag: BagReader, topics: set[str], before: int) -> dict[str, Written]:
    return {
        topic: (m.topic, m.log_time, m.data)
        for topic, m in last_messages_before(bag, topics, before).items()
    }


def test_transient_local_is_read_from_every_qos_form() -> None:
    assert is_transient_local(LATCHED) and is_transient_local(LATCHED_V8)
    assert not is_transient_local(VOLATILE)
    two_offers = VOLATILE + "\n" + LATCHED  # one of two publishers latched: replayed latched
    assert is_transient_local(two_offers)
    for hostile in ("", "[", "durability: transient_local", "- durability: true", "- 7"):
        assert not is_transient_local(hostile)


def test_last_message_before_any_time_matches_the_written_ones(tmp_path: Path) -> None:
    written = _write_bag(tmp_path / "bag")
    topics = {"/imu/data", "/map", "/tf_static", "/mode"}
    rng = random.Random(7)
    times = [START - 1, START, START + 1, START + 3_000_000_000, *(w[1] for w in written[::97])]
    times += [START + rng.randrange(3_100_000_000) for _ in range(40)]
    with BagReader(tmp_path / "bag") as bag:
        assert len(bag.files) == 1
        for before in times:
            assert _found(bag, topics, before) == _oracle(written, topics, before), before
        assert bag.problems == []


def test_only_the_chunks_near_the_time_are_read(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    written = _write_bag(tmp_path / "bag")
    with BagReader(tmp_path / "bag") as bag:
        chunks = sum(1 for _ in bag.chunks())
    reads: list[int] = []
    real_read_chunk = bagkit.bag.mcap_file.read_chunk

    def counting_read_chunk(*args: object, **kwargs: object) -> object:
        reads.append(1)
        return real_read_chunk(*args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(bagkit.bag.mcap_file, "read_chunk", counting_read_chunk)
    with BagReader(tmp_path / "bag") as bag:
        before = START + 2_900_000_000
        found = _found(bag, {"/map", "/tf_static"}, before)
    assert found == _oracle(written, {"/map", "/tf_static"}, before)
    # /tf_static's last one is 1.4 s earlier, yet only the chunks holding the two answers
    # are decompressed (Message Index records tell where they are).
    assert chunks > 50 and len(reads) <= 2


def test_latched_state_takes_transient_local_topics_plus_extra_ones(tmp_path: Path) -> None:
    written = _write_bag(tmp_path / "bag")
    before = START + 1_600_000_000
    with BagReader(tmp_path / "bag") as bag:
        assert transient_local_topics(bag.topics) == {"/map", "/tf_static"}
        state = latched_state(bag, before)
        assert [(m.topic, m.log_time, m.data) for m in state] == sorted(
            _oracle(written, {"/map", "/tf_static"}, before).values(), key=lambda w: w[1]
        )
        with_mode = latched_state(bag, before, LatchedOptions(extra_topics=("mode",)))
        assert {m.topic for m in with_mode} == {"/map", "/tf_static", "/mode"}
        assert latched_state(bag, before, LatchedOptions(enabled=False)) == []
        only_map = latched_state(bag, before, selected={"/map", "/imu/data"})
        assert [m.topic for m in only_map] == ["/map"]
        with pytest.raises(UnknownTopicError, match="/nope"):
            latched_topics(bag.topics, LatchedOptions(extra_topics=("/nope",)))
        assert latched_state(bag, START) == []  # nothing before the first message


def test_ties_and_overlapping_chunks_give_the_one_stored_last(tmp_path: Path) -> None:
    """Out-of-order writes make chunks overlap in time; equal log times: the later one."""
    path = tmp_path / "bag"
    written: list[Written] = []
    with BagWriter(path, chunk_size=512) as bag:
        bag.add_topic(TopicInfo("/state", STRING, offered_qos_profiles=LATCHED))
        for i in range(400):
            t = START + ((i * 37) % 400) * 1_000_000  # a permutation of 400 times
            data = string_cdr(f"state {i}")
            bag.write("/state", data, log_time=t)
            written.append(("/state", t, data))
        tie = string_cdr("tie")
        bag.write("/state", tie, log_time=START + 200_000_000)
        written.append(("/state", START + 200_000_000, tie))
    with BagReader(path) as bag:
        for before in (START + 200_000_001, START + 123_456_789, START + 400_000_000):
            expected = max(
                (w for w in written if w[1] < before),
                key=lambda w: (w[1], written.index(w)),
            )
            assert _found(bag, {"/state"}, before) == {"/state": expected}


def test_sqlite3_and_mixed_storage(tmp_path: Path) -> None:
    db3 = write_db3(tmp_path / "a.db3", n=40)  # /a even, /b odd messages, 1 ms apart
    db = sqlite3.connect(db3)
    db.execute("UPDATE topics SET offered_qos_profiles = ? WHERE name = '/a'", (LATCHED,))
    db.commit()
    db.close()
    with BagReader(db3) as bag:
        everything = [(m.topic, m.log_time, m.data) for m in bag.messages()]
        assert transient_local_topics(bag.topics) == {"/a"}
        for before in (START, START + 1, START + 17_000_000, START + 17_000_001, START + 10**12):
            assert _found(bag, {"/a", "/b"}, before) == _oracle(everything, {"/a", "/b"}, before)
    mixed = tmp_path / "mixed"
    mixed.mkdir()
    written = _write_bag(tmp_path / "mcap_bag", n=500)
    shutil.copy(next((tmp_path / "mcap_bag").glob("*.mcap")), mixed / "m_0.mcap")
    shutil.copy(db3, mixed / "s_1.db3")
    with BagReader(mixed) as bag:
        before = START + 250_000_000
        topics = {"/a", "/map", "/imu/data"}
        assert _found(bag, topics, before) == _oracle(written + everything, topics, before)


def test_a_file_without_summary_is_searched_too(tmp_path: Path) -> None:
    """A crashed recording (summary cut off): salvaged blocks, same answers as a full read."""
    _write_bag(tmp_path / "bag", n=1000)
    (mcap,) = (tmp_path / "bag").glob("*.mcap")
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(mcap.read_bytes()[: mcap.stat().st_size * 2 // 3])
    with BagReader(cut) as bag:
        assert not bag.has_summary
        everything = [(m.topic, m.log_time, m.data) for m in bag.messages()]
        topics = {"/imu/data", "/map", "/tf_static"}
        for before in (START + 100_000_000, START + 600_000_000, START + 10**12):
            assert _found(bag, topics, before) == _oracle(everything, topics, before)
