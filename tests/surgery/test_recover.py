"""``bagkit recover``: cut, summary-less and index-less bags rewritten as complete ones that
rosbags and the ``mcap`` package open with every message bagkit's salvage reads."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import pytest
import yaml
from mcap.reader import make_reader
from rosbags.rosbag2 import Reader as Rosbag2Reader
from surgery_samples import (
    chunk_records,
    mcap_messages,
    rosbags_messages,
    run,
    run_here,
    write_mixed_bag,
)

from bagkit.bag import BagReader

Message = tuple[str, int, bytes]


def salvaged(path: Path) -> list[Message]:
    """The messages bagkit's reader (salvage) gets from a damaged bag, in its order."""
    with BagReader(path, allow_empty=True) as reader:
        return [(m.topic, m.log_time, bytes(m.data)) for m in reader.messages()]


def data_end(file: Path) -> int:
    """Offset of the Data End record (where the summary starts to matter)."""
    data = file.read_bytes()
    pos = 8
    while data[pos] != 0x0F:
        pos += 9 + int.from_bytes(data[pos + 1 : pos + 9], "little")
    return pos


@pytest.fixture(scope="module")
def source(tmp_path_factory: pytest.TempPathFactory) -> Path:
    bag = write_mixed_bag(tmp_path_factory.mktemp("in") / "drive", 3000)
    return next(bag.glob("*.mcap"))


