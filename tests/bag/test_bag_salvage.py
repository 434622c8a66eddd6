"""Crash safety: truncated files are salvaged, SIGKILL loses at most a second, disk full."""

from __future__ import annotations

import io
import json
import re
import shutil
import signal
import struct
import subprocess
import sys
import textwrap
import time
from collections.abc import Callable
from pathlib import Path

import pytest
from mcap.exceptions import McapError
from mcap.records import Message
from mcap.stream_reader import StreamReader

from bagkit.bag import BagReader, BagWriteError, BagWriter, NotABagError, TopicInfo


def _intact_messages_before(data: bytes) -> int:
    """Messages in complete chunks of a (possibly cut) MCAP file, per the mcap library.

    The stream reader reads a chunk record whole before it yields the messages inside, so the
    messages it yields before failing are exactly those of the intact chunks.
    """
    count = 0
    try:
        for record in StreamReader(io.BytesIO(data)).records:
            count += isinstance(record, Message)
    except (McapError, EOFError, ValueError, struct.error):
        pass
    return count


@pytest.mark.parametrize("fraction", [0.2, 0.35, 0.5, 0.77, 0.97, 0.999])
def test_truncated_file_keeps_every_complete_chunk(
    write_sample_bag: Callable[..., Path], tmp_path: Path, fraction: float
) -> None:
    bag_path = write_sample_bag(n_imu=400, chunk_size=6_000)
    original = (bag_path / "sample_0.mcap").read_bytes()
    cut = int(len(original) * fraction)
    crashed = tmp_path / "crashed"
    crashed.mkdir()
    (crashed / "crashed_0.mcap").write_bytes(original[:cut])
    expected = _intact_messages_before(original[:cut])
    assert 0 < expected <= 440

    with BagReader(crashed) as bag:
        assert bag.message_count == expected
        messages = list(bag.messages())
        assert len(messages) == expected
        # The intact part is a prefix of what was written: no holes.
        imu = [m.sequence for m in messages if m.topic == "/imu/data"]
        assert imu == list(range(len(imu)))
        problems = bag.problems
    if fraction < 0.9:  # the cut falls in the data section: the reader says how much it lost
        assert len(problems) == 1
        match = re.search(r"crashed_0\.mcap: truncated at byte (\d+): (\d+) bytes", problems[0])
        assert match is not None, problems
        offset, lost = int(match.group(1)), int(match.group(2))
        assert offset + lost == cut
        assert 0 < lost < 6_000 + 1_000


def test_garbage_is_not_a_bag(tmp_path: Path) -> None:
    (tmp_path / "junk.mcap").write_bytes(b"hello, not an mcap file at all")
    with pytest.raises(NotABagError):
        BagReader(tmp_path / "junk.mcap").open()


_KILLED_WRITER = textwrap.dedent(
    """
    import sys, time
    from bagkit.bag import BagWriter, TopicInfo
    with BagWriter(sys.argv[1]) as bag:
        bag.add_topic(TopicInfo("/tick", "std_msgs/msg/UInt64"))
        i = 0
        while True:
            bag.write("/tick", b"\\x00\\x01\\x00\\x00" + i.to_bytes(8, "little"),
                      log_time=time.time_ns(), sequence=i)
            i += 1
            if i == 200:
                print("writing", flush=True)
            time.sleep(0.001)
    """
)


def test_sigkill_loses_at_most_the_last_second(tmp_path: Path) -> None:
    bag_path = tmp_path / "killed"
    proc = subprocess.Popen(
        [sys.executable, "-c", _KILLED_WRITER, str(bag_path)],
        stdout=subprocess.PIPE,
        start_new_session=True,
    )
    try:
        assert proc.stdout is not None
        assert proc.stdout.readline() == b"writing\n"
        time.sleep(2.2)
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    killed_at = time.time_ns()
    assert not (bag_path / "metadata.yaml").exists()
    with BagReader(bag_path) as bag:
        messages = list(bag.messages())
    assert [m.sequence for m in messages] == list(range(len(messages)))
    assert [int.from_bytes(m.data[4:], "little") for m in messages] == list(range(len(messages)))
    # Everything older than one second before the kill is in the bag (0.5 s of slack for a
    # loaded machine: the child may be descheduled between writes).
    assert killed_at - messages[-1].log_time < 1_500_000_000


_FULL_DISK_WRITER = textwrap.dedent(
    """
    import json, resource, signal, sys
    from bagkit.bag import BagWriteError, BagWriter, TopicInfo
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # over the limit, write() fails with EFBIG
    resource.setrlimit(resource.RLIMIT_FSIZE, (60_000, 60_000))
    bag = BagWriter(sys.argv[1], compression="none", chunk_size=4_000).open()
    bag.add_topic(TopicInfo("/a", "std_msgs/msg/UInt64"))
    bag.add_topic(TopicInfo("/b", "std_msgs/msg/UInt64"))
    accepted = {"/a": 0, "/b": 0}
    batch = int(sys.argv[2])  # 1: write(), more: write_batch() of that many messages
    for first in range(0, 100_000, batch):
        topic = "/a" if (first // batch) % 3 else "/b"
        numbers = range(first, first + batch)
        accepted[topic] += batch  # the messages are taken even when the call raises
        payloads = [b"\\x00\\x01\\x00\\x00" + i.to_bytes(8, "little") for i in numbers]
        try:
            if batch == 1:
                bag.write(topic, payloads[0], log_time=1_000 + first, sequence=first)
            else:
                bag.write_batch(topic, payloads, log_times=[1_000 + i for i in numbers],
                                sequences=numbers)
        except BagWriteError as exc:
            print(json.dumps({"error": str(exc), "accepted": accepted,
                              "lost": exc.lost_by_topic}), flush=True)
            break
    try:
        bag.close()
    except BagWriteError as exc:
        print(json.dumps({"close": str(exc)}), flush=True)
    """
)


