"""``bagkit doctor``: healthy bags, the interop bags' real problems, and corrupted copies.

Most runs are in the test's process (``run_here``); a real ``bagkit`` process (``run``) for
each exit status a shell sees: 1 for a damaged bag, 2 for input that is no bag.
"""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import pytest
import yaml
from bagkit_runs import bagkit_in_process
from mcap.reader import make_reader
from mcap.records import Message
from mcap.stream_reader import StreamReader
from surgery_samples import STRING, chunk_records, run, string_cdr, write_mixed_bag

from bagkit.bag import BagWriter, TopicInfo
from bagkit.words import counted

FIXTURES = Path(__file__).resolve().parents[2] / "fixtures"


def run_here(*args: str) -> subprocess.CompletedProcess[str]:
    return bagkit_in_process(list(args), Path.cwd())


def stored_out_of_order(files: list[Path]) -> int:
    """Messages logged earlier than the one stored before them (the mcap stream reader)."""
    count = 0
    for file in files:
        previous = 0
        with open(file, "rb") as f:
            for record in StreamReader(f, skip_magic=False).records:
                if isinstance(record, Message):
                    count += record.log_time < previous
                    previous = record.log_time
    return count


@pytest.mark.parametrize("name", ["nominal", "faults", "fast"])
def test_golden_fixtures_are_healthy(name: str) -> None:
    bag = FIXTURES / name / "golden"
    result = run_here("doctor", str(bag), "--deep", "--format", "json")
    assert result.returncode == 0, result.stdout
    report = json.loads(result.stdout)
    assert report["healthy"] and report["problems"] == []
    with open(bag / "golden_0.mcap", "rb") as f:
        assert report["message_count"] == make_reader(f).get_summary().statistics.message_count
    # The recorder writes per-topic batches: a few messages are stored out of log-time order.
    notes = [n["note"] for n in report["notes"]]
    late = stored_out_of_order([bag / "golden_0.mcap"])
    assert notes == ([f"{counted(late, 'message')} stored out of log-time order"] if late else [])


def _oracle_metadata_problems(bag: Path, files: list[Path]) -> set[str]:
    """Which metadata.yaml fields disagree with what the mcap package reads from the files."""
    info = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    times = []
    for file in files:
        with open(file, "rb") as f:
            times += [m.log_time for _, _, m in make_reader(f).iter_messages()]
    wrong = set()
    if info["message_count"] != len(times):
        wrong.add("message_count")
    if info["starting_time"]["nanoseconds_since_epoch"] != min(times):
        wrong.add("starting_time")
    if info["duration"]["nanoseconds"] != max(times) - min(times):
        wrong.add("duration")
    return wrong


def test_every_interop_bag(interop_dir: Path) -> None:
    """Files that the mcap package reads whole with CRCs checked have no file problem; the
    metadata.yaml problems are exactly the fields that disagree with the files."""
    bags = sorted({p.parent if (p.parent / "metadata.yaml").exists() else p
                   for p in interop_dir.rglob("*.mcap")})  # fmt: skip
    assert len(bags) >= 15
    flagged = 0
    for bag in bags:
        files = sorted(bag.glob("*.mcap")) if bag.is_dir() else [bag]
        for file in files:
            with open(file, "rb") as f:
                reader = make_reader(f, validate_crcs=True)
                count = sum(1 for _ in reader.iter_messages())
                assert reader.get_summary().statistics.message_count == count
        result = run_here("doctor", str(bag), "--deep", "--format", "json")
        report = json.loads(result.stdout)
        file_problems = [p for p in report["problems"] if p["where"] != "metadata.yaml"]
        assert file_problems == [], bag
        fields = {p["problem"].split(" is ")[0] for p in report["problems"]}
        expected = _oracle_metadata_problems(bag, files) if bag.is_dir() else set()
        assert fields == expected, bag
        assert result.returncode == (1 if expected else 0)
        flagged += bool(expected)
    assert flagged >= 1  # rosbag2's wbag test bag has a metadata.yaml off from its files


@pytest.fixture
def bag(tmp_path: Path) -> Path:
    return write_mixed_bag(tmp_path / "bag", 1500, compression="none")


def _lines(result: object) -> list[str]:
    return result.stdout.splitlines()  # type: ignore[attr-defined, no-any-return]