def check_recovered(out: Path, expected: list[Message]) -> None:
    """``out`` is complete: rosbags (metadata.yaml, then AnyReader) and mcap (summary, CRCs)
    read exactly ``expected``; metadata.yaml v9 says what the files hold."""
    files = sorted(out.glob("*.mcap"))
    assert mcap_messages(files) == expected
    assert rosbags_messages(out) == expected
    with Rosbag2Reader(out) as reader:  # rosbag2's metadata, as rosbags reads it
        assert reader.message_count == len(expected)
        counts = {c.topic: c.msgcount for c in reader.connections}
        assert counts == {t: sum(1 for m in expected if m[0] == t) for t in counts}
    info = yaml.safe_load((out / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["version"] == 9
    assert info["relative_file_paths"] == [f.name for f in files]
    if expected:
        assert info["starting_time"]["nanoseconds_since_epoch"] == expected[0][1]
        assert info["duration"]["nanoseconds"] == expected[-1][1] - expected[0][1]
    for file in files:
        with open(file, "rb") as f:
            reader = make_reader(f, validate_crcs=True)
            summary = reader.get_summary()
            assert summary is not None and summary.statistics is not None
            assert summary.statistics.message_count == len(expected)
            assert all(c.message_index_offsets for c in summary.chunk_indexes)
            assert [m.name for m in reader.iter_metadata()] == ["rosbag2"]


@pytest.mark.parametrize(
    "fraction", [0.05, 0.13, 0.27, 0.33, 0.41, 0.5, 0.58, 0.66, 0.79, 0.9, 0.97]
)
def test_truncated_copies(source: Path, tmp_path: Path, fraction: float) -> None:
    cut = tmp_path / "cut.mcap"
    data = source.read_bytes()
    cut.write_bytes(data[: int(len(data) * fraction)])
    expected = salvaged(cut)
    out = tmp_path / "recovered"
    result = run_here("recover", str(cut), "-o", str(out))
    assert f"{len(expected):,} messages" in result.stdout
    if not expected:  # nothing recovered: a failure
        assert result.returncode == 1, result.stderr
        assert "error: no message of" in result.stderr
        return
    if len(cut.read_bytes()) < data_end(source):  # recovered with a loss: 3
        assert result.returncode == 3, result.stderr
        assert "warning: lost: cut.mcap: truncated at byte" in result.stderr
    else:  # only the summary was cut: nothing is lost
        assert result.returncode == 0, result.stderr
        assert result.stderr == ""
        assert len(expected) == len(rosbags_messages(source.parent))
    check_recovered(out, expected)
    # Every chunk the cut left whole is copied as it was stored.
    stored = chunk_records(source)
    recovered = chunk_records(next(out.glob("*.mcap")))
    whole = [c for c in stored if data.find(c) + len(c) <= len(cut.read_bytes())]
    assert recovered[: len(whole)] == whole


def test_no_summary_and_no_indexes(source: Path, tmp_path: Path) -> None:
    data = source.read_bytes()
    no_summary = tmp_path / "no_summary.mcap"
    no_summary.write_bytes(data[: data_end(source)])
    # Index-less: the data section without its Message Index records.
    pos, kept = 8, bytearray(data[:8])
    while data[pos] != 0x0F:
        end = pos + 9 + int.from_bytes(data[pos + 1 : pos + 9], "little")
        if data[pos] != 0x07:
            kept += data[pos:end]
        pos = end
    no_indexes = tmp_path / "no_indexes.mcap"
    no_indexes.write_bytes(bytes(kept))
    everything = rosbags_messages(source.parent)
    for damaged in (no_summary, no_indexes):
        assert salvaged(damaged) == everything
        out = tmp_path / f"{damaged.stem}_recovered"
        result = run_here("reindex", str(damaged), "-o", str(out))
        assert result.returncode == 0, result.stderr
        check_recovered(out, everything)
        assert chunk_records(next(out.glob("*.mcap"))) == chunk_records(source)


def test_killed_bag_directory(source: Path, tmp_path: Path) -> None:
    """A bag directory without metadata.yaml whose file was cut, as a killed recorder leaves."""
    bag = tmp_path / "killed"
    bag.mkdir()
    data = source.read_bytes()
    (bag / "killed_0.mcap").write_bytes(data[: len(data) * 2 // 3])
    expected = salvaged(bag)
    out = tmp_path / "out"
    assert run("recover", str(bag), "-o", str(out)).returncode == 3  # the cut tail is lost
    check_recovered(out, expected)
    shutil.rmtree(out)
    # A damaged chunk: its messages are reported lost, the rest recovered.
    before = expected
    damaged = bytearray(data[: len(data) * 2 // 3])
    middle = chunk_records(source)[3]
    damaged[data.find(middle) + len(middle) // 2] ^= 0xFF
    (bag / "killed_0.mcap").write_bytes(bytes(damaged))
    expected = salvaged(bag)
    result = run_here("recover", str(bag), "-o", str(out))
    assert result.returncode == 3, result.stderr
    assert "unreadable" in result.stderr and "messages lost" in result.stderr
    check_recovered(out, expected)
    first, last = int.from_bytes(middle[9:17], "little"), int.from_bytes(middle[17:25], "little")
    assert expected == [m for m in before if not first <= m[1] <= last]
    assert len(expected) < len(before)


def test_bad_input(tmp_path: Path) -> None:
    text = tmp_path / "text.mcap"
    text.write_text("not a bag")
    for args in (["recover", str(text)], ["recover", str(tmp_path / "none")]):
        result = run_here(*args, "-o", str(tmp_path / "out"))
        assert result.returncode == 2
        assert result.stderr.startswith("error: ") and len(result.stderr.splitlines()) == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["text.mcap"]
    bag = write_mixed_bag(tmp_path / "bag", 10)
    assert run_here("recover", str(bag), "-o", str(bag)).returncode == 2


def test_cut_file_scanned_once_less(
    source: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A summary-less file is scanned to index it: the copy takes the index that the check for
    message-compressed payloads read (2 scans, not 3), and the output is the same."""
    from bagkit.bag import mcap_file
    from bagkit.surgery import rewrite
    from bagkit.surgery.rewrite import recover_bag

    cut = tmp_path / "cut.mcap"
    cut.write_bytes(source.read_bytes()[: source.stat().st_size // 2])
    scans: list[str] = []

    def counted(source, **kwargs):  # type: ignore[no-untyped-def]
        scans.append(source.name)
        return real(source, **kwargs)

    real = rewrite.read_file_index
    monkeypatch.setattr(rewrite, "read_file_index", counted)
    monkeypatch.setattr(mcap_file, "read_file_index", counted)
    report = recover_bag(cut, tmp_path / "recovered")
    assert scans == ["cut.mcap", "cut.mcap"]
    expected = salvaged(cut)
    assert report.message_count == len(expected)
    check_recovered(tmp_path / "recovered", expected)


def test_scanned_file_changed_is_read_again(source: Path, tmp_path: Path) -> None:
    """An index is reused only for the same file, unchanged (size, modification time)."""
    from bagkit.bag.mcap_file import McapFile
    from bagkit.bag.mcapio import Source
    from bagkit.surgery.rewrite import ScannedFiles

    cut = tmp_path / "cut.mcap"
    data = source.read_bytes()
    cut.write_bytes(data[: len(data) // 2])
    mcap = McapFile(cut)
    mcap.open()
    mcap.close()
    scanned = ScannedFiles()
    scanned.add(mcap)
    with cut.open("rb") as f:
        assert scanned.index(cut, Source(f, cut.name)) is mcap.index
    cut.write_bytes(data[: len(data) * 3 // 4])
    with cut.open("rb") as f:
        index = scanned.index(cut, Source(f, cut.name))
    assert index is not mcap.index
    assert index.message_count > mcap.index.message_count


def test_chunks_failing_their_check_are_lost_the_rest_copied_in_order(
    source: Path, tmp_path: Path
) -> None:
    """Chunks copied as stored are checked on threads and written on another: two damaged
    chunks (a byte of their compressed data flipped) are reported in file order, every other
    chunk is copied as stored, in order."""
    with open(source, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    chunks = sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)
    assert len(chunks) > 20
    damaged = [chunks[3], chunks[17]]
    data = bytearray(source.read_bytes())
    for chunk in damaged:
        data[chunk.chunk_start_offset + chunk.chunk_length - 40] ^= 0xFF
    bag = tmp_path / "damaged.mcap"
    bag.write_bytes(bytes(data[: data_end(source)]))  # no summary: recover scans it
    expected = salvaged(bag)
    everything = rosbags_messages(source.parent)
    assert 0 < len(expected) < len(everything)
    out = tmp_path / "recovered"
    result = run_here("recover", str(bag), "-o", str(out))
    assert result.returncode == 3, result.stderr
    lost = [line for line in result.stderr.splitlines() if "unreadable" in line]
    assert [line.split("chunk at byte ")[1].split(" ")[0] for line in lost] == [
        str(c.chunk_start_offset) for c in damaged
    ]
    assert all(re.search(r"; [\d,]+ messages? lost$", line) for line in lost)
    check_recovered(out, expected)
    stored = chunk_records(source)
    assert chunk_records(next(out.glob("*.mcap"))) == [
        record for i, record in enumerate(stored) if i not in (3, 17)
    ]