@pytest.mark.parametrize("batch", [1, 7])
def test_disk_full_is_a_clear_error_and_keeps_what_was_flushed(tmp_path: Path, batch: int) -> None:
    bag_path = tmp_path / "full"
    result = subprocess.run(
        [sys.executable, "-c", _FULL_DISK_WRITER, str(bag_path), str(batch)],
        capture_output=True,
        text=True,
        timeout=60,
        check=True,
    )
    report = json.loads(result.stdout.splitlines()[0])
    assert "full_0.mcap" in report["error"] and "messages lost" in report["error"]
    lost = report["lost"]
    assert lost["/a"] > 0 and lost["/b"] > 0  # the failed chunk held both topics
    kept = {t: report["accepted"][t] - lost[t] for t in ("/a", "/b")}
    assert kept["/a"] + kept["/b"] > 500
    with BagReader(bag_path) as bag:
        assert bag.topic_counts == kept
        sequences = [m.sequence for m in bag.messages()]
    assert sequences == list(range(kept["/a"] + kept["/b"]))


def test_unwritable_location_is_a_clear_error(tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("a file, not a directory")
    with pytest.raises(BagWriteError, match="cannot create"):
        BagWriter(blocker / "bag").open()


def test_chunks_close_once_per_second_and_on_flush(tmp_path: Path) -> None:
    with BagWriter(tmp_path / "bag", chunk_interval_s=0.2) as bag:
        bag.add_topic(TopicInfo("/tick", "std_msgs/msg/UInt64"))
        data_file = tmp_path / "bag" / "bag_0.mcap"
        bag.write("/tick", bytes(12), log_time=1)
        size_after_first = data_file.stat().st_size
        time.sleep(0.25)
        bag.write("/tick", bytes(12), log_time=2)  # the chunk is older than 0.2 s: closed
        size_after_interval = data_file.stat().st_size
        bag.write("/tick", bytes(12), log_time=3)
        bag.flush()
        size_after_flush = data_file.stat().st_size
        copy = tmp_path / "copy"
        copy.mkdir()
        shutil.copy(data_file, copy / "copy_0.mcap")
    assert size_after_interval > size_after_first
    assert size_after_flush > size_after_interval
    with BagReader(copy) as salvaged:
        assert [m.log_time for m in salvaged.messages()] == [1, 2, 3]
        assert salvaged.problems == []


def _payloads_from_chunks(bag: BagReader, topic: str) -> list[bytes]:
    """Payloads located through the chunk-level API (payload spans)."""
    out = []
    for chunk in bag.chunks(topics=[topic]):
        _, starts, lengths = chunk.payloads(topic)
        for start, length in zip(starts.tolist(), lengths.tolist(), strict=True):
            out.append(chunk.records[start : start + length])
    return out


@pytest.mark.parametrize("cut_fraction", [1.0, 0.6])
def test_chunk_access_finds_the_same_messages(
    write_sample_bag: Callable[..., Path], tmp_path: Path, cut_fraction: float
) -> None:
    bag_path = write_sample_bag(n_imu=300, chunk_size=5_000)
    data = (bag_path / "sample_0.mcap").read_bytes()
    target = tmp_path / "cut"
    target.mkdir()
    (target / "cut_0.mcap").write_bytes(data[: int(len(data) * cut_fraction)])
    with BagReader(target) as bag:
        for topic in ("/imu/data", "/text"):
            expected = [m.data for m in bag.messages(topics=[topic])]
            assert expected
            assert _payloads_from_chunks(bag, topic) == expected


@pytest.mark.parametrize("kept_bytes", [0, 5, 20])
def test_split_bag_killed_while_opening_a_file_keeps_the_others(
    write_sample_bag: Callable[..., Path], kept_bytes: int
) -> None:
    bag_path = write_sample_bag(
        n_imu=600, max_bag_size=40_000, chunk_size=8_000, compression="none"
    )
    files = sorted(bag_path.glob("*.mcap"), key=lambda p: int(p.stem.split("_")[-1]))
    (bag_path / "metadata.yaml").unlink()
    last = files[-1]
    last.write_bytes(last.read_bytes()[:kept_bytes])
    with BagReader(bag_path) as bag:
        assert bag.files == files[:-1]
        sequences = [m.sequence for m in bag.messages(topics=["/imu/data"])]
        assert len(bag.problems) == 1
        assert bag.problems[0].startswith(f"{last.name}: unreadable, skipped")
    assert sequences == list(range(len(sequences)))
    assert 0 < len(sequences) < 600