def test_flipped_byte_in_a_chunk(bag: Path) -> None:
    file = next(bag.glob("*.mcap"))
    data = bytearray(file.read_bytes())
    chunk = chunk_records(file)[2]
    at = data.find(chunk)
    data[at + len(chunk) - 100] ^= 0x01
    file.write_bytes(bytes(data))
    result = run("doctor", str(bag))
    assert result.returncode == 1
    assert f"bag_0.mcap: chunk at byte {at}: CRC mismatch (the chunk is damaged)" in _lines(result)


def test_cut_file(bag: Path) -> None:
    file = next(bag.glob("*.mcap"))
    data = file.read_bytes()
    file.write_bytes(data[: len(data) // 2])
    lines = _lines(run_here("doctor", str(bag)))
    assert any(line.startswith("bag_0.mcap: truncated at byte") for line in lines)
    assert any("no usable summary" in line for line in lines)
    assert any(
        line.startswith("metadata.yaml: message_count is 1745, the files hold") for line in lines
    )


def test_wrong_count_in_metadata(bag: Path) -> None:
    path = bag / "metadata.yaml"
    info = yaml.safe_load(path.read_text())
    root = info["rosbag2_bagfile_information"]
    root["message_count"] += 3
    root["topics_with_message_count"][1]["message_count"] += 3
    root["relative_file_paths"].append("bag_1.mcap")
    path.write_text(yaml.safe_dump(info))
    result = run_here("doctor", str(bag))
    assert result.returncode == 1
    assert _lines(result) == [
        "metadata.yaml: lists bag_1.mcap, which is missing or unreadable",
        "metadata.yaml: message_count is 1748, the files hold 1745",
        "metadata.yaml: /text: message_count is 218, the files hold 215",
    ]


def test_chunk_index_pointing_wrong(bag: Path) -> None:
    file = next(bag.glob("*.mcap"))
    data = bytearray(file.read_bytes())
    footer = data[-8 - 29 :]
    summary_start = int.from_bytes(footer[9:17], "little")
    pos, indexes = summary_start, []
    while data[pos] != 0x02:
        if data[pos] == 0x08:
            indexes.append(pos + 9 + 16)  # chunk_start_offset
        pos += 9 + int.from_bytes(data[pos + 1 : pos + 9], "little")
    first, second = indexes[1], indexes[2]
    data[first : first + 8], data[second : second + 8] = (
        data[second : second + 8],
        data[first : first + 8],
    )
    file.write_bytes(bytes(data))
    lines = _lines(run_here("doctor", str(bag)))
    assert "bag_0.mcap: summary CRC mismatch (the summary is damaged)" in lines
    assert sum("chunk index" in line and "disagrees" in line for line in lines) == 2


def test_undecodable_message_only_with_deep(tmp_path: Path) -> None:
    bag = tmp_path / "bad"
    with BagWriter(bag) as writer:
        writer.add_topic(TopicInfo("/text", STRING))
        writer.write("/text", string_cdr("fine"), log_time=10)
        writer.write("/text", b"\x00\x01\x00\x00\xff\xff\x00\x00abc", log_time=20)
    assert run_here("doctor", str(bag)).returncode == 0
    result = run_here("doctor", str(bag), "--deep")
    assert result.returncode == 1
    (line,) = _lines(result)
    assert line.startswith("bag: /text: 1 message did not decode (first at log time 20:")


def test_unreadable(tmp_path: Path) -> None:
    text = tmp_path / "x.mcap"
    text.write_text("hello")
    for path in (text, tmp_path / "missing", tmp_path):
        result = run("doctor", str(path))
        assert result.returncode == 2, path
        assert result.stderr.startswith("error: ") and len(result.stderr.splitlines()) == 1


def test_json_matches_text(bag: Path) -> None:
    shutil.copy(bag / "metadata.yaml", bag / "metadata.bak")
    (bag / "metadata.yaml").write_text("rosbag2_bagfile_information: [")
    text = _lines(run_here("doctor", str(bag)))
    report = json.loads(run_here("doctor", str(bag), "--format", "json").stdout)
    assert [f"{p['where']}: {p['problem']}" for p in report["problems"]] == text
    assert text[0].startswith("metadata.yaml: not valid YAML (while parsing a flow node did not")
